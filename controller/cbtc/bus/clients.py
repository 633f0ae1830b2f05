"""Which MQTT client a live command connects with: `lean` (cbtc.bus.lean_bus, the default: a fraction of paho's work
per message) or `paho` (cbtc.bus.paho_bus, the reference). Both run on the process's NetLoop."""

MQTT_CLIENTS = ("lean", "paho")


def start_bus(kind: str, url: str, client_id: str, net, login: str = None, **options):
    """A connected bus of client `kind` on `net` (options: status_topic, username, password, keepalive_s, ...).
    A broker that cannot be reached is said by cause (cbtc.bus.reach); a refused login names `login`, where the
    user name and password came from."""
    from cbtc.bus.reach import LOGIN_OPTIONS, reach, refused_login
    from cbtc.errors import BusError

    if kind == "paho":
        from cbtc.bus.paho_bus import PahoBus as Bus
    elif kind == "lean":
        from cbtc.bus.lean_bus import LeanBus as Bus
    else:
        raise ValueError(f"MQTT client {kind!r}: choose one of {', '.join(MQTT_CLIENTS)}")
    bus = Bus(url, client_id, net=net, **options)
    reach(bus.host, bus.port, client_id)
    try:
        return bus.start()
    except BusError:
        if bus.refusal:
            raise BusError(refused_login(client_id, bus.host, bus.port, bus.refusal, login or LOGIN_OPTIONS)) from None
        raise
