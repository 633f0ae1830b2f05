"""The train board's loop (main.py calls `main()`): boot (startup.py, then assemble.py), then the loop.

The loop polls MQTT without blocking, keeps a monotonic uptime (ms, `uptime_ms`, modulo 2^30 by the wire's rule:
a small int for ever) and hands it to the OnboardUnit. The hardware watchdog is fed only after a healthy pass (no
exception, the previous pass recent). When the broker is lost the loop goes on (the unit brakes when its command
expires); reconnect attempts, which may block, are made with backoff and only while the motor is held braked.
MicroPython only (it runs on the board). `run` stays one function: its console stats and the REPL's detaching as
functions of their own cost 176 B more of the 32-bit loop heap (tests/test_heap32.py).
"""

import gc
import sys
from time import sleep_ms, ticks_diff, ticks_ms

import wire

VERSION = "0.1.0"
_clock = [ticks_ms(), 0]   # ticks_ms() at the last reading, board ms since boot


def uptime_ms():
    """Board time in ms since boot, modulo 2^30 (wire.wrap_add), whatever the port's own ticks period."""
    t = ticks_ms()
    _clock[1] = wire.wrap_add(_clock[1], ticks_diff(t, _clock[0]))
    _clock[0] = t
    return _clock[1]


def run(config, now, unit, link, maint, watchdog=None, integrity=None):
    """The loop, `now()` giving board ms: `unit` the OnboardUnit, `link` its link.Link, `maint` the FLASH button's
    pin, `watchdog` a machine.WDT (or None), `integrity` the train line's pin number (read once the REPL is detached,
    where config['integrity_loop'] says one is wired). Returns (heap_peak, heap_live) in bytes after config['run_ms']
    (if > 0), or with the motor braked when the FLASH button (`maint` reads 0) is held in the boot window (maintenance:
    the REPL stays). heap_peak: the most heap in use at the end of a pass, its garbage not yet collected (an upper
    bound of the live heap during a pass); heap_live: the most heap in use after a pass's garbage is collected."""
    peak = live = errors = next_stats_ms = refused_said = 0
    grace_over = False
    last_ms = now()
    while True:
        now_ms = now()
        healthy = wire.wrap_diff(now_ms, last_ms) <= config["max_pass_ms"]
        last_ms = now_ms
        try:   # the link catches its own errors; whatever it does, the unit steps below
            if link.connected:
                link.poll(now_ms)
            elif link.due(now_ms) and unit.motor.mode == "brake":
                if link.connect(now_ms):
                    print("mqtt: connected to %s:%d" % (config["broker_host"], config["broker_port"]))
                else:
                    print("mqtt: %s; retrying" % link.last_error)
                gc.collect()   # an attempt's garbage (the socket's, umqtt's) goes before the unit steps and reports
            unit.link_ok = link.connected
        except Exception as exc:
            healthy = False
            errors += 1
            print("link: %r" % (exc,))
        try:   # the command deadline and the trip supervision run on every pass
            unit.step(now_ms)
        except Exception as exc:  # never let the loop die: brake, report on the console, let the watchdog judge
            healthy = False
            errors += 1
            print("loop: %r" % (exc,))
            unit.motor.brake()
        used = gc.mem_alloc()
        if used > peak:
            peak = used
        if watchdog is not None and healthy:
            watchdog.feed()
        if not grace_over:
            if maint.value() == 0:
                unit.motor.brake()
                print("maintenance: FLASH button held, the train loop stops and the REPL stays")
                return peak, live
            if now_ms >= config["repl_grace_ms"]:
                grace_over = True
                if sys.platform == "esp8266":   # UART0 goes to the IPS; the REPL comes back after a reset
                    import os

                    os.dupterm(None, 1)
                    if integrity is not None and config.get("integrity_loop"):
                        # TX is free now: the train line, closed to GND while the train is whole
                        import machine

                        unit.integrity = machine.Pin(integrity, machine.Pin.IN, machine.Pin.PULL_UP)
        if wire.wrap_diff(now_ms, next_stats_ms) >= 0:
            next_stats_ms = wire.wrap_add(now_ms, config["stats_ms"])
            print("stats: up_ms %d heap_peak %d heap_live %d heap_free %d link %s losses %d mode %s errors %d "
                  "sensor_errors %d dropped %d %d %d" % (now_ms, peak, live, gc.mem_free(),
                                                         "up" if link.connected else "down", link.losses, unit.mode,
                                                         errors, unit.sensor_errors, link.oversized, link.retained,
                                                         link.failed))
            if unit.rejected != refused_said:   # refused commands: a count and the newest reason, once a period
                print("refused: %d commands since the last stats; the newest: %s"
                      % (unit.rejected - refused_said, unit.last_reject))
                refused_said = unit.rejected
        if config["run_ms"] and now_ms >= config["run_ms"]:
            return peak, live
        gc.collect()
        used = gc.mem_alloc()
        if used > live:
            live = used
        sleep_ms(config["loop_ms"])


def main():
    """Boot in two halves, then run the loop. startup.py: config, drivers (motor braked), Wi-Fi; assemble.py: the
    MQTT link, the OnboardUnit and the watchdog. Each half leaves sys.modules when it is done (startup.py before the
    second half loads the heavy modules), so the board's heap never holds boot code it will not run again."""
    gc.collect()
    import startup

    config, drivers = startup.start(uptime_ms, VERSION, sleep_ms)
    del startup
    for name in ("startup", "board", "train_config", "network"):
        sys.modules.pop(name, None)
    gc.collect()
    import assemble

    unit, link, watchdog, config = assemble.build(config, drivers)
    del assemble
    sys.modules.pop("assemble")
    maint, integrity = drivers["maint"], drivers.get("integrity")
    del drivers
    gc.collect()
    print("stopped: heap_peak %d heap_live %d" % run(config, uptime_ms, unit, link, maint, watchdog, integrity))
