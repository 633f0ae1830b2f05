"""The bus over a real MQTT broker, through paho-mqtt (v2 callback API): the same interface as the mock broker.

This is the one place that owns the connection policy: paho's network thread connects, and after a loss reconnects
with exponential backoff (`reconnect_delay_set`); the connect handler sets TCP_NODELAY on the socket (without it,
Nagle's algorithm adds 40-90 ms to a round trip), subscribes again to every filter (clean sessions: the broker
forgets them) and publishes the retained `online` status; the last will publishes `offline` if the link dies.

QoS per topic (`topic_qos`): status topics QoS 1 and retained, so "who is alive" reaches a late or reconnecting
subscriber exactly as last set; reports and commands QoS 0, because each is superseded 100 ms later and the
onboard command watchdog, not the broker, makes a lost command safe (a redelivered old command would be stale
anyway). See docs/protocol.md and docs/mqtt.md.

Threads: with a `NetLoop` (`net=`, what `cbtc zone`, `cbtc trains` and the benches use), there is no network thread:
the loop's thread reads the socket and runs the callbacks, and a command published in answer to a report is written
as the callback returns (cbtc.bus.net_loop). Without one, paho runs its own thread per connection and the callbacks
run on it.
"""

import logging
import socket
import threading
import time

import paho.mqtt.client as mqtt

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

log = logging.getLogger("cbtc.paho")

