"""An in-process MQTT broker on a virtual clock: deterministic, fast, and made for fault injection.

MQTT semantics where they matter to the testbed: '+'/'#' filters, retained messages (an empty payload deletes),
last will on abrupt loss (killed client, keep-alive expired; not on a clean disconnect, not on a session takeover),
clean sessions (subscriptions are lost on reconnect, so the owner resubscribes in `on_connect`), QoS 0 delivery in
order per connection (unless a link is set to reorder or duplicate, for fault injection). Each client has an `up`
link (client -> broker) and a `down` link (broker -> client) with latency, jitter and loss drawn from the broker's
seeded RNG, so the same seed and the same calls give the same deliveries at the same virtual times. It is for
simulation; the integration tests use a real Mosquitto.
"""

import functools
import random
from dataclasses import dataclass

from cbtc.bus.client import topic_matches, validate_filter, validate_topic
from cbtc.errors import BusError

# (filter, topic) -> match: a simulation uses a few dozen topics and filters, each matched at every message
_matches = functools.lru_cache(maxsize=8192)(topic_matches)

KEEPALIVE_GRACE = 1.5  # MQTT: the broker declares a client dead after 1.5 keep-alive periods of silence


@dataclass
class LinkProfile:
    """One direction of a client's link."""

    latency_s: float = 0.002
    jitter_s: float = 0.0     # extra delay, uniform in [0, jitter_s]
    loss: float = 0.0         # probability a message is lost on this link
    reorder: float = 0.0      # probability a message is held back reorder_s, so that later ones overtake it
    reorder_s: float = 0.05
    duplicate: float = 0.0    # probability a message arrives twice (the copy one latency later)

    def __post_init__(self):
        shares = (self.loss, self.reorder, self.duplicate)
        if self.latency_s < 0 or self.jitter_s < 0 or self.reorder_s < 0 or not all(0.0 <= p <= 1.0 for p in shares):
            raise ValueError(f"link profile {self}: latency_s, jitter_s and reorder_s must be >= 0, loss, reorder "
                             "and duplicate in [0, 1]")


class _Subscriptions(dict):
    """A client's filter -> callback, telling the broker of every change: it keeps the clients of each topic, and
    this client's callbacks of each topic (`callbacks`)."""

    def __init__(self, broker):
        super().__init__()
        self._broker = broker
        self._callbacks = {}   # topic -> the callbacks of the filters matching it, each once, in subscription order

    def callbacks(self, topic):
        found = self._callbacks.get(topic)
        if found is None:
            if len(self._callbacks) >= 4096:   # a flood of topics: bounded all the same
                self._callbacks.clear()
            found = self._callbacks[topic] = tuple(
                dict.fromkeys(cb for f, cb in self.items() if _matches(f, topic)))
        return found

    def __setitem__(self, topic_filter, callback):
        super().__setitem__(topic_filter, callback)
        self._changed()

    def pop(self, *args):
        self._changed()
        return super().pop(*args)

    def clear(self):
        self._changed()
        super().clear()

    def _changed(self):
        self._broker._routes.clear()
        self._callbacks.clear()


class MockClient:
    """One connection to a `MockBroker`; made by `MockBroker.connect`, implements `cbtc.bus.client.BusClient` (a
    Protocol: an instance passes isinstance without the class deriving from it, which a C type could not)."""

    def __init__(self, broker, client_id, will, up, down, keepalive_s):
        self._broker = broker
        self.client_id = client_id
        self.will = will
        self.up = up or LinkProfile()
        self.down = down or LinkProfile()
        self.keepalive_s = keepalive_s
        self.on_connect = None        # callable(client), run after reconnect(): resubscribe there
        self._subs = _Subscriptions(broker)   # filter -> callback
        self._connected = False
        self._conn = 0                # bumped on every (re)connect: deliveries for an older connection are dropped
        self._cuts = 0                # bumped on every abrupt loss: messages still on the uplink are dropped
        self._last_up_s = 0.0
        self._last_down_s = 0.0
        self._deadline = None         # keep-alive expiry event on the broker side
        self._pinger = None           # keep-alive ping task on the client side

    @property
    def connected(self) -> bool:
        return self._connected

    def publish(self, topic, payload, retain=False, qos=0):
        """Send over the up link; dropped (and counted) while disconnected. `qos` is accepted and treated as 0."""
        validate_topic(topic)
        if not isinstance(payload, (bytes, bytearray)):
            raise TypeError(f"payload on {topic} must be bytes, got {type(payload).__name__}")
        broker = self._broker
        broker._from_client(self, topic, bytes(payload), retain)

    def subscribe(self, topic_filter, callback):
        """Subscribe (retained matches are sent at once); ignored while disconnected, as the session is lost anyway."""
        validate_filter(topic_filter)
        if not self._connected:
            return
        self._subs[topic_filter] = callback
        self._broker._send_retained(self, topic_filter)

    def unsubscribe(self, topic_filter):
        self._subs.pop(topic_filter, None)

    def disconnect(self):
        """Clean disconnect: the last will is discarded; messages already sent still reach the broker."""
        self._connected = False
        self._subs.clear()
        self._broker._cancel_deadline(self)

    def reconnect(self) -> bool:
        """Connect again with a clean session (False while the broker is down); then `on_connect(self)` runs."""
        if not self._broker.running:
            return False
        self._broker._attach(self)
        if self.on_connect is not None:
            self.on_connect(self)
        return True


