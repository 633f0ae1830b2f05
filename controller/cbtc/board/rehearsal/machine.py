"""The rehearsal board's `machine` (MicroPython unix port): the host stand-in (host_machine, cbtc/board/host) with a
wheel that turns as if the train were pushed by hand, so that the firmware's encoder counts as on the table.

wheel_config (written by cbtc.board.virtual_board) says the encoder's pins, the wheel's true counts per metre, how
far and how fast the push goes and when it starts: PUSH_AFTER_MS after the encoder is set up, or (-1) once the file
TRIGGER exists. The wheel runs on a thread, as an interrupt would, and writes how far it has gone to STATUS.
"""

import _thread
import os
import time

import host_machine
from host_machine import PWM, SPI, UART, UART_RX, WDT  # noqa: F401  (the firmware imports them from here)
from wheel_config import COUNTS_PER_M, ENC_A, ENC_B, PUSH_AFTER_MS, PUSH_MM, PUSH_MMPS, STATUS, TRIGGER

_pins = {}


class Pin(host_machine.Pin):
    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        if args and isinstance(args[0], int):
            _pins[args[0]] = self

    def irq(self, trigger, handler, hard=False):
        super().irq(trigger, handler, hard)
        if self is _pins.get(ENC_A):
            _thread.start_new_thread(_wheel, (self, _pins.get(ENC_B)))


def _say(text):
    with open(STATUS, "w") as fh:
        fh.write(text)


def _triggered():
    try:
        os.stat(TRIGGER)
        return True
    except OSError:
        return False


def _pushed_mm(t_s):
    """How far a push of PUSH_MM at PUSH_MMPS has gone after `t_s`: speeding up and slowing down at _PUSH_MMPS2, as
    a hand does (a wheel that stops dead is what a failed encoder looks like)."""
    v, a, d = PUSH_MMPS, _PUSH_MMPS2, PUSH_MM
    if v * v / a > d:   # too short to reach the speed
        v = (a * d) ** 0.5
    ta = v / a
    tc = (d - v * ta) / v
    if t_s < ta:
        return 0.5 * a * t_s * t_s
    if t_s < ta + tc:
        return 0.5 * v * ta + v * (t_s - ta)
    left = max(0.0, 2 * ta + tc - t_s)
    return d - 0.5 * a * left * left


_PUSH_MMPS2 = 300


def _wheel(pin_a, pin_b):
    """Stand until the push starts, then give an edge of A per count (B read at A's edges: A leading B, forward)."""
    start = time.ticks_ms()
    _say("standing 0 0")
    while not (_triggered() if PUSH_AFTER_MS < 0 else time.ticks_diff(time.ticks_ms(), start) >= PUSH_AFTER_MS):
        time.sleep_ms(20)
    pushed = time.ticks_ms()
    counts = said = 0
    while True:
        time.sleep_ms(2)
        gone_ms = time.ticks_diff(time.ticks_ms(), pushed)
        done_mm = min(PUSH_MM, int(_pushed_mm(gone_ms / 1000)))
        want = done_mm * COUNTS_PER_M // 1000
        while counts < want:
            counts += 1
            level = 1 - pin_a.state
            pin_a.state = level
            if pin_b is not None:
                pin_b.state = 1 - level
            pin_a.handler(pin_a)
        if done_mm >= PUSH_MM:
            _say("pushed %d %d" % (done_mm, counts))
            return
        if gone_ms - said >= 250:
            said = gone_ms
            _say("pushing %d %d" % (done_mm, counts))