class PahoBus(BusClient):
    """One connection to an MQTT broker; implements `cbtc.bus.client.BusClient`.

    `status_topic`: the client's retained status topic (`online` on every connect, `offline` as last will and on a
    clean `disconnect`)."""

    def __init__(self, url: str, client_id: str, status_topic: str = None, username: str = None,
                 password: str = None, keepalive_s: int = 5,
                 reconnect_min_s: float = 0.2, reconnect_max_s: float = 2.0, net=None):
        host, port, url_user, url_password = parse_broker_url(url)
        self.host, self.port = host, port
        self.client_id = client_id
        self.status_topic = status_topic
        self.on_connect = None
        self.connects = 0
        self.losses = 0
        self.dropped = 0            # publishes while not connected (QoS 0: lost, as on the mock broker)
        self.refusal = ""           # the broker's reason when it refused the last CONNECT
        self._subs = {}             # filter -> callback
        self._lock = threading.Lock()
        self._connected = threading.Event()
        self._answered = threading.Event()   # the broker answered a CONNECT (accepted or refused)
        self._client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=True)
        username = username if username is not None else url_user
        password = password if password is not None else url_password
        if username is not None:
            self._client.username_pw_set(username, password)
        if status_topic is not None:
            validate_topic(status_topic)
            self._client.will_set(status_topic, OFFLINE, qos=topic_qos(status_topic), retain=True)
        self._client.reconnect_delay_set(reconnect_min_s, reconnect_max_s)
        self._client.on_connect = self._on_connect
        self._client.on_disconnect = self._on_disconnect
        self._client.on_message = self._on_message
        self._keepalive_s = keepalive_s
        self._started = False
        self._net = net                          # a NetLoop: no paho thread, the loop drives the socket
        self._reconnect_s = (reconnect_min_s, reconnect_max_s)
        self._retry_delay_s = reconnect_min_s
        self._retry_due_s = None                 # when to open a lost connection again (net mode)

    # --- lifecycle ---------------------------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> "PahoBus":
        """Connect (paho's thread keeps reconnecting from now on) and wait for the first CONNACK.

        Raises BusError if the broker refuses us (credentials, ACL) or does not answer within `timeout_s`."""
        if self._net is not None:
            self._start_on_net(timeout_s)
        else:
            self._client.connect_async(self.host, self.port, keepalive=self._keepalive_s)
            self._client.loop_start()
            self._started = True
            self._answered.wait(timeout_s)
        if not self._answered.is_set():
            self._stop_loop()
            raise BusError(f"{self.client_id}: no MQTT broker answered at {self.host}:{self.port} within "
                           f"{timeout_s:g} s; start one (e.g. `cbtc broker config` + mosquitto -c) or fix --broker")
        if not self._connected.is_set():
            self._stop_loop()
            raise BusError(f"{self.client_id}: the broker at {self.host}:{self.port} refused the connection "
                           f"({self.refusal}); check --username/--password (or CBTC_MQTT_USERNAME/PASSWORD)")
        return self

    @property
    def connected(self) -> bool:
        return self._connected.is_set()

    def disconnect(self) -> None:
        """Clean end: publish the retained `offline` status (if any), then DISCONNECT (the will is not sent)."""
        if self.status_topic is not None and self.connected:
            info = self._client.publish(self.status_topic, OFFLINE, qos=topic_qos(self.status_topic), retain=True)
            if self._net is not None:
                deadline_s = time.monotonic() + 1.0
                while not info.is_published() and self.connected and time.monotonic() < deadline_s:
                    self._net.poll(0.01)
            else:
                try:
                    info.wait_for_publish(timeout=1.0)
                except (RuntimeError, ValueError):
                    pass  # lost the connection meanwhile: the will says offline
        self._client.disconnect()
        self._stop_loop()
        self._connected.clear()

    def _stop_loop(self):
        if self._net is not None:
            self._net.detach(self)
            self._retry_due_s = None
        elif self._started:
            self._client.loop_stop()
            self._started = False

    # --- net mode: the NetLoop's thread drives the socket ----------------------------------------------------------

    def _start_on_net(self, timeout_s: float) -> None:
        """Connect, retrying with backoff while nothing listens, then run the net loop until the broker answers."""
        deadline_s = time.monotonic() + timeout_s
        self._client.connect_async(self.host, self.port, keepalive=self._keepalive_s)   # sets the address only
        self._net.attach(self)
        self._retry_due_s = time.monotonic()
        while not self._answered.is_set() and time.monotonic() < deadline_s:
            if self._retry_due_s is not None and time.monotonic() >= self._retry_due_s:
                self._open(time.monotonic())
            self._net.poll(min(0.05, max(0.0, deadline_s - time.monotonic())))

    def _open(self, now_s: float) -> None:
        """Open the connection (first time or again); on failure, try again after a doubled delay."""
        try:
            self._client.reconnect()
        except OSError as exc:
            self._retry_due_s = now_s + self._retry_delay_s
            self._retry_delay_s = min(self._retry_delay_s * 2.0, self._reconnect_s[1])
            log.debug("%s: connecting to %s:%d failed (%s)", self.client_id, self.host, self.port, exc)
            return
        self._retry_due_s = None
        sock = self._client.socket()
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._net.socket_changed(self)
        self._net.wants_write(self)    # the CONNECT, if the kernel did not take it at once

    def net_socket(self):
        return self._client.socket()

    def net_read(self) -> None:
        self._client.loop_read()
        if self._client.want_write():
            self._net.wants_write(self)
        self._lost_check()

    def net_wants_write(self) -> bool:
        return self._client.socket() is not None and self._client.want_write()

    def net_write(self) -> None:
        self._client.loop_write()
        self._lost_check()

    def net_misc(self, now_s: float) -> None:
        """Keepalive; and a lost connection opened again when its backoff delay is over."""
        if self._client.socket() is not None:
            self._client.loop_misc()
            self._lost_check()
        elif self._retry_due_s is not None and now_s >= self._retry_due_s:
            self._open(now_s)

    def _lost_check(self) -> None:
        if self._client.socket() is None and self._retry_due_s is None and self._net is not None:
            self._retry_due_s = time.monotonic() + self._retry_delay_s
            # the next loss before a CONNACK waits twice as long (the delay is the least again on a connect)
            self._retry_delay_s = min(self._retry_delay_s * 2.0, self._reconnect_s[1])
            self._net.socket_changed(self)

    # --- BusClient ---------------------------------------------------------------------------------------------

    def publish(self, topic, payload, retain=False, qos=0):
        """Send `payload`; QoS is the higher of `qos` and `topic_qos(topic)`. Dropped (counted) while disconnected."""
        payload = checked_payload(topic, payload)
        if not self.connected:
            self.dropped += 1
            return
        info = self._client.publish(topic, payload, qos=max(qos, topic_qos(topic)), retain=retain)
        if info.rc != mqtt.MQTT_ERR_SUCCESS:
            self.dropped += 1
        if self._net is not None and self._client.want_write():
            self._net.wants_write(self)   # published inside a callback: written when it returns

    def subscribe(self, topic_filter, callback):
        """Route messages matching `topic_filter` to `callback(topic, payload)`; kept across reconnects."""
        validate_filter(topic_filter)
        with self._lock:
            self._subs[topic_filter] = callback
        if self.connected:
            self._client.subscribe(topic_filter, qos=topic_qos(topic_filter))

    def unsubscribe(self, topic_filter):
        with self._lock:
            self._subs.pop(topic_filter, None)
        if self.connected:
            self._client.unsubscribe(topic_filter)

    # --- paho's thread -------------------------------------------------------------------------------------------

    def _on_connect(self, client, _userdata, _flags, reason_code, _properties):
        if reason_code.is_failure:
            self.refusal = str(reason_code)
            # on the first connection start() raises with the reason; on a reconnect it is said here
            (log.warning if self._answered.is_set() else log.debug)(
                "%s: broker %s:%d refused the connection: %s", self.client_id, self.host, self.port, reason_code)
            self._answered.set()
            return
        sock = client.socket()
        if sock is not None:
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            filters = list(self._subs)
        for topic_filter in filters:
            client.subscribe(topic_filter, qos=topic_qos(topic_filter))
        if self.status_topic is not None:
            client.publish(self.status_topic, ONLINE, qos=topic_qos(self.status_topic), retain=True)
        self.connects += 1
        self._retry_delay_s = self._reconnect_s[0]
        self.refusal = ""
        self._connected.set()
        self._answered.set()
        if self.connects > 1:
            log.warning("%s: reconnected to %s:%d", self.client_id, self.host, self.port)
        if self.on_connect is not None:
            self._dispatch(self._run_on_connect)

    def _run_on_connect(self):
        if self.on_connect is not None:
            self.on_connect(self)

    def _on_disconnect(self, _client, _userdata, _flags, reason_code, _properties):
        if self._connected.is_set():
            self._connected.clear()
            if reason_code.is_failure:
                self.losses += 1
                log.warning("%s: lost the broker (%s); reconnecting", self.client_id, reason_code)
        elif not self._answered.is_set() and self._net is not None:
            self._lost_check()   # the broker closed before answering: try again after the backoff delay

    def _on_message(self, _client, _userdata, message):
        topic = message.topic
        payload = bytes(message.payload)
        with self._lock:
            callbacks = []
            for topic_filter, callback in self._subs.items():
                if topic_matches(topic_filter, topic) and callback not in callbacks:
                    callbacks.append(callback)
        for callback in callbacks:
            self._dispatch(callback, topic, payload)

    def _dispatch(self, fn, *args):
        try:
            fn(*args)
        except Exception as exc:  # a subscriber's bug must not kill the network loop or paho's thread
            if self._net is not None:
                self._net.callback_failed(fn, exc)
            else:
                log.exception("%s: callback failed", self.client_id)