class MockBroker:
    """The broker. `stats` counts published, delivered (per receiving client), dropped_loss, dropped_down,
    retained (topics held), callback_errors and keepalive_expired; `last_error` describes the last failing callback."""

    def __init__(self, scheduler, seed: int = 0):
        self.scheduler = scheduler
        self._rng = random.Random(seed)
        self._clients = {}
        self._routes = {}    # topic -> the clients subscribed to it, in connection order; cleared on any change
        self._retained = {}
        self.running = True
        self.last_error = ""
        self.stats = {"published": 0, "delivered": 0, "dropped_loss": 0, "dropped_down": 0, "retained": 0,
                      "callback_errors": 0, "keepalive_expired": 0}

    # --- connections ---------------------------------------------------------------------------------------------

    def connect(self, client_id, will=None, up=None, down=None, keepalive_s=None) -> MockClient:
        """A client, connected unless the broker is down. `will` = (topic, payload bytes, retain). An existing session
        with this id is taken over (closed without its will). With `keepalive_s` the client pings over its up link
        every `keepalive_s` and the broker declares it dead (publishing its will) after 1.5 * keepalive_s without
        hearing from it."""
        if will is not None:
            if not (isinstance(will, tuple) and len(will) == 3):
                raise ValueError(f"client {client_id!r}: will must be (topic, payload bytes, retain), got {will!r}")
            validate_topic(will[0])
            if not isinstance(will[1], (bytes, bytearray)):
                raise TypeError(f"client {client_id!r}: will payload on {will[0]} must be bytes")
        if keepalive_s is not None and keepalive_s <= 0:
            raise ValueError(f"client {client_id!r}: keepalive_s must be > 0 or None, got {keepalive_s}")
        client = MockClient(self, client_id, will, up, down, keepalive_s)
        if self.running:   # while the broker is down the client is made unconnected: reconnect() once it is up
            self._attach(client)
        return client

    def _attach(self, client):
        """(Re)connect `client` with a clean session, taking over an open session with the same id (no will)."""
        old = self._clients.get(client.client_id)
        if old is not None and old is not client and old._connected:
            self._cut(old)
        client._connected = True
        client._subs.clear()
        client._conn += 1
        self._clients[client.client_id] = client
        self._routes.clear()
        if client.keepalive_s is not None:
            self._heard(client, client._cuts)
            tick = functools.partial(self._ping, client, client._conn)
            client._pinger = self.scheduler.call_every(client.keepalive_s, tick,
                                                       start_s=self.scheduler.now_s() + client.keepalive_s)

    def _client(self, client_id):
        if client_id not in self._clients:
            raise BusError(f"no client {client_id!r} on the mock broker; known: {sorted(self._clients)}")
        return self._clients[client_id]

    def set_link(self, client_id, up=None, down=None):
        """Change a client's link profiles at run time (fault injection); None keeps a direction as it is."""
        client = self._client(client_id)
        if up is not None:
            client.up = up
        if down is not None:
            client.down = down

    def kill_client(self, client_id):
        """Abrupt loss of a client (power cut, Wi-Fi gone): its will is published, nothing more flows."""
        client = self._client(client_id)
        if client._connected:
            self._cut(client)
            self._publish_will(client)

    def _cut(self, client):
        client._connected = False
        client._subs.clear()
        client._cuts += 1
        self._cancel_deadline(client)

    def _publish_will(self, client):
        if client.will is not None and self.running:
            topic, payload, retain = client.will
            self._route(topic, bytes(payload), retain)

    def stop(self):
        """The broker goes down: every client is cut off (no wills: there is no broker to send them)."""
        self.running = False
        for client in self._clients.values():
            if client._connected:
                self._cut(client)

    def start(self):
        """The broker is back, with its retained store; clients must reconnect."""
        self.running = True

    # --- keep-alive -----------------------------------------------------------------------------------------------

    def _ping(self, client, conn, now_s):
        if conn != client._conn or not client._connected:
            client._pinger.cancel()
            return
        if client.up.loss and self._rng.random() < client.up.loss:
            return
        client._last_up_s = self._delay(client.up, client._last_up_s)
        self.scheduler.call_at(client._last_up_s, self._heard, client, client._cuts)

    def _heard(self, client, cuts):
        if client.keepalive_s is None or cuts != client._cuts or not self.running:
            return
        self._cancel_deadline(client)
        client._deadline = self.scheduler.call_later(KEEPALIVE_GRACE * client.keepalive_s, self._expire, client)

    def _expire(self, client):
        client._deadline = None
        if client._connected and self.running:
            self.stats["keepalive_expired"] += 1
            self._cut(client)
            self._publish_will(client)

    def _cancel_deadline(self, client):
        if client._deadline is not None:
            self.scheduler.cancel(client._deadline)
            client._deadline = None

    # --- message flow ---------------------------------------------------------------------------------------------

    def _delay(self, link, last_s):
        t = self.scheduler.now_s() + link.latency_s + (self._rng.random() * link.jitter_s if link.jitter_s else 0.0)
        return max(t, last_s)  # QoS 0 over one TCP connection: never overtakes an earlier message

    def _arrivals(self, link, last_s):
        """(arrival times of one message sent now over `link`, the link's new in-order time): in order after the
        message arriving at `last_s`; held back by `reorder_s` without holding later ones (they overtake it); twice."""
        t = self._delay(link, last_s)
        in_order_s = t
        if link.reorder and self._rng.random() < link.reorder:
            t, in_order_s = t + link.reorder_s, last_s
        if link.duplicate and self._rng.random() < link.duplicate:
            return (t, t + max(link.latency_s, 0.001)), in_order_s
        return (t,), in_order_s

    def _from_client(self, client, topic, payload, retain):
        self.stats["published"] += 1
        if not client._connected or not self.running:
            self.stats["dropped_down"] += 1
            return
        if client.up.loss and self._rng.random() < client.up.loss:
            self.stats["dropped_loss"] += 1
            return
        times, client._last_up_s = self._arrivals(client.up, client._last_up_s)
        for t_s in times:
            self.scheduler.call_at(t_s, self._arrive, client, client._cuts, topic, payload, retain)

    def _arrive(self, client, cuts, topic, payload, retain):
        if not self.running or cuts != client._cuts:
            self.stats["dropped_down"] += 1
            return
        self._heard(client, cuts)
        self._route(topic, payload, retain)

    def _route(self, topic, payload, retain):
        if retain:
            if payload:
                self._retained[topic] = payload
            else:
                self._retained.pop(topic, None)
            self.stats["retained"] = len(self._retained)
        clients = self._routes.get(topic)
        if clients is None:
            clients = self._routes[topic] = [client for client in self._clients.values()
                                             if any(_matches(f, topic) for f in client._subs)]
        for client in clients:
            if client._connected:
                self._to_client(client, topic, payload)

    def _to_client(self, client, topic, payload):
        if client.down.loss and self._rng.random() < client.down.loss:
            self.stats["dropped_loss"] += 1
            return
        times, client._last_down_s = self._arrivals(client.down, client._last_down_s)
        for t_s in times:
            self.scheduler.call_at(t_s, self._deliver, client, client._conn, topic, payload)

    def _send_retained(self, client, topic_filter):
        for topic, payload in sorted(self._retained.items()):
            if topic_matches(topic_filter, topic):
                self._to_client(client, topic, payload)

    def _deliver(self, client, conn, topic, payload):
        if not client._connected or conn != client._conn or not self.running:
            self.stats["dropped_down"] += 1
            return
        callbacks = client._subs.callbacks(topic)
        if not callbacks:
            return
        self.stats["delivered"] += 1
        for callback in callbacks:
            try:
                callback(topic, payload)
            except Exception as exc:  # a subscriber's bug must not stop the broker
                self.stats["callback_errors"] += 1
                self.last_error = f"{client.client_id} on {topic}: {type(exc).__name__}: {exc}"
