"""The board's boot and loop in steps, for the 32-bit heap measurement in the WebAssembly port (tests/test_heap32.py).

The WebAssembly port frees garbage only between calls from JavaScript, so heap32.mjs runs the board's boot halves and
each pass of its loop as separate calls, with a collection in between: `boot()`, `assemble()`, then `one_pass(ms)`
repeatedly (and `second_half()` after a pass that connected). Each does what firmware/train.py main() and run() do at
that point, on a clock the driver advances.
"""

import gc
import sys

import machine

_ = {"ms": 0}


def boot(uart_bytes):
    """The first half of train.main(): startup.start (config, drivers, Wi-Fi), then the boot-only modules leave."""
    import startup
    import train

    machine.UART_RX[0] = uart_bytes
    _["train"] = train
    _["cfg"], _["drivers"] = startup.start(lambda: _["ms"], train.VERSION, lambda ms: None)
    for name in ("startup", "board", "train_config", "network"):
        sys.modules.pop(name, None)


def assemble():
    """The second half: assemble.build (MQTT link, OnboardUnit, watchdog), then assemble leaves."""
    import assemble

    _["unit"], _["link"], _["wdt"], _["cfg"] = assemble.build(_["cfg"], _["drivers"])
    _["unit"].boot_id = 4242   # the boot the test's prepared commands name (a board draws its own)
    sys.modules.pop("assemble")
    del _["drivers"]


def _roll(unit, dt_ms):
    """The wheel under the motor: edges on the encoder's pin, through its interrupt handler, at the speed the duty
    drives the train unloaded (7.5 mm/s per %), one count per mm; integers only (um), so it adds nothing to the heap."""
    if unit.motor.mode == "drive":
        _["um"] = _.get("um", 0) + unit.motor.duty_pct * 15 * dt_ms // 2
        pin, pin_b = unit.encoder.pin_a, unit.encoder.pin_b
        while _["um"] >= 1000:
            _["um"] -= 1000
            if pin_b is not None:   # forward: B, read at A's edges, lags A by a quarter cycle
                pin_b.state = pin.state
            pin.state ^= 1
            pin.handler(pin)


def one_pass(now_ms):
    """One pass of train.run at board time `now_ms`, or its first half when it connects (train.run collects after a
    connection attempt: second_half() is the rest); returns the heap in use at its end, before collection."""
    _roll(_["unit"], now_ms - _["ms"])
    _["ms"] = now_ms
    unit, link = _["unit"], _["link"]
    try:
        if link.connected:
            link.poll(now_ms)
        elif link.due(now_ms) and unit.motor.mode == "brake":
            link.connect(now_ms)
            _["half"] = True
            return gc.mem_alloc()
    except Exception as exc:
        print("link: %r" % (exc,))
    return second_half()


def second_half():
    """The rest of a pass: the unit steps (after a connection attempt, in a call of its own: a collection between)."""
    unit = _["unit"]
    _["half"] = False
    try:
        unit.link_ok = _["link"].connected
        unit.step(_["ms"])
    except Exception as exc:
        print("loop: %r" % (exc,))
        unit.motor.brake()
    if _["wdt"] is not None:
        _["wdt"].feed()
    return gc.mem_alloc()


def halved():
    """True when the last one_pass stopped after a connection attempt (second_half() is due)."""
    return _.get("half", False)


def feed_ips(frame):
    """Bytes arriving on the IPS UART (the receiver's UART object is the board's)."""
    _["unit"].ips.uart.buf.extend(frame)


def state():
    unit = _["unit"]
    return "%s %d %d %d" % (unit.mode, unit.seq, unit.cseq, unit.rejected)
