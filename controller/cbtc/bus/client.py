"""The bus interface the controller and the trains talk to, and the MQTT rules shared by its implementations: topics
and filters, the QoS of each topic, the retained status words, the broker URL.

Implementations: `cbtc.bus.mock_broker` (in-process, virtual clock, fault injection), and on a real broker
`cbtc.bus.lean_bus` (this project's MQTT client) and `cbtc.bus.paho_bus` (paho-mqtt). A client object has:

    client_id: str
    connected: bool
    on_connect: callable(client) or None     called after every (re)connect: resubscribe there
    publish(topic, payload: bytes, retain=False, qos=0)
    subscribe(topic_filter, callback)        callback(topic: str, payload: bytes)
    unsubscribe(topic_filter)
    disconnect()                             clean: no last will

`BusClient` states this as a Protocol, so `isinstance(client, BusClient)` checks an implementation.
"""

import urllib.parse
from typing import Callable, Optional, Protocol, runtime_checkable

from cbtc.errors import ConfigError

MAX_TOPIC_BYTES = 65535
ONLINE = b"online"
OFFLINE = b"offline"
DEFAULT_PORT = 1883


def topic_qos(topic: str) -> int:
    """The QoS a topic is published and subscribed with: 1 for the retained `.../status` and `.../info`, 0 for
    reports and commands."""
    return 1 if topic.endswith(("/status", "/info")) else 0


def parse_broker_url(url: str):
    """`mqtt://[user:password@]host[:port]` -> (host, port, username or None, password or None)."""
    parts = urllib.parse.urlsplit(url if "://" in url else "mqtt://" + url)
    if parts.scheme != "mqtt":
        raise ConfigError(f"broker URL {url!r}: scheme {parts.scheme!r} is not supported; use mqtt://HOST:PORT")
    try:
        port = parts.port or DEFAULT_PORT
    except ValueError:
        raise ConfigError(f"broker URL {url!r}: the port must be a number in 1-65535") from None
    if not parts.hostname:
        raise ConfigError(f"broker URL {url!r} names no host; use mqtt://HOST:PORT, e.g. mqtt://127.0.0.1:1883")
    user = urllib.parse.unquote(parts.username) if parts.username else None
    password = urllib.parse.unquote(parts.password) if parts.password else None
    return parts.hostname, port, user, password


def checked_payload(topic: str, payload) -> bytes:
    """`payload` as bytes to publish on `topic` (checked: no wildcards, bytes); ValueError or TypeError naming it."""
    validate_topic(topic)
    if not isinstance(payload, (bytes, bytearray)):
        raise TypeError(f"payload on {topic} must be bytes, got {type(payload).__name__}")
    return bytes(payload)


@runtime_checkable
class BusClient(Protocol):
    """What the zone controller and the trains need from a bus connection."""

    client_id: str
    on_connect: Optional[Callable]

    @property
    def connected(self) -> bool:
        """True while the connection to the broker is up."""

    def publish(self, topic: str, payload: bytes, retain: bool = False, qos: int = 0) -> None:
        """Send `payload` on `topic` (no wildcards); a retained empty payload deletes the retained message."""

    def subscribe(self, topic_filter: str, callback: Callable[[str, bytes], None]) -> None:
        """Call `callback(topic, payload)` for each message matching `topic_filter` (until the connection is lost)."""

    def unsubscribe(self, topic_filter: str) -> None:
        """Stop the callbacks of `topic_filter`."""

    def disconnect(self) -> None:
        """Clean disconnect: the last will is not published."""


def validate_topic(topic: str) -> str:
    """A topic to publish on: non-empty, no wildcards, no NUL, at most 65535 bytes UTF-8."""
    if not isinstance(topic, str) or not topic:
        raise ValueError(f"topic {topic!r} must be a non-empty string")
    if "+" in topic or "#" in topic:
        raise ValueError(f"topic {topic!r}: wildcards '+' and '#' are for subscriptions, not for publishing")
    _common(topic, "topic")
    return topic


def validate_filter(topic_filter: str) -> str:
    """A subscription filter: '+' must be a whole level, '#' a whole last level."""
    if not isinstance(topic_filter, str) or not topic_filter:
        raise ValueError(f"filter {topic_filter!r} must be a non-empty string")
    _common(topic_filter, "filter")
    levels = topic_filter.split("/")
    for i, level in enumerate(levels):
        if "#" in level and (level != "#" or i != len(levels) - 1):
            raise ValueError(f"filter {topic_filter!r}: '#' must be a whole level and the last one")
        if "+" in level and level != "+":
            raise ValueError(f"filter {topic_filter!r}: '+' must be a whole level, like 'a/+/c'")
    return topic_filter


def _common(text, what):
    if "\x00" in text:
        raise ValueError(f"{what} {text!r} contains a NUL character")
    if len(text.encode("utf-8")) > MAX_TOPIC_BYTES:
        raise ValueError(f"{what} {text[:40]!r}... is longer than {MAX_TOPIC_BYTES} bytes UTF-8: shorten it")


def topic_matches(topic_filter: str, topic: str) -> bool:
    """MQTT 3.1.1 matching: '+' one level, '#' any number of trailing levels including none ('a/#' matches 'a');
    topics beginning with '$' are not matched by a wildcard in the first level."""
    if topic.startswith("$") and topic_filter[:1] in ("+", "#"):
        return False
    f_levels = topic_filter.split("/")
    t_levels = topic.split("/")
    for i, level in enumerate(f_levels):
        if level == "#":
            return True
        if i >= len(t_levels):
            return False
        if level != "+" and level != t_levels[i]:
            return False
    return len(f_levels) == len(t_levels)
