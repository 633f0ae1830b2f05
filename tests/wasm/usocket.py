"""An in-memory MQTT broker peer standing in for `usocket` when the firmware runs in the WebAssembly port (which has
no sockets), for the 32-bit heap measurement (tests/test_heap32.py).

It answers the board's CONNECT (CONNACK), SUBSCRIBE (SUBACK), QoS 1 PUBLISH (PUBACK) and PINGREQ (PINGRESP); for a
report with sequence number N it queues the command prepared for it in the file `<CMD_DIR>/<N>` (a whole MQTT
PUBLISH packet, written by the test with the zone controller's own encoder), if there is one. Counters: REPORTS,
COMMANDS. Kept small, since it costs heap that a board's socket (C code) does not.
"""

CMD_DIR = "/cmds"
REPORTS = [0]
COMMANDS = [0]
_in = bytearray()    # board -> broker, not yet parsed
_out = bytearray()   # broker -> board


def getaddrinfo(host, port, *args):
    return [(0, 0, 0, "", (host, port))]


def _packet():
    """Take one whole packet off _in: (first byte, body) or None."""
    n = shift = 0
    i = 1
    while i < len(_in):
        b = _in[i]
        n |= (b & 0x7F) << shift
        shift += 7
        i += 1
        if not b & 0x80:
            if len(_in) < i + n:
                return None
            kind, body = _in[0], bytes(_in[i:i + n])
            _in[:] = _in[i + n:]
            return kind, body
    return None


class socket:
    def connect(self, addr):
        pass

    def setsockopt(self, *args):
        pass

    def setblocking(self, flag):
        pass

    def settimeout(self, t):
        pass

    def close(self):
        pass

    def write(self, buf, n=None):
        _in.extend(buf if n is None else buf[:n])
        while True:
            packet = _packet()
            if packet is None:
                break
            kind, body = packet
            if kind == 0x10:
                _out.extend(b"\x20\x02\x00\x00")
            elif kind == 0x82:
                _out.extend(b"\x90\x03" + body[:2] + b"\x00")
            elif kind == 0xC0:
                _out.extend(b"\xd0\x00")
            elif kind & 0xF0 == 0x30:
                cut = 2 + (body[0] << 8 | body[1])
                if kind & 6:
                    _out.extend(b"\x40\x02" + body[cut:cut + 2])
                if body[cut - 7:cut] == b"/report":
                    REPORTS[0] += 1
                    at = body.find(b'"seq":') + 6
                    end = at
                    while 47 < body[end] < 58:
                        end += 1
                    try:
                        with open("%s/%d" % (CMD_DIR, int(body[at:end])), "rb") as fh:
                            _out.extend(fh.read())
                        COMMANDS[0] += 1
                    except OSError:
                        pass
        return len(buf) if n is None else n

    def read(self, n):
        if not _out:
            return None
        data = bytes(_out[:n])
        _out[:] = _out[n:]
        return data

    def readinto(self, buf, n):
        if not _out:
            return None
        n = min(n, len(buf), len(_out))
        buf[:n] = _out[:n]
        _out[:] = _out[n:]
        return n
