"""An in-process MQTT broker on a virtual clock: deterministic, fast, and made for fault injection.

MQTT semantics where they matter to the testbed: '+'/'#' filters, retained messages (an empty payload deletes),
last will on abrupt loss (not on a clean disconnect), clean sessions (subscriptions are lost on reconnect, so the
owner resubscribes in `on_connect`), QoS 0 delivery in order per connection. Each client has an `up` link (client ->
broker) and a `down` link (broker -> client) with latency, jitter and loss drawn from the broker's seeded RNG, so
the same seed and the same calls give the same deliveries at the same virtual times. It is for simulation; the
integration tests use a real Mosquitto.
"""

import random
from dataclasses import dataclass

from .bus import topic_matches, validate_filter, validate_topic


@dataclass
class LinkProfile:
    """One direction of a client's link."""

    latency_s: float = 0.002
    jitter_s: float = 0.0     # extra delay, uniform in [0, jitter_s]
    loss: float = 0.0         # probability a message is lost on this link

    def __post_init__(self):
        if self.latency_s < 0 or self.jitter_s < 0 or not 0.0 <= self.loss <= 1.0:
            raise ValueError(f"link profile {self}: latency and jitter must be >= 0, loss in [0, 1]")


class MockClient:
    def __init__(self, broker, client_id, will, up, down):
        self._broker = broker
        self.client_id = client_id
        self.will = will
        self.up = up or LinkProfile()
        self.down = down or LinkProfile()
        self.on_connect = None
        self._subs = {}               # filter -> callback
        self._connected = True
        self._session = 0             # bumped on every (re)connect: late deliveries to an old session are dropped
        self._last_up_s = 0.0
        self._last_down_s = 0.0

    @property
    def connected(self) -> bool:
        return self._connected

    def publish(self, topic, payload, retain=False, qos=0):
        validate_topic(topic)
        if not isinstance(payload, (bytes, bytearray)):
            raise TypeError(f"payload on {topic} must be bytes, got {type(payload).__name__}")
        self._broker._from_client(self, topic, bytes(payload), retain)

    def subscribe(self, topic_filter, callback):
        validate_filter(topic_filter)
        if not self._connected:
            return
        self._subs[topic_filter] = callback
        self._broker._send_retained(self, topic_filter)

    def unsubscribe(self, topic_filter):
        self._subs.pop(topic_filter, None)

    def disconnect(self):
        """Clean disconnect: the last will is discarded."""
        self._connected = False
        self._subs.clear()

    def reconnect(self) -> bool:
        """Connect again with a clean session (False while the broker is down); then `on_connect(self)` runs."""
        if not self._broker.running:
            return False
        self._broker._attach(self)
        if self.on_connect is not None:
            self.on_connect(self)
        return True


class MockBroker:
    def __init__(self, scheduler, seed: int = 0):
        self.scheduler = scheduler
        self._rng = random.Random(seed)
        self._clients = {}
        self._retained = {}
        self.running = True
        self.last_error = ""
        self.stats = {"published": 0, "delivered": 0, "dropped_loss": 0, "dropped_down": 0, "retained": 0,
                      "callback_errors": 0}

    # --- connections ---------------------------------------------------------------------------------------------

    def connect(self, client_id, will=None, up=None, down=None) -> MockClient:
        """A connected client. `will` = (topic, payload bytes, retain). An existing session with this id is taken over."""
        if will is not None:
            validate_topic(will[0])
        old = self._clients.get(client_id)
        if old is not None:
            old._connected = False
            old._subs.clear()
        client = MockClient(self, client_id, will, up, down)
        self._attach(client)
        return client

    def _attach(self, client):
        client._connected = True
        client._subs.clear()
        client._session += 1
        self._clients[client.client_id] = client

    def set_link(self, client_id, up=None, down=None):
        client = self._clients[client_id]
        if up is not None:
            client.up = up
        if down is not None:
            client.down = down

    def kill_client(self, client_id):
        """Abrupt loss of a client (power cut, Wi-Fi gone): its will is published, nothing more flows."""
        client = self._clients[client_id]
        if not client._connected:
            return
        client._connected = False
        client._subs.clear()
        if client.will is not None and self.running:
            topic, payload, retain = client.will
            self._route(topic, payload, retain)

    def stop(self):
        """The broker goes down: every client is cut off (no wills: there is no broker to send them)."""
        self.running = False
        for client in self._clients.values():
            client._connected = False
            client._subs.clear()

    def start(self):
        """The broker is back, with its retained store; clients must reconnect."""
        self.running = True

    # --- message flow ---------------------------------------------------------------------------------------------

    def _delay(self, link, last_s):
        t = self.scheduler.now_s() + link.latency_s + (self._rng.random() * link.jitter_s if link.jitter_s else 0.0)
        return max(t, last_s)  # QoS 0 over one TCP connection: never overtakes an earlier message

    def _from_client(self, client, topic, payload, retain):
        self.stats["published"] += 1
        if not client._connected or not self.running:
            self.stats["dropped_down"] += 1
            return
        if client.up.loss and self._rng.random() < client.up.loss:
            self.stats["dropped_loss"] += 1
            return
        client._last_up_s = self._delay(client.up, client._last_up_s)
        self.scheduler.call_at(client._last_up_s, self._arrive, client, client._session, topic, payload, retain)

    def _arrive(self, client, session, topic, payload, retain):
        if not self.running or session != client._session:
            self.stats["dropped_down"] += 1
            return
        self._route(topic, payload, retain)

    def _route(self, topic, payload, retain):
        if retain:
            if payload:
                self._retained[topic] = payload
            else:
                self._retained.pop(topic, None)
            self.stats["retained"] = len(self._retained)
        for client in list(self._clients.values()):
            if client._connected and any(topic_matches(f, topic) for f in client._subs):
                self._to_client(client, topic, payload)

    def _to_client(self, client, topic, payload):
        if client.down.loss and self._rng.random() < client.down.loss:
            self.stats["dropped_loss"] += 1
            return
        client._last_down_s = self._delay(client.down, client._last_down_s)
        self.scheduler.call_at(client._last_down_s, self._deliver, client, client._session, topic, payload)

    def _send_retained(self, client, topic_filter):
        for topic, payload in sorted(self._retained.items()):
            if topic_matches(topic_filter, topic):
                self._to_client(client, topic, payload)

    def _deliver(self, client, session, topic, payload):
        if not client._connected or session != client._session or not self.running:
            self.stats["dropped_down"] += 1
            return
        callbacks = []
        for topic_filter, callback in client._subs.items():
            if topic_matches(topic_filter, topic) and callback not in callbacks:
                callbacks.append(callback)
        if not callbacks:
            return
        self.stats["delivered"] += 1
        for callback in callbacks:
            try:
                callback(topic, payload)
            except Exception as exc:  # a subscriber's bug must not stop the broker
                self.stats["callback_errors"] += 1
                self.last_error = f"{client.client_id} on {topic}: {type(exc).__name__}: {exc}"
