"""The train board's loop (main.py calls `main()`): boot (startup.py, then `build`), then the OnboardUnit loop.

The loop polls MQTT without blocking, keeps a monotonic, non-wrapping uptime (ms) from ticks_ms/ticks_diff and hands
it to the OnboardUnit. The hardware watchdog is fed only after a healthy pass (no exception, the previous pass
recent). When the broker is lost the loop goes on (the unit brakes when its command expires); reconnect attempts,
which may block, are made with backoff and only while the motor is held braked.
"""

import gc
import sys
import time

try:
    from time import sleep_ms, ticks_diff, ticks_ms
except ImportError:  # CPython
    def ticks_ms():
        return int(time.monotonic() * 1000)

    def ticks_diff(new, old):
        return new - old

    def sleep_ms(ms):
        time.sleep(ms / 1000.0)

VERSION = "0.1.0"


class Uptime:
    """Board time in ms since boot that never wraps: ticks_ms differences summed into a Python int."""

    def __init__(self):
        self._last = ticks_ms()
        self.ms = 0

    def now(self):
        t = ticks_ms()
        self.ms += ticks_diff(t, self._last)
        self._last = t
        return self.ms


def run(cfg, clock, unit, net, maint_pin, wdt=None):
    """The loop; returns (heap_peak, heap_live) in bytes after cfg['run_ms'] (if > 0), or with the motor braked when
    the FLASH button (`maint_pin` reads 0) is held in the boot window (maintenance: the REPL stays).
    heap_peak: the most heap in use at the end of a pass, its garbage not yet collected (an upper bound of the live
    heap during a pass); heap_live: the most heap in use after a pass's garbage is collected."""
    peak_bytes = 0
    live_bytes = 0
    errors = 0
    next_stats_ms = 0
    grace_over = False
    last_pass_ms = clock.now()
    while True:
        now_ms = clock.now()
        healthy = now_ms - last_pass_ms <= cfg["max_pass_ms"]
        last_pass_ms = now_ms
        try:
            if net.connected:
                net.poll(now_ms)
            elif net.due(now_ms) and unit.motor.mode == "brake":
                if net.connect(now_ms):
                    print("mqtt: connected to %s:%d" % (cfg["broker_host"], cfg["broker_port"]))
                else:
                    print("mqtt: %s; retrying" % net.last_error)
            unit.link_ok = net.connected
            unit.step(now_ms)
        except Exception as exc:  # never let the loop die: brake, report on the console, let the watchdog judge
            healthy = False
            errors += 1
            print("loop: %r" % (exc,))
            unit.motor.brake()
        used = gc.mem_alloc()
        if used > peak_bytes:
            peak_bytes = used
        if wdt is not None and healthy:
            wdt.feed()
        if not grace_over:
            if maint_pin.value() == 0:
                unit.motor.brake()
                print("maintenance: FLASH button held, the train loop stops and the REPL stays")
                return peak_bytes, live_bytes
            if now_ms >= cfg["repl_grace_ms"]:
                grace_over = True
                if sys.platform == "esp8266":   # UART0 goes to the IPS; the REPL comes back after a reset
                    import os

                    os.dupterm(None, 1)
        if now_ms >= next_stats_ms:
            next_stats_ms = now_ms + cfg["stats_ms"]
            print("stats: up_ms %d heap_peak %d heap_live %d heap_free %d link %s losses %d mode %s errors %d "
                  "sensor_errors %d" % (now_ms, peak_bytes, live_bytes, gc.mem_free(),
                                        "up" if net.connected else "down", net.losses, unit.mode, errors,
                                        unit.sensor_errors))
        if cfg["run_ms"] and now_ms >= cfg["run_ms"]:
            return peak_bytes, live_bytes
        gc.collect()
        used = gc.mem_alloc()
        if used > live_bytes:
            live_bytes = used
        sleep_ms(cfg["loop_ms"])


def build(cfg, drivers):
    """Second half of the boot: MQTT link, OnboardUnit and watchdog; returns (unit, link, wdt or None)."""
    import binascii

    from umqtt.simple import MQTTClient, MQTTException

    gc.collect()
    import wire

    gc.collect()
    import obu

    gc.collect()
    import link

    gc.collect()
    train_id = cfg["train_id"]
    client = MQTTClient("cbtc-" + train_id, cfg["broker_host"], cfg["broker_port"], cfg["mqtt_user"],
                        cfg["mqtt_password"], cfg["keepalive_s"])
    net = link.Link(client, wire.topic_status(train_id), (wire.topic_command(train_id),),
                    (OSError, MQTTException), cfg["backoff_min_ms"], cfg["backoff_max_ms"])
    unit = obu.OnboardUnit(train_id, binascii.unhexlify(cfg["key_hex"]), drivers["encoder"], drivers["ips"],
                           drivers["rfid"], drivers["motor"], net.publish, cfg["obu"])
    net.on_message = unit.on_message
    wdt = None
    if cfg["watchdog"]:
        import machine

        wdt = machine.WDT()
    return unit, net, wdt


def main():
    clock = Uptime()
    gc.collect()
    import startup

    cfg, drivers = startup.start(clock, VERSION, sleep_ms)
    del startup
    for name in ("startup", "board", "train_config", "network"):   # boot-only: their heap goes back
        sys.modules.pop(name, None)
    gc.collect()
    unit, net, wdt = build(cfg, drivers)
    gc.collect()
    print("stopped: heap_peak %d heap_live %d" % run(cfg, clock, unit, net, drivers["maint"], wdt))
