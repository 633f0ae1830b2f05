"""Wheel encoder on pin interrupts: a slotted wheel / hall sensor (one channel) or a quadrature pair.

Encoder(pin_a, pin_b=None) takes ready `machine.Pin` inputs. One channel: every edge counts +1 (monotonic: the
direction comes from the motor command, not from the sensor). Two channels: x4 quadrature decoding, signed (A leading B
counts up). The interrupt handlers touch only preallocated ints: read the level, reject a repeated level (a bounce or a
missed edge seen twice), count, return. ESP8266 pin IRQs are soft: the handler runs late, so it reads the levels
itself instead of trusting the trigger.
"""

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_RISING = const(1)       # machine.Pin.IRQ_RISING on the ESP8266
_FALLING = const(2)      # machine.Pin.IRQ_FALLING

# quadrature transition table: index = old_state * 4 + new_state, state = (a << 1) | b;
# forward order 00 -> 10 -> 11 -> 01 -> 00 counts +1, the reverse -1, no change or a double change 0
_QUAD = (0, -1, 1, 0,
         1, 0, 0, -1,
         -1, 0, 0, 1,
         0, 1, -1, 0)


class Encoder:
    def __init__(self, pin_a, pin_b=None):
        self.pin_a = pin_a
        self.pin_b = pin_b
        self._count = 0
        self._level_a = pin_a.value()
        trigger = getattr(pin_a, "IRQ_RISING", _RISING) | getattr(pin_a, "IRQ_FALLING", _FALLING)
        if pin_b is None:
            pin_a.irq(trigger=trigger, handler=self._edge)
        else:
            self._state = (self._level_a << 1) | pin_b.value()
            pin_a.irq(trigger=trigger, handler=self._quad_edge)
            pin_b.irq(trigger=trigger, handler=self._quad_edge)

    def _edge(self, _):
        level = self.pin_a.value()
        if level != self._level_a:
            self._level_a = level
            self._count += 1

    def _quad_edge(self, _):
        state = (self.pin_a.value() << 1) | self.pin_b.value()
        self._count += _QUAD[(self._state << 2) | state]
        self._state = state

    def count(self):
        """Snapshot of the edge count (counts; signed with two channels)."""
        return self._count
