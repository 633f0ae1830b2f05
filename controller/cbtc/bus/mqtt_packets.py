"""MQTT 3.1.1 packets as bytes: what `LeanBus` writes and reads. Pure: values in, bytes out, and a parser that takes
bytes as they come off a socket and gives whole packets back.

Only what a bus client of this project uses: CONNECT (clean session, last will, user name and password), PUBLISH at
QoS 0 and 1 (both ways) with PUBACK, SUBSCRIBE, UNSUBSCRIBE, PINGREQ, DISCONNECT; the broker's CONNACK, SUBACK,
UNSUBACK and PINGRESP are read. Spec: OASIS MQTT Version 3.1.1 (2014), section 2 (fixed header) and 3 (packets).
"""

import struct

CONNECT, CONNACK, PUBLISH, PUBACK = 0x10, 0x20, 0x30, 0x40
SUBSCRIBE, SUBACK, UNSUBSCRIBE, UNSUBACK = 0x82, 0x90, 0xA2, 0xB0
PINGREQ, PINGRESP, DISCONNECT = 0xC0, 0xD0, 0xE0
SUBACK_FAILURE = 0x80       # a SUBACK's return code for a filter the broker refused
MAX_REMAINING = 268_435_455   # the largest remaining length four bytes can state

CONNACK_REASONS = {1: "unacceptable protocol version", 2: "identifier rejected", 3: "server unavailable",
                   4: "bad user name or password", 5: "not authorised"}


class ProtocolError(Exception):
    """The broker sent bytes that are not MQTT 3.1.1: the connection is closed and opened again."""


def _remaining(n: int) -> bytes:
    if n > MAX_REMAINING:
        raise ValueError(f"MQTT packet of {n} bytes is larger than the protocol allows")
    out = bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        out.append(byte | 0x80 if n else byte)
        if not n:
            return bytes(out)


def _string(value) -> bytes:
    data = value.encode() if isinstance(value, str) else bytes(value)
    return struct.pack("!H", len(data)) + data


def connect(client_id: str, keepalive_s: int, will=None, username=None, password=None) -> bytes:
    """CONNECT with a clean session; `will` = (topic, payload, qos, retain) or None."""
    flags = 0x02
    payload = _string(client_id)
    if will is not None:
        topic, message, qos, retain = will
        flags |= 0x04 | (qos << 3) | (0x20 if retain else 0)
        payload += _string(topic) + _string(message)
    if username is not None:
        flags |= 0x80
        payload += _string(username)
        if password is not None:
            flags |= 0x40
            payload += _string(password)
    body = _string("MQTT") + bytes((4, flags)) + struct.pack("!H", keepalive_s) + payload
    return bytes((CONNECT,)) + _remaining(len(body)) + body


def publish(topic: str, payload: bytes, qos: int = 0, retain: bool = False, packet_id: int = 0) -> bytes:
    topic_b = topic.encode()
    head = PUBLISH | (qos << 1) | (1 if retain else 0)
    pid = struct.pack("!H", packet_id) if qos else b""
    length = 2 + len(topic_b) + len(pid) + len(payload)
    if length < 128:   # reports and commands: one length byte
        return bytes((head, length)) + struct.pack("!H", len(topic_b)) + topic_b + pid + payload
    return bytes((head,)) + _remaining(length) + struct.pack("!H", len(topic_b)) + topic_b + pid + payload


def puback(packet_id: int) -> bytes:
    return struct.pack("!BBH", PUBACK, 2, packet_id)


def subscribe(packet_id: int, filters) -> bytes:
    """SUBSCRIBE to (filter, qos) pairs."""
    body = struct.pack("!H", packet_id) + b"".join(_string(f) + bytes((qos,)) for f, qos in filters)
    return bytes((SUBSCRIBE,)) + _remaining(len(body)) + body


def unsubscribe(packet_id: int, filters) -> bytes:
    body = struct.pack("!H", packet_id) + b"".join(_string(f) for f in filters)
    return bytes((UNSUBSCRIBE,)) + _remaining(len(body)) + body


def pingreq() -> bytes:
    return bytes((PINGREQ, 0))


def disconnect() -> bytes:
    return bytes((DISCONNECT, 0))


def split(buffer: bytearray):
    """Take every whole packet off the front of `buffer` (bytes read so far); returns [(first byte, body bytes)]
    and leaves a partial packet in `buffer`. Raises ProtocolError on a length no MQTT packet has."""
    packets = []
    pos, end = 0, len(buffer)
    while end - pos >= 2:
        length, shift, k, whole = 0, 0, pos + 1, False
        while k < end:
            byte = buffer[k]
            k += 1
            length |= (byte & 0x7F) << shift
            if not byte & 0x80:
                whole = True
                break
            shift += 7
            if shift > 21:
                raise ProtocolError("remaining length longer than four bytes")
        if not whole or end - k < length:
            break   # the rest of this packet has not come yet
        packets.append((buffer[pos], bytes(buffer[k:k + length])))
        pos = k + length
    if pos:
        del buffer[:pos]
    return packets


def parse_publish(first: int, body: bytes):
    """(topic, payload, qos, packet id or 0, retain) of a PUBLISH."""
    qos = (first >> 1) & 0x03
    if qos > 1 or len(body) < 2:   # QoS 2 is never subscribed to, so never sent
        raise ProtocolError("malformed PUBLISH")
    n = (body[0] << 8) | body[1]
    k = 2 + n
    if k > len(body):
        raise ProtocolError("PUBLISH topic longer than its packet")
    try:
        topic = body[2:k].decode()
    except UnicodeDecodeError:
        raise ProtocolError("PUBLISH topic is not UTF-8") from None
    packet_id = 0
    if qos:
        if len(body) < k + 2:
            raise ProtocolError("PUBLISH without its packet identifier")
        packet_id = (body[k] << 8) | body[k + 1]
        k += 2
    return topic, body[k:], qos, packet_id, bool(first & 0x01)
