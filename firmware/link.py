"""The board's MQTT link: connect, last will, TCP_NODELAY, subscribe, bounded reading and writing, reconnect.

umqtt.simple (built into the board's firmware) opens the connection: CONNECT with the last will and the user, and the
retained `online` status. Past that this module reads and writes the socket itself, because umqtt.simple reads a
whole message into the heap and blocks until it has it: here a poll never waits, takes at most _MAX_READ bytes and
_MAX_MESSAGES messages, keeps a PUBLISH only up to the protocol's size (a longer one is read in _CHUNK pieces and
dropped) and drops retained messages (a stored command is never news). A publish is one write that waits at most
`send_timeout_ms`; a short write loses the link (the stream's framing is gone). Every exception ends here: the link is
marked lost and retried with backoff. Only `connect` may block (it opens a socket): the loop calls it only while the
train is held braked.
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
_MAX_READ = const(4096)   # bytes read per poll at most
_CHUNK = const(256)       # piece size in which an oversized message is read and dropped (bytes)
_MAX_BODY = const(1088)   # longest PUBLISH body kept: topic length, topic (< 48 bytes), wire.MAX_PAYLOAD
_PUBLISH = const(3)       # MQTT packet types (the high nibble of the first byte)
_SUBACK = const(9)


class Link:
    # state that starts like this on every link (class attributes: an instance pays for one only once it changes it)
    on_message = None   # callable(topic: str, payload: bytes, now_ms)
    connected = False
    losses = 0          # connections lost
    last_error = ""     # repr of the error that lost (or refused) the connection
    now_ms = 0          # board ms of the current poll, handed on to on_message
    oversized = 0       # messages dropped unread for their size
    retained = 0        # retained messages dropped
    failed = 0          # messages whose handler raised (a MemoryError, say)
    _next_try_ms = 0
    _head = 0           # first byte of the packet being read (0: none yet)
    _size = 0           # its remaining length, as decoded so far
    _shift = 0
    _left = -1          # body bytes still to read (-1: reading the fixed header)
    _got = 0
    _body = None        # the body being read, or None while an oversized one is dropped
    _sink = None        # _CHUNK bytes to read oversized messages into, made at the first one

    def __init__(self, client, status_topic, subscriptions, errors=(OSError,), backoff_ms=(500, 8000),
                 send_timeout_ms=10):
        """`client`: an umqtt.simple.MQTTClient; `subscriptions`: topics to (re)subscribe after every connect;
        `errors`: the exception classes that mean the connection is gone (any other is counted lost too, with its
        repr); `backoff_ms`: (first, longest) delay before a reconnect attempt (ms): it doubles after each failure
        and starts again at the first after a success; `send_timeout_ms`: longest wait for room to send (ms)."""
        self.client = client
        self.status_topic = status_topic
        self.subscriptions = subscriptions
        self.errors = errors
        self.backoff_ms = backoff_ms
        self._backoff_ms = backoff_ms[0]
        self._send_timeout_s = send_timeout_ms / 1000
        client.set_last_will(status_topic, b"offline", True, 1)   # retained

    def due(self, now_ms):
        """True when disconnected and the backoff since the last failure has passed (board ms)."""
        return not self.connected and wire.wrap_diff(now_ms, self._next_try_ms) >= 0

    def connect(self, now_ms):
        """One attempt: connect, TCP_NODELAY, `online` retained, subscribe. True on success."""
        self.now_ms = now_ms
        self._head = 0
        self._left = -1
        self._body = None
        try:
            self.client.connect()
            sock = self.client.sock
            sock.setsockopt(_IPPROTO_TCP, _TCP_NODELAY, 1)
            self.client.publish(self.status_topic, b"online", True, 1)   # no subscription yet: only its PUBACK comes
            pid = 0
            for topic in self.subscriptions:   # the SUBACK is checked when the poll reads it
                pid += 1
                topic = topic.encode()
                n = len(topic)
                sock.write(bytes((0x82, 5 + n, 0, pid, n >> 8, n & 0xFF)) + topic + b"\0")
        except Exception as exc:
            self._lost(now_ms, exc)
            return False
        self.connected = True
        self._backoff_ms = self.backoff_ms[0]
        return True

    def poll(self, now_ms):
        """Take waiting packets without blocking; each message goes to on_message with `now_ms`."""
        if not self.connected:
            return
        self.now_ms = now_ms
        try:
            sock = self.client.sock
            sock.setblocking(False)
            budget = _MAX_READ
            messages = 0
            while budget > 0 and messages < _MAX_MESSAGES:
                if self._left < 0:   # the fixed header: the packet's type byte, then 1-4 bytes of remaining length
                    b = sock.read(1)
                    if b is None:
                        break
                    if not b:
                        raise OSError("closed by the broker")
                    budget -= 1
                    b = b[0]
                    if not self._head:
                        self._head = b
                        self._size = self._shift = 0
                        continue
                    self._size |= (b & 0x7F) << self._shift
                    self._shift += 7
                    if b & 0x80:
                        if self._shift > 21:
                            raise OSError("malformed packet length")
                        continue
                    self._left = self._size
                    self._got = 0
                    if self._size <= _MAX_BODY:
                        self._body = bytearray(self._size)
                    else:
                        self.oversized += 1
                        if self._sink is None:
                            self._sink = bytearray(_CHUNK)
                if self._left > 0:
                    n = min(self._left, budget)
                    if self._body is None:
                        got = sock.readinto(self._sink, min(n, _CHUNK))
                    else:
                        got = sock.readinto(memoryview(self._body)[self._got:], n)
                    if got is None:
                        break
                    if not got:
                        raise OSError("closed by the broker")
                    self._got += got
                    self._left -= got
                    budget -= got
                    if self._left:
                        continue
                messages += self._packet()
                self._head = 0
                self._left = -1
                self._body = None
        except Exception as exc:
            self._lost(now_ms, exc)

    def _packet(self):
        """Act on the packet just read; 1 if it was a message handed on, else 0."""
        head = self._head
        body = self._body
        if head >> 4 == _SUBACK:
            if body is None or len(body) < 3 or body[-1] == 0x80:
                raise OSError("subscription refused")
            return 0
        if head >> 4 != _PUBLISH or body is None:   # PINGRESP, PUBACK; an oversized message, already counted
            return 0
        if head & 1:
            self.retained += 1
            return 0
        n = (body[0] << 8) | body[1]
        start = 2 + n + (2 if head & 6 else 0)   # the packet id of QoS 1 and 2 (we subscribe at QoS 0)
        if start > len(body):
            raise OSError("malformed PUBLISH")
        if self.on_message is not None:
            view = memoryview(body)
            topic = str(view[2:2 + n], "utf-8")
            payload = bytes(view[start:])
            view = body = self._body = None   # one copy of the message in the heap while it is decoded
            try:
                self.on_message(topic, payload, self.now_ms)
            except Exception as exc:   # the message's fault, not the link's: the stream is intact
                self.failed += 1
                self.last_error = "on_message: %r" % (exc,)
        return 1

    def publish(self, topic, payload):
        """Publish QoS 0 as one write; False (and the link marked lost) if the connection is gone or the write waits
        longer than the send timeout."""
        if not self.connected:
            return False
        try:
            sock = self.client.sock
            sock.settimeout(self._send_timeout_s)
            topic = topic.encode()
            n = 2 + len(topic) + len(payload)
            head = bytearray(7)
            head[0] = 0x30
            i = 1
            while n > 0x7F:
                head[i] = (n & 0x7F) | 0x80
                n >>= 7
                i += 1
            head[i] = n
            head[i + 1] = len(topic) >> 8
            head[i + 2] = len(topic) & 0xFF
            packet = head[:i + 3] + topic + payload
            if sock.write(packet) != len(packet):
                raise OSError("short write")
        except Exception as exc:
            self._lost(self.now_ms, exc)
            return False
        return True

    def _lost(self, now_ms, exc):
        if self.connected:
            self.losses += 1
        self.connected = False
        self.last_error = repr(exc)
        sock = self.client.sock
        if sock is not None:
            try:
                sock.close()
            except Exception:
                pass
        self._next_try_ms = wire.wrap_add(now_ms, self._backoff_ms)
        self._backoff_ms = min(self._backoff_ms * 2, self.backoff_ms[1])
