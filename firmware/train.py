"""Boot of a train board (main.py calls `main()`): config, Wi-Fi, MQTT, then the OnboardUnit loop, for ever.

Config: DEFAULTS below, overridden by the per-board `train_config.py` (CONFIG dict; never committed: it holds the
train's key and Wi-Fi password; see train_config.py.example, or let `cbtc flash` write it). Pins: board.py.

The loop polls MQTT without blocking, keeps a monotonic, non-wrapping uptime (ms) from ticks_ms/ticks_diff and hands
it to the OnboardUnit. The hardware watchdog is fed only after a healthy pass (no exception, the previous pass
recent). When the broker is lost the loop goes on (the unit brakes when its command expires); reconnect attempts,
which may block, are made with backoff and only while the motor is held braked.
"""

import gc
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

DEFAULTS = {
    "train_id": None,         # 1-16 of A-Z a-z 0-9 _ -
    "key_hex": None,          # the train's 16-byte HMAC key, 32 hex digits (shared with the zone controller)
    "wifi_ssid": None,        # None: the network interface is left as it is (already connected, or wired)
    "wifi_password": "",
    "wifi_timeout_ms": 15000, # give up one Wi-Fi attempt after this long, then try again (ms)
    "broker_host": "192.168.1.10",
    "broker_port": 1883,
    "mqtt_user": None,
    "mqtt_password": None,
    "keepalive_s": 10,        # MQTT keepalive; the broker publishes our `offline` will 1.5x this after we vanish (s)
    "backoff_min_ms": 500,    # first reconnect delay, doubling up to backoff_max_ms (ms)
    "backoff_max_ms": 8000,
    "loop_ms": 10,            # sleep between loop passes (ms)
    "max_pass_ms": 500,       # a pass later than this after the previous one does not feed the watchdog (ms)
    "watchdog": True,         # use machine.WDT (on the ESP8266 its timeout is fixed, about 3 s)
    "stats_ms": 10000,        # print uptime, heap peak and link state this often (ms)
    "run_ms": 0,              # stop the loop after this long (ms); 0: run for ever (tests use it)
    "repl_grace_ms": 2000,    # boot window: the REPL stays and the FLASH button is watched, then UART0 goes to the IPS
    "obu": {},                # OnboardUnit overrides, e.g. {"counts_per_m": 1250}; see obu.DEFAULTS
}


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


def load_config():
    """DEFAULTS overridden by train_config.CONFIG; ValueError naming the key if something is missing or unknown."""
    try:
        import train_config
    except ImportError:
        raise ValueError("no train_config.py on the board: run `cbtc flash --train ID ...` or copy "
                         "train_config.py.example to train_config.py and fill it in")
    cfg = dict(DEFAULTS)
    for name in train_config.CONFIG:
        if name not in DEFAULTS:
            raise ValueError("train_config.py: unknown key %r; known: %s" % (name, ", ".join(sorted(DEFAULTS))))
        cfg[name] = train_config.CONFIG[name]
    for name in ("train_id", "key_hex"):
        if not cfg[name]:
            raise ValueError("train_config.py: %r is required" % name)
    if len(cfg["key_hex"]) != 32:
        raise ValueError("train_config.py: 'key_hex' must be 32 hex digits (16 bytes)")
    return cfg


def connect_wifi(cfg, clock):
    """Join the configured network, retrying until it works (the train is braked meanwhile)."""
    if not cfg["wifi_ssid"]:
        return
    import network

    sta = network.WLAN(network.STA_IF)
    sta.active(True)
    while not sta.isconnected():
        print("wifi: joining %s" % cfg["wifi_ssid"])
        sta.connect(cfg["wifi_ssid"], cfg["wifi_password"])
        start = clock.now()
        while not sta.isconnected() and clock.now() - start < cfg["wifi_timeout_ms"]:
            sleep_ms(100)
    print("wifi: %s" % (sta.ifconfig()[0],))


def start(cfg, clock):
    """Build drivers, MQTT link and OnboardUnit; returns (unit, link)."""
    import binascii

    import board

    drivers = board.make_drivers()
    gc.collect()
    connect_wifi(cfg, clock)
    gc.collect()
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
    gc.collect()
    return unit, net


def run(cfg, clock, unit, net, wdt=None):
    """The loop; returns the peak heap use (bytes) after cfg['run_ms'] (if > 0), or with the motor braked when the
    FLASH button is held in the boot window (maintenance: the REPL stays)."""
    import board

    peak_bytes = 0
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
            if board.maintenance_requested():
                unit.motor.brake()
                print("maintenance: FLASH button held, the train loop stops and the REPL stays")
                return peak_bytes
            if now_ms >= cfg["repl_grace_ms"]:
                grace_over = True
                board.detach_repl()
        if now_ms >= next_stats_ms:
            next_stats_ms = now_ms + cfg["stats_ms"]
            print("stats: up_ms %d heap_peak %d heap_free %d link %s losses %d mode %s errors %d sensor_errors %d"
                  % (now_ms, peak_bytes, gc.mem_free(), "up" if net.connected else "down", net.losses, unit.mode,
                     errors, unit.sensor_errors))
        if cfg["run_ms"] and now_ms >= cfg["run_ms"]:
            return peak_bytes
        gc.collect()
        sleep_ms(cfg["loop_ms"])


def main():
    clock = Uptime()
    cfg = load_config()
    print("lego-cbtc train %s boot %s" % (cfg["train_id"], VERSION))
    gc.collect()
    unit, net = start(cfg, clock)
    wdt = None
    if cfg["watchdog"]:
        import machine

        wdt = machine.WDT()
    peak_bytes = run(cfg, clock, unit, net, wdt)
    print("stopped: heap_peak %d" % peak_bytes)

