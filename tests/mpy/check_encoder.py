"""Encoder checks that run unchanged under CPython and under the MicroPython unix port.

Each `check_*` function builds the driver on the host shims (tests/mpy/shims) and asserts byte-exact behaviour;
tests/test_drivers.py calls each one directly and again inside `micropython -X heapsize=36K`.
"""

import machine
from drivers.encoder import Encoder


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
