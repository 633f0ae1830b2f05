"""Which MQTT client a live command connects with: `lean` (cbtc.bus.lean_bus, the default: a fraction of paho's work
per message) or `paho` (cbtc.bus.paho_bus, the reference). Both run on the process's NetLoop."""

MQTT_CLIENTS = ("lean", "paho")


def start_bus(kind: str, url: str, client_id: str, net, **options):
    """A connected bus of client `kind` on `net` (options: status_topic, username, password, keepalive_s, ...)."""
    if kind == "paho":
        from cbtc.bus.paho_bus import PahoBus
        return PahoBus(url, client_id, net=net, **options).start()
    if kind == "lean":
        from cbtc.bus.lean_bus import LeanBus
        return LeanBus(url, client_id, net=net, **options).start()
    raise ValueError(f"MQTT client {kind!r}: choose one of {', '.join(MQTT_CLIENTS)}")
