"""The board's MQTT link reads and writes the socket in bounded steps (firmware/link.py), here over a scripted socket:
packets split anywhere, oversized and retained messages, a refused subscription, a flood, short writes."""

import pytest

from cbtc.firmware import link as link_module
from cbtc.protocol import wire

TOPIC = wire.topic_command("A")


class FakeSocket:
    """Hands out `chunks` one read at a time (None: nothing waiting now); records writes; `room` bytes per write."""

    def __init__(self, chunks=(), room=None):
        self.chunks = list(chunks)
        self.pending = b""
        self.written = []
        self.room = room
        self.timeout = "blocking"
        self.closed = False

    def setsockopt(self, *args):
        pass

    def setblocking(self, flag):
        self.timeout = "blocking" if flag else 0

    def settimeout(self, t):
        self.timeout = t

    def _take(self, n):
        if not self.pending:
            if not self.chunks:
                return None
            chunk = self.chunks.pop(0)
            if chunk is None:
                return None
            self.pending = chunk
        data, self.pending = self.pending[:n], self.pending[n:]
        return data

    def read(self, n):
        return self._take(n)

    def readinto(self, buf, n):
        data = self._take(min(n, len(buf)))
        if data is None:
            return None
        buf[:len(data)] = data
        return len(data)

    def write(self, data):
        n = len(data) if self.room is None else min(self.room, len(data))
        self.written.append(bytes(data[:n]))
        return n

    def close(self):
        self.closed = True


class FakeClient:
    def __init__(self, sock):
        self.sock = sock
        self.published = []

    def set_last_will(self, *args):
        pass

    def connect(self):
        pass

    def publish(self, topic, msg, retain=False, qos=0):
        self.published.append((topic, msg, retain, qos))


def publish_packet(topic, payload, retain=False):
    topic = topic.encode()
    body = len(topic).to_bytes(2, "big") + topic + payload
    n, length = len(body), b""
    while True:
        byte, n = n & 0x7F, n >> 7
        length += bytes([byte | (0x80 if n else 0)])
        if not n:
            break
    return bytes([0x30 | retain]) + length + body


def make_link(chunks, room=None):
    sock = FakeSocket(chunks, room)
    net = link_module.Link(FakeClient(sock), wire.topic_status("A"), (TOPIC,))
    got = []
    net.on_message = lambda topic, payload, now_ms: got.append((topic, payload, now_ms))
    assert net.connect(0)
    sock.chunks = list(chunks)
    return net, sock, got


def test_connect_subscribes_without_waiting_and_a_refused_subscription_loses_the_link():
    net, sock, _ = make_link([])
    assert sock.written[-1] == bytes((0x82, 5 + len(TOPIC), 0, 1, 0, len(TOPIC))) + TOPIC.encode() + b"\0"
    net, sock, _ = make_link([b"\x90\x03\x00\x01\x80"])
    net.poll(5)
    assert not net.connected and "subscription refused" in net.last_error and net.losses == 1


def test_messages_split_anywhere_arrive_whole_and_in_order():
    stream = publish_packet(TOPIC, b"one") + b"\x90\x03\x00\x01\x00" + publish_packet(TOPIC, b"two" * 100)
    chunks = [stream[i:i + 1] for i in range(0, 9)] + [None] + [stream[9:40], None, stream[40:]]
    net, sock, got = make_link(chunks)
    for now_ms in range(10, 200, 10):
        net.poll(now_ms)
    assert [(t, p) for t, p, _ in got] == [(TOPIC, b"one"), (TOPIC, b"two" * 100)]
    assert net.connected and sock.timeout == 0   # read without blocking


def test_oversized_messages_are_dropped_in_bounded_pieces_and_the_next_one_is_taken():
    big = publish_packet(TOPIC, b"x" * 65536)
    stream = big + publish_packet(TOPIC, b"after")
    net, sock, got = make_link([stream])
    polls = 0
    while not got:
        net.poll(polls)
        polls += 1
        assert polls < 100
    assert got[0][:2] == (TOPIC, b"after") and net.oversized == 1 and net.connected
    assert polls >= len(big) // link_module._MAX_READ   # at most _MAX_READ bytes a poll: the loop goes on between


def test_retained_messages_are_dropped_and_a_flood_is_taken_a_few_at_a_time():
    stream = publish_packet(TOPIC, b"stored", retain=True) + publish_packet(TOPIC, b"m") * 10
    net, sock, got = make_link([stream])
    net.poll(1)
    assert net.retained == 1 and len(got) == link_module._MAX_MESSAGES
    for now_ms in range(2, 6):
        net.poll(now_ms)
    assert len(got) == 10


@pytest.mark.parametrize("chunks, reason", [
    ([b""], "closed by the broker"),
    ([b"\x30\xff\xff\xff\xff"], "malformed packet length"),
    ([b"\x30\x05\x00\x09abc"], "malformed PUBLISH"),
])
def test_a_broken_stream_loses_the_link_and_never_raises(chunks, reason):
    net, sock, got = make_link(chunks)
    net.poll(7)
    assert not net.connected and reason in net.last_error and sock.closed and not got
    assert not net.due(7) and net.due(7 + 500)   # retried after the backoff


def test_a_publish_is_one_write_with_a_timeout_and_a_short_write_loses_the_link():
    net, sock, _ = make_link([])
    assert net.publish(wire.topic_report("A"), b"r" * 300)
    assert sock.written[-1] == publish_packet(wire.topic_report("A"), b"r" * 300)
    assert sock.timeout == 0.01
    sock.room = 100
    assert not net.publish(wire.topic_report("A"), b"r" * 300)
    assert not net.connected and "short write" in net.last_error


def test_an_exception_in_the_message_handler_stays_with_that_message():
    net, sock, got = make_link([publish_packet(TOPIC, b"bad") + publish_packet(TOPIC, b"good")])

    def handler(topic, payload, now_ms):
        if payload == b"bad":
            raise MemoryError("decoding")
        got.append(payload)

    net.on_message = handler
    net.poll(3)
    assert got == [b"good"] and net.connected and "MemoryError" in net.last_error and net.failed == 1
