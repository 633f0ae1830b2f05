"""The board's MQTT policy: connect, last will, TCP_NODELAY, resubscribe, reconnect with backoff.

The MQTT client (umqtt.simple on the board) only speaks the protocol; this module owns what happens around it and is
the only place that catches the client's errors (OSError, and MQTTException for a refused CONNACK). Nothing blocks
for long here except `connect`, which opens a socket: the main loop calls it only while the train is held braked.
"""

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

_IPPROTO_TCP = const(6)   # lwIP and Linux agree on these values; MicroPython ports may not export the names
_TCP_NODELAY = const(1)
_MAX_MESSAGES = const(4)  # messages taken per poll, so a flood cannot starve the loop

ONLINE = b"online"
OFFLINE = b"offline"


class Link:
    def __init__(self, client, status_topic, subscriptions, errors=(OSError,), backoff_min_ms=500,
                 backoff_max_ms=8000):
        """`client`: an umqtt.simple.MQTTClient; `subscriptions`: topics to (re)subscribe after every connect;
        `errors`: the exception classes that mean the connection is gone; backoff in ms, doubling up to the max."""
        self.client = client
        self.status_topic = status_topic
        self.subscriptions = subscriptions
        self.errors = errors
        self.backoff_min_ms = backoff_min_ms
        self.backoff_max_ms = backoff_max_ms
        self._backoff_ms = backoff_min_ms
        self._next_try_ms = 0
        self.now_ms = 0
        self._delivered = False
        self.on_message = None      # callable(topic: str, payload: bytes, now_ms)
        self.connected = False
        self.connects = 0
        self.losses = 0
        self.last_error = ""
        client.set_last_will(status_topic, OFFLINE, True, 1)
        client.set_callback(self._deliver)

    def due(self, now_ms):
        """True when disconnected and the backoff since the last failure has passed (board ms)."""
        return not self.connected and now_ms >= self._next_try_ms

    def connect(self, now_ms):
        """One attempt: connect, TCP_NODELAY, `online` retained, subscribe. True on success."""
        self.now_ms = now_ms
        try:
            self.client.connect()
            self.client.sock.setsockopt(_IPPROTO_TCP, _TCP_NODELAY, 1)
            self.client.publish(self.status_topic, ONLINE, True, 1)
            for topic in self.subscriptions:
                self.client.subscribe(topic)
        except self.errors as exc:
            self._lost(now_ms, exc)
            return False
        self.connected = True
        self.connects += 1
        self._backoff_ms = self.backoff_min_ms
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
        self._next_try_ms = now_ms + self._backoff_ms
        self._backoff_ms = min(self._backoff_ms * 2, self.backoff_max_ms)
