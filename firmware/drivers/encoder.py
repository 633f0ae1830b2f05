"""Wheel encoder on pin interrupts: a slotted wheel / hall sensor (one channel) or a quadrature pair.

Encoder(pin_a, pin_b=None, quadrature=True) takes ready `machine.Pin` inputs. One channel: every edge counts +1
(monotonic: the direction comes from the motor command, not from the sensor). Two channels: x4 quadrature decoding,
signed (A leading B counts up). Two channels with `quadrature=False`: only A interrupts and B is read at each of A's
edges (x2 decoding, signed, the same counts per metre as one channel): B needs no interrupt, so it can sit on a pin
that has none (GPIO16). The interrupt handlers touch only preallocated ints: read the level, reject a repeated level
(a bounce or a missed edge seen twice), count, note the time of the edge, return. They are hard interrupts (the
ESP8266 has them), so the time is the edge's own; they read the levels themselves rather than trust the trigger.

Two channels count travel: `way` is -1 while the train runs backwards (the OnboardUnit sets it when it turns), and
the wheel turning backwards then counts up, so the odometer runs on through a reversal. One channel counts up anyway.

Each edge's time makes the speed exact to the edge (the M/T method in the OnboardUnit): `count()` also sets `age_us`,
how long before the read the newest counted edge came.
"""

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

from time import ticks_diff, ticks_us  # CPython has none: the host checks lend it MicroPython's (tests/mpy)

_RISING = const(1)       # machine.Pin.IRQ_RISING on the ESP8266
_FALLING = const(2)      # machine.Pin.IRQ_FALLING

# quadrature transition table: index = old_state * 4 + new_state, state = (a << 1) | b;
# forward order 00 -> 10 -> 11 -> 01 -> 00 counts +1, the reverse -1, no change or a double change 0
_QUAD = (0, -1, 1, 0,
         1, 0, 0, -1,
         -1, 0, 0, 1,
         0, 1, -1, 0)


class Encoder:
    way = 1   # the way of travel: -1 running backwards (two channels count the backward turn up)

    def __init__(self, pin_a, pin_b=None, quadrature=True):
        self.pin_a = pin_a
        self.pin_b = pin_b
        self.signed = pin_b is not None   # two channels count down on the way back; one channel only ever counts up
        self._count = 0
        self._edge_us = ticks_us()   # as if an edge at start: the first age is the time standing since
        self.age_us = 0
        self._level_a = pin_a.value()
        trigger = getattr(pin_a, "IRQ_RISING", _RISING) | getattr(pin_a, "IRQ_FALLING", _FALLING)
        if pin_b is None:
            pin_a.irq(trigger=trigger, handler=self._edge, hard=True)
        elif not quadrature:
            pin_a.irq(trigger=trigger, handler=self._dir_edge, hard=True)
        else:
            self._state = (self._level_a << 1) | pin_b.value()
            pin_a.irq(trigger=trigger, handler=self._quad_edge, hard=True)
            pin_b.irq(trigger=trigger, handler=self._quad_edge, hard=True)

    def _edge(self, _):
        level = self.pin_a.value()
        if level != self._level_a:
            self._level_a = level
            self._count += 1
            self._edge_us = ticks_us()

    def _dir_edge(self, _):
        level = self.pin_a.value()
        if level != self._level_a:   # A leading B (00 10 11 01): A and B differ just after each of A's edges
            self._level_a = level
            self._count += self.way if level != self.pin_b.value() else -self.way
            self._edge_us = ticks_us()

    def _quad_edge(self, _):
        state = (self.pin_a.value() << 1) | self.pin_b.value()
        step = _QUAD[(self._state << 2) | state]
        if step:
            self._count += step * self.way
            self._edge_us = ticks_us()
        self._state = state

    def count(self):
        """Snapshot of the edge count (counts; signed with two channels); sets `age_us`, us since that count's edge
        (it wraps after 2^29 us, 9 min, of standing: the OnboardUnit takes a count's age only when the count is new)."""
        count = self._count
        edge_us = self._edge_us
        while count != self._count:   # an edge came between the two reads (the handler may run at any bytecode)
            count = self._count
            edge_us = self._edge_us
        self.age_us = ticks_diff(ticks_us(), edge_us)
        return count
