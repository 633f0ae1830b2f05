"""Second half of a train board's boot, run once by train.main() after startup.py has left the heap: the MQTT
client and its link policy (link.py), the OnboardUnit and the watchdog. train.main() drops this module afterwards,
so its code does not stay in the board's heap while the loop runs.
"""

import gc


def new_boot_id():
    """A random boot id in [1, 2^30-1], drawn once per boot: every report names it and every command must, so
    nothing recorded in another boot is ever taken for this one. Boot code: it leaves the heap with this module."""
    try:
        from os import urandom

        n = int.from_bytes(urandom(4), "big")
    except ImportError:   # a port without urandom; its random module is seeded from hardware at boot
        from random import getrandbits

        n = getrandbits(30)
    import wire

    return (n & wire.BOOT_MAX) or 1


def build(config, drivers):
    """Returns (unit, link, watchdog or None, loop config) for the config and drivers of startup.start(); the loop
    config holds only what train.run reads, so the rest of the config leaves the heap."""
    from binascii import unhexlify

    from umqtt.simple import MQTTClient, MQTTException

    gc.collect()
    import wire

    gc.collect()
    import obu

    gc.collect()
    import link

    gc.collect()
    train_id = config["train_id"]
    client = MQTTClient("cbtc-" + train_id, config["broker_host"], config["broker_port"], config["mqtt_user"],
                        config["mqtt_password"], config["keepalive_s"])
    net = link.Link(client, wire.topic_status(train_id), (wire.topic_command(train_id),), (OSError, MQTTException),
                    (config["backoff_min_ms"], config["backoff_max_ms"]), max(config["loop_ms"], 10))
    unit = obu.OnboardUnit(train_id, unhexlify(config["key_hex"]), new_boot_id(), drivers["encoder"], drivers["ips"],
                           drivers["rfid"], drivers["motor"], net.publish, config["obu"])
    net.on_message = unit.on_message
    wdt = None
    if config["watchdog"]:
        from machine import WDT

        wdt = WDT()
    loop = {}
    for name in ("max_pass_ms", "repl_grace_ms", "stats_ms", "run_ms", "loop_ms", "broker_host", "broker_port",
                 "integrity_loop"):
        loop[name] = config[name]
    return unit, net, wdt, loop
