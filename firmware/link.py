"""The board's MQTT policy: connect, last will, TCP_NODELAY, resubscribe, reconnect with backoff.

The MQTT client (umqtt.simple on the board) only speaks the protocol; this module owns what happens around it and is
the only place that catches the client's errors (OSError, and MQTTException for a refused CONNACK). Nothing blocks
for long here except `connect`, which opens a socket: the main loop calls it only while the train is held braked.
"""

try:
    from . import wire  # the controller imports the firmware as the package cbtc.firmware
except ImportError:
    import wire  # a board holds the firmware's modules at the top level

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_IPPROTO_TCP = const(6)   # lwIP and Linux agree on these values; MicroPython ports may not export the names
_TCP_NODELAY = const(1)
_MAX_MESSAGES = const(4)  # messages taken per poll, so a flood cannot starve the loop


class Link:
    # state that starts like this on every link (class attributes: an instance pays for one only once it changes it)
    on_message = None   # callable(topic: str, payload: bytes, now_ms)
    connected = False
    losses = 0          # connections lost
    last_error = ""     # repr of the error that lost (or refused) the connection
    now_ms = 0          # board ms of the current poll, handed on to on_message
    _next_try_ms = 0

    def __init__(self, client, status_topic, subscriptions, errors=(OSError,), backoff_ms=(500, 8000)):
        """`client`: an umqtt.simple.MQTTClient; `subscriptions`: topics to (re)subscribe after every connect;
        `errors`: the exception classes that mean the connection is gone; `backoff_ms`: (first, longest) delay before
        a reconnect attempt (ms): it doubles after each failure and starts again at the first after a success."""
        self.client = client
        self.status_topic = status_topic
        self.subscriptions = subscriptions
        self.errors = errors
        self.backoff_ms = backoff_ms
        self._backoff_ms = backoff_ms[0]
        client.set_last_will(status_topic, b"offline", True, 1)   # retained
        client.set_callback(self._deliver)

    def due(self, now_ms):
        """True when disconnected and the backoff since the last failure has passed (board ms)."""
        return not self.connected and wire.wrap_diff(now_ms, self._next_try_ms) >= 0

    def connect(self, now_ms):
        """One attempt: connect, TCP_NODELAY, `online` retained, subscribe. True on success."""
        self.now_ms = now_ms
        try:
            self.client.connect()
            self.client.sock.setsockopt(_IPPROTO_TCP, _TCP_NODELAY, 1)
            self.client.publish(self.status_topic, b"online", True, 1)
            for topic in self.subscriptions:
                self.client.subscribe(topic)
        except self.errors as exc:
            self._lost(now_ms, exc)
            return False
        self.connected = True
        self._backoff_ms = self.backoff_ms[0]
        return True

    def poll(self, now_ms):
        """Take waiting messages (never blocks); each goes to on_message with `now_ms`."""
        if not self.connected:
            return
        self.now_ms = now_ms
        try:
            for _ in range(_MAX_MESSAGES):
                self._delivered = False
                self.client.check_msg()
                if not self._delivered:
                    break
        except self.errors as exc:
            self._lost(now_ms, exc)

    def publish(self, topic, payload):
        """Publish QoS 0; False (and the link marked lost) if the connection is gone."""
        if not self.connected:
            return False
        try:
            self.client.publish(topic, payload)
        except self.errors as exc:
            self._lost(self.now_ms, exc)
            return False
        return True

    def _deliver(self, topic, payload):
        self._delivered = True
        if self.on_message is not None:
            self.on_message(topic.decode(), payload, self.now_ms)

    def _lost(self, now_ms, exc):
        if self.connected:
            self.losses += 1
        self.connected = False
        self.last_error = repr(exc)
        sock = self.client.sock
        if sock is not None:
            try:
                sock.close()
            except OSError:
                pass
        self._next_try_ms = wire.wrap_add(now_ms, self._backoff_ms)
        self._backoff_ms = min(self._backoff_ms * 2, self.backoff_ms[1])
