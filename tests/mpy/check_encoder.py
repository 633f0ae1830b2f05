"""Encoder checks that run unchanged under CPython and under the MicroPython unix port.

Each `check_*` function builds the driver on the host shims (cbtc/board/host) and asserts byte-exact behaviour;
tests/test_drivers.py calls each one directly and again inside `micropython -X heapsize=36K`.
"""

import time

import machine

if not hasattr(time, "ticks_us"):   # CPython: MicroPython's ticks, for the driver
    import host_ticks
    time.ticks_us = host_ticks.ticks_us
    time.ticks_diff = host_ticks.ticks_diff

from drivers import encoder as encoder_module  # noqa: E402  (after the ticks)
from drivers.encoder import Encoder  # noqa: E402


def set_level(pin, level):
    """Drive a shim input pin to `level`: its handler runs if it listens to this edge."""
    old = pin.value()
    pin.value(level)
    if pin.handler and old != level and pin.trigger & (machine.Pin.IRQ_RISING if level else machine.Pin.IRQ_FALLING):
        pin.handler(pin)


def check_encoder_single_channel():
    pin = machine.Pin(14, machine.Pin.IN)
    enc = Encoder(pin)
    for level in (1, 0, 1, 0, 1):
        set_level(pin, level)
    assert enc.count() == 5
    enc._edge(pin)                                      # a late IRQ on an unchanged level is rejected
    assert enc.count() == 5


def check_encoder_quadrature():
    a = machine.Pin(14, machine.Pin.IN)
    b = machine.Pin(12, machine.Pin.IN)
    enc = Encoder(a, b)
    forward = ((a, 1), (b, 1), (a, 0), (b, 0))          # A leads B: 00 10 11 01 00
    for _ in range(3):
        for pin, level in forward:
            set_level(pin, level)
    assert enc.count() == 12
    for pin, level in ((b, 1), (a, 1), (b, 0), (a, 0)):  # B leads A: backwards one cycle
        set_level(pin, level)
    assert enc.count() == 8


def check_encoder_direction_pin():
    a = machine.Pin(4, machine.Pin.IN)
    b = machine.Pin(16, machine.Pin.IN)
    enc = Encoder(a, b, quadrature=False)
    assert b.handler is None                             # B is only read, at A's edges
    forward = ((a, 1), (b, 1), (a, 0), (b, 0))
    for _ in range(3):
        for pin, level in forward:
            set_level(pin, level)
    assert enc.count() == 6 and enc.signed
    for pin, level in ((b, 1), (a, 1), (b, 0), (a, 0)):  # backwards one cycle
        set_level(pin, level)
    assert enc.count() == 4
    enc._dir_edge(a)                                     # a late IRQ on an unchanged level is rejected
    assert enc.count() == 4


def check_encoder_counts_travel_up_when_the_train_runs_backwards():
    """`way` -1 (the board turned): the wheel turning backwards counts up, forwards down, on both two-channel
    decoders; one channel counts up whatever the way."""
    for quadrature in (True, False):
        a, b = machine.Pin(4, machine.Pin.IN), machine.Pin(16, machine.Pin.IN)
        enc = Encoder(a, b, quadrature=quadrature)
        enc.way = -1
        for pin, level in ((b, 1), (a, 1), (b, 0), (a, 0)):   # backwards one cycle
            set_level(pin, level)
        assert enc.count() == (4 if quadrature else 2), enc.count()
        for pin, level in ((a, 1), (b, 1), (a, 0), (b, 0)):   # forwards one cycle: back where it started
            set_level(pin, level)
        assert enc.count() == 0
    single = machine.Pin(14, machine.Pin.IN)
    enc = Encoder(single)
    enc.way = -1
    for level in (1, 0, 1):
        set_level(single, level)
    assert enc.count() == 3


try:
    from time import ticks_add
    TICKS_PERIOD = ticks_add(0, -1) + 1      # 2^30 on the ESP8266; wider on a 64-bit port
except ImportError:  # CPython: host_ticks, which wraps as the ESP8266 does
    TICKS_PERIOD = 0x40000000


class Clock:
    """A tick counter the check sets (us), wrapping like the port's; it stands in for the driver's ticks_us until
    `restore()`."""

    def __init__(self, t_us=0):
        self.t_us = t_us
        self._real = encoder_module.ticks_us
        encoder_module.ticks_us = self

    def __call__(self):
        return self.t_us % TICKS_PERIOD

    def restore(self):
        encoder_module.ticks_us = self._real


def check_encoder_times_its_newest_edge():
    pin = machine.Pin(14, machine.Pin.IN)
    clock = Clock(5000)
    try:
        enc = Encoder(pin)
        assert pin.hard, "a hard interrupt: the edge's time is its own, not the scheduler's"
        clock.t_us = 7000
        assert enc.count() == 0 and enc.age_us == 2000         # standing since the start
        for level, t_us in ((1, 10000), (0, 12500), (1, 15000)):
            clock.t_us = t_us
            set_level(pin, level)
        clock.t_us = 15800
        assert enc.count() == 3 and enc.age_us == 800
        # a late IRQ on an unchanged level: no count, no new time
        enc._edge(pin)
        clock.t_us = 16000
        assert enc.count() == 3 and enc.age_us == 1000
    finally:
        clock.restore()


def check_encoder_age_runs_across_the_tick_wrap():
    pin = machine.Pin(14, machine.Pin.IN)
    clock = Clock(TICKS_PERIOD - 300)                  # an edge just before the counter wraps
    try:
        enc = Encoder(pin)
        set_level(pin, 1)
        clock.t_us += 1000
        assert enc.count() == 1 and enc.age_us == 1000     # across the wrap
        set_level(pin, 0)
        clock.t_us += 300
        assert enc.count() == 2 and enc.age_us == 300
    finally:
        clock.restore()


def check_encoder_quadrature_times_counted_edges_only():
    a = machine.Pin(14, machine.Pin.IN)
    b = machine.Pin(12, machine.Pin.IN)
    clock = Clock(0)
    try:
        enc = Encoder(a, b)
        clock.t_us = 1000
        set_level(a, 1)
        clock.t_us = 3000
        enc._quad_edge(a)                                       # no change of state: not an edge
        assert enc.count() == 1 and enc.age_us == 2000
    finally:
        clock.restore()
