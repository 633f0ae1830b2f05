"""The bus over a real MQTT broker without paho: MQTT 3.1.1 on a non-blocking socket driven by a `NetLoop`.

The same connection policy and interface as `PahoBus` in net mode (TCP_NODELAY; clean sessions, so every filter is
subscribed again on each connect; retained `online` status and `offline` as last will; reconnect with exponential
backoff; QoS per topic, `topic_qos`), for a fraction of paho's per-message work: one `recv` takes every packet that
has come, a publish is a few bytes appended to the output, and what the handlers of one poll published leaves in one
`send`. `cbtc bench latency --client paho|lean` measures both on the same broker; paho stays the reference.
"""

import logging
import socket
import time

from cbtc.bus import mqtt_packets as mp
from cbtc.bus.client import (
    OFFLINE,
    ONLINE,
    BusClient,
    checked_payload,
    parse_broker_url,
    topic_matches,
    topic_qos,
    validate_filter,
    validate_topic,
)
from cbtc.errors import BusError

log = logging.getLogger("cbtc.mqtt")

READ_BYTES = 65536
MAX_ROUTES = 4096        # topics whose callbacks are kept; more (a flood of topics) starts the table again
CONNECT_TIMEOUT_S = 2.0


class LeanBus(BusClient):
    """One connection to an MQTT broker on `net` (a NetLoop); implements `cbtc.bus.client.BusClient`."""

    def __init__(self, url: str, client_id: str, status_topic: str = None, username: str = None,
                 password: str = None, keepalive_s: int = 5, reconnect_min_s: float = 0.2,
                 reconnect_max_s: float = 2.0, net=None):
        if net is None:
            raise ValueError("LeanBus runs on a NetLoop: pass net=")
        host, port, url_user, url_password = parse_broker_url(url)
        self.host, self.port = host, port
        self.client_id = client_id
        self.status_topic = status_topic
        if status_topic is not None:
            validate_topic(status_topic)
        self.on_connect = None
        self.connects = 0
        self.losses = 0
        self.dropped = 0            # publishes while not connected (QoS 0: lost, as on the mock broker)
        self.refusal = ""           # the broker's reason when it refused the last CONNECT
        self._username = username if username is not None else url_user
        self._password = password if password is not None else url_password
        self._keepalive_s = keepalive_s
        self._reconnect_s = (reconnect_min_s, reconnect_max_s)
        self._retry_delay_s = reconnect_min_s
        self._retry_due_s = None    # when to open a lost connection again
        self._net = net
        self._sock = None
        self._in = bytearray()
        self._out = bytearray()
        self._connected = False
        self._answered = False      # the broker answered a CONNECT (accepted or refused)
        self._subs = {}             # filter -> callback
        self._routes = {}           # topic -> callbacks of the filters matching it (cleared when the filters change)
        self._unacked = set()       # packet ids of QoS 1 publishes not yet acknowledged
        self._next_id = 0
        self._last_in_s = self._last_out_s = 0.0
        self._ping_s = 0.0              # when the newest PINGREQ went out

    # --- lifecycle ---------------------------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> "LeanBus":
        """Connect, retrying with backoff while nothing listens, and wait for the first CONNACK. Raises BusError if
        the broker refuses us (credentials, ACL) or none answers within `timeout_s`."""
        deadline_s = time.monotonic() + timeout_s
        self._net.attach(self)
        self._retry_due_s = time.monotonic()
        while not self._answered and time.monotonic() < deadline_s:
            if self._retry_due_s is not None and time.monotonic() >= self._retry_due_s:
                self._open(time.monotonic())
            self._net.poll(min(0.05, max(0.0, deadline_s - time.monotonic())))
        if not self._answered:
            self._stop()
            raise BusError(f"{self.client_id}: no MQTT broker answered at {self.host}:{self.port} within "
                           f"{timeout_s:g} s; start one (e.g. `cbtc broker config` + mosquitto -c) or fix --broker")
        if not self._connected:
            self._stop()
            raise BusError(f"{self.client_id}: the broker at {self.host}:{self.port} refused the connection "
                           f"({self.refusal}); check --username/--password (or CBTC_MQTT_USERNAME/PASSWORD)")
        return self

    @property
    def connected(self) -> bool:
        return self._connected

    def disconnect(self) -> None:
        """Clean end: publish the retained `offline` status (if any) and wait for its PUBACK, then DISCONNECT (the
        will is not sent)."""
        if self.status_topic is not None and self._connected:
            pid = self._publish(self.status_topic, OFFLINE, topic_qos(self.status_topic), True)
            deadline_s = time.monotonic() + 1.0
            while pid in self._unacked and self._connected and time.monotonic() < deadline_s:
                self._net.poll(0.01)
        if self._sock is not None:
            self._out += mp.disconnect()
            self.net_write()
        self._stop()

    def _stop(self):
        self._close()
        self._net.detach(self)
        self._retry_due_s = None

    # --- BusClient ---------------------------------------------------------------------------------------------

    def publish(self, topic, payload, retain=False, qos=0):
        """Send `payload`; QoS is the higher of `qos` and `topic_qos(topic)`. Dropped (counted) while disconnected."""
        payload = checked_payload(topic, payload)
        if not self._connected:
            self.dropped += 1
            return
        self._publish(topic, payload, max(qos, topic_qos(topic)), retain)

    def _publish(self, topic, payload, qos, retain):
        pid = 0
        if qos:
            pid = self._packet_id()
            self._unacked.add(pid)
        self._out += mp.publish(topic, payload, qos, retain, pid)
        self._net.wants_write(self)   # written when the callback that published returns, or at the next poll
        return pid

    def subscribe(self, topic_filter, callback):
        """Route messages matching `topic_filter` to `callback(topic, payload)`; kept across reconnects."""
        validate_filter(topic_filter)
        self._subs[topic_filter] = callback
        self._routes.clear()
        if self._connected:
            self._out += mp.subscribe(self._packet_id(), [(topic_filter, topic_qos(topic_filter))])
            self._net.wants_write(self)

    def unsubscribe(self, topic_filter):
        self._subs.pop(topic_filter, None)
        self._routes.clear()
        if self._connected:
            self._out += mp.unsubscribe(self._packet_id(), [topic_filter])
            self._net.wants_write(self)

    def _packet_id(self):
        self._next_id = self._next_id % 65535 + 1
        return self._next_id

    # --- driven by the NetLoop ----------------------------------------------------------------------------------

    def net_socket(self):
        return self._sock

    def net_wants_write(self) -> bool:
        return self._sock is not None and bool(self._out)

    def net_write(self) -> None:
        if self._sock is None or not self._out:
            return
        try:
            sent = self._sock.send(self._out)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            self._lost(f"writing: {exc}")
            return
        del self._out[:sent]
        self._last_out_s = time.monotonic()

    def net_read(self) -> None:
        if self._sock is None:
            return
        try:
            data = self._sock.recv(READ_BYTES)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as exc:
            self._lost(f"reading: {exc}")
            return
        if not data:
            self._lost("the broker closed the connection")
            return
        self._last_in_s = time.monotonic()
        self._in += data
        try:
            for first, body in mp.split(self._in):
                self._handle(first, body)
                if self._sock is None:
                    return   # a handler or the broker ended the connection
        except mp.ProtocolError as exc:
            self._lost(f"protocol error: {exc}")
            return
        if self._out:
            self._net.wants_write(self)

    def net_misc(self, now_s: float) -> None:
        """Keepalive as paho keeps it: a PINGREQ when nothing was written, or nothing read, for the keepalive period
        (a client that only publishes hears nothing else from the broker); a loss when nothing was read for one and
        a half. A lost connection is opened again when its backoff delay is over."""
        if self._sock is not None:
            quiet_s = now_s - max(self._last_in_s, self._ping_s)
            if self._connected and (now_s - self._last_out_s >= self._keepalive_s or quiet_s >= self._keepalive_s):
                self._out += mp.pingreq()
                self._ping_s = now_s
                self._net.wants_write(self)
            if now_s - self._last_in_s >= 1.5 * self._keepalive_s:
                self._lost("no answer from the broker within 1.5 keepalive periods")
        elif self._retry_due_s is not None and now_s >= self._retry_due_s:
            self._open(now_s)

    # --- the connection -----------------------------------------------------------------------------------------

    def _open(self, now_s: float) -> None:
        """Open the connection (first time or again) and send CONNECT; on failure, try again after a doubled delay."""
        try:
            sock = socket.create_connection((self.host, self.port), timeout=CONNECT_TIMEOUT_S)
        except OSError as exc:
            self._retry_due_s = now_s + self._retry_delay_s
            self._retry_delay_s = min(self._retry_delay_s * 2.0, self._reconnect_s[1])
            log.debug("%s: connecting to %s:%d failed (%s)", self.client_id, self.host, self.port, exc)
            return
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)
        self._sock = sock
        self._retry_due_s = None
        self._in.clear()
        self._out.clear()
        self._unacked.clear()
        will = None
        if self.status_topic is not None:
            will = (self.status_topic, OFFLINE, topic_qos(self.status_topic), True)
        self._out += mp.connect(self.client_id, self._keepalive_s, will, self._username, self._password)
        self._last_in_s = self._last_out_s = time.monotonic()
        self._net.socket_changed(self)
        self._net.wants_write(self)

    def _handle(self, first: int, body: bytes) -> None:
        kind = first & 0xF0
        if kind == mp.PUBLISH:
            topic, payload, qos, pid, _retain = mp.parse_publish(first, body)
            if qos:
                self._out += mp.puback(pid)
            callbacks = self._routes.get(topic)
            if callbacks is None:
                if len(self._routes) >= MAX_ROUTES:
                    self._routes.clear()
                callbacks = self._routes[topic] = tuple(
                    dict.fromkeys(cb for f, cb in self._subs.items() if topic_matches(f, topic)))
            for callback in callbacks:
                try:
                    callback(topic, payload)
                except Exception as exc:  # a subscriber's bug must not kill the network loop
                    self._net.callback_failed(callback, exc)
        elif kind == mp.PUBACK:
            if len(body) == 2:
                self._unacked.discard((body[0] << 8) | body[1])
        elif kind == mp.CONNACK:
            self._connack(body)
        elif kind == mp.SUBACK:
            if mp.SUBACK_FAILURE in body[2:]:
                log.warning("%s: the broker refused a subscription (its ACL?): %s", self.client_id, sorted(self._subs))
        elif kind not in (mp.UNSUBACK, mp.PINGRESP):
            raise mp.ProtocolError(f"unexpected packet type 0x{first:02x}")

    def _connack(self, body: bytes) -> None:
        self._answered = True
        code = body[1] if len(body) >= 2 else 255
        if code != 0:
            self.refusal = mp.CONNACK_REASONS.get(code, f"CONNACK code {code}")
            # on the first connection start() raises with the reason; on a reconnect it is said here
            (log.warning if self.connects else log.debug)("%s: broker %s:%d refused the connection: %s",
                                                          self.client_id, self.host, self.port, self.refusal)
            self._close()
            if self.connects:   # refused on a reconnect: keep trying, as after a loss, less and less often
                self._retry_due_s = time.monotonic() + self._retry_delay_s
                self._retry_delay_s = min(self._retry_delay_s * 2.0, self._reconnect_s[1])
            return
        self._connected = True
        self.connects += 1
        self._retry_delay_s = self._reconnect_s[0]
        self.refusal = ""
        if self._subs:
            self._out += mp.subscribe(self._packet_id(), [(f, topic_qos(f)) for f in self._subs])
        if self.status_topic is not None:
            self._publish(self.status_topic, ONLINE, topic_qos(self.status_topic), True)
        if self.connects > 1:
            log.warning("%s: reconnected to %s:%d", self.client_id, self.host, self.port)
        if self.on_connect is not None:
            try:
                self.on_connect(self)
            except Exception as exc:
                self._net.callback_failed(self.on_connect, exc)

    def _lost(self, why: str) -> None:
        """The connection is gone: close it, and open it again after the backoff delay."""
        if self._connected:
            self.losses += 1
            log.warning("%s: lost the broker (%s); reconnecting", self.client_id, why)
        self._close()
        self._retry_due_s = time.monotonic() + self._retry_delay_s
        # the next loss before a CONNACK waits twice as long: a broker that accepts and drops is not hammered
        self._retry_delay_s = min(self._retry_delay_s * 2.0, self._reconnect_s[1])

    def _close(self) -> None:
        was = self._sock
        self._sock = None
        self._connected = False
        self._out.clear()
        if was is not None:
            try:
                was.close()
            except OSError:
                pass
            self._net.socket_changed(self)
