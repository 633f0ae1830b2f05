"""First half of a train board's boot, run once by train.main(): config, drivers, Wi-Fi.

Config: DEFAULTS below, overridden by the per-board `train_config.py` (CONFIG dict; never committed: it holds the
train's key and Wi-Fi password; see train_config.py.example, or let `cbtc flash` write it). Pins: board.py.
Nothing here is needed afterwards: train.main() drops this module (and board, train_config, network) from
sys.modules before it loads the MQTT client, the protocol and the OnboardUnit, so the ESP8266's small heap never
holds both halves at once.
"""

import gc

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
    "integrity_loop": False,  # a train line is wired (board.py, TX): a car that comes off opens it and the train stops
    "obu": {},                # OnboardUnit overrides, e.g. {"counts_per_m": 1250}; see obu.DEFAULTS
}


def start(now, version, sleep_ms):
    """Config, drivers (motor braked), Wi-Fi (`now()` gives board ms); returns (cfg, drivers dict: see
    board.make_drivers). Prints the boot line `lego-cbtc train <id> boot <version>` that `cbtc flash` waits for.
    The config is DEFAULTS overridden by train_config.CONFIG; ValueError naming the key if one is missing or unknown.
    Wi-Fi: join the configured network, retrying until it works (the train is braked meanwhile)."""
    try:
        from train_config import CONFIG
    except ImportError:
        raise ValueError("no train_config.py on the board: run `cbtc flash --train ID ...` or copy "
                         "train_config.py.example to train_config.py and fill it in")
    cfg = dict(DEFAULTS)
    for name in CONFIG:
        if name not in DEFAULTS:
            raise ValueError("train_config.py: unknown key %r; known: %s" % (name, ", ".join(sorted(DEFAULTS))))
        cfg[name] = CONFIG[name]
    for name in ("train_id", "key_hex"):
        if not cfg[name]:
            raise ValueError("train_config.py: %r is required" % name)
    if len(cfg["key_hex"]) != 32:
        raise ValueError("train_config.py: 'key_hex' must be 32 hex digits (16 bytes)")
    print("lego-cbtc train %s boot %s" % (cfg["train_id"], version))
    import board

    drivers = board.make_drivers()
    gc.collect()
    if cfg["wifi_ssid"]:
        import network

        sta = network.WLAN(network.STA_IF)
        sta.active(True)
        while not sta.isconnected():
            print("wifi: joining %s" % cfg["wifi_ssid"])
            sta.connect(cfg["wifi_ssid"], cfg["wifi_password"])
            start_ms = now()
            while not sta.isconnected() and now() - start_ms < cfg["wifi_timeout_ms"]:
                sleep_ms(100)
        print("wifi: %s" % (sta.ifconfig()[0],))
    return cfg, drivers
