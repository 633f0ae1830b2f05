"""The wire protocol between train boards and the zone controller: one definition for both sides.

MicroPython-compatible (runs on the ESP8266 and under CPython). Messages are compact JSON objects; each payload is
`<json body>#<mac>` where mac is the first 16 bytes of HMAC-SHA256(key, topic + "\\n" + body), hex-encoded. The MAC is
checked over the bytes exactly as received, so key order and number formatting never matter. See docs/protocol.md.

This module is what a board needs. The zone controller's half (report decoding, command encoding, zone topics, the
mode and fault names) is wire_zc.py, and every message's fields are declared in messages.py: a board loads neither.

Topics (train id `T`, zone `Z`):
  cbtc/train/T/report   board -> controller, 20 Hz, QoS 0
  cbtc/train/T/cmd      controller -> board, one per report, QoS 0
  cbtc/train/T/status   board's retained "online"/"offline" (last will)
  cbtc/zc/Z/status      controller's retained "online"/"offline" (last will)
"""

import binascii
import hashlib
import json

try:
    from micropython import const
except ImportError:  # CPython
    def const(value):
        return value

VERSION = const(2)
ODO_MM_PER_M_MIN = const(500)    # the encoder scales a command may state (odometer mm per true m): no wheel is
ODO_MM_PER_M_MAX = const(2000)   # off by a factor of two
MAX_TAGS = const(4)
INT31 = const(2147483647)     # largest session id or odometer value
WRAP_MASK = const(0x3FFFFFFF) # times (ms) and sequence numbers on the wire count modulo 2^30 (12.4 days of ms)
_HALF = const(0x20000000)
BOOT_MAX = const(1073741823)  # boot ids are 1..2^30-1: a small int on the board
_MAC_BYTES = const(16)        # MAC length on the wire: the first 16 bytes of the HMAC, as 32 hex digits
MAX_PAYLOAD = const(1024)     # longest payload accepted (bytes); the board's link drops longer messages unread
_ID_MAX_LEN = const(16)       # longest train id (characters)


try:
    from hmac import compare_digest  # CPython: the constant-time comparison, in C
except ImportError:   # MicroPython has no hmac module: decode_sealed compares the MACs itself
    compare_digest = None

try:
    dumps_compact = json.JSONEncoder(separators=(",", ":")).encode   # CPython: one encoder, not one per message
except AttributeError:   # MicroPython's json
    def dumps_compact(msg):
        return json.dumps(msg, separators=(",", ":"))


class WireError(ValueError):
    """A message that must be ignored; `reason` says why in words a log reader can act on."""

    def __init__(self, reason):
        super().__init__(reason)
        self.reason = reason


class AuthError(WireError):
    """A message whose seal does not match: sealed with another key (the board's and the zone's differ), or altered."""


def topic_report(train_id):
    return "cbtc/train/%s/report" % train_id


def topic_command(train_id):
    return "cbtc/train/%s/cmd" % train_id


def topic_status(train_id):
    return "cbtc/train/%s/status" % train_id


def train_id_of(topic):
    """The train id in `cbtc/train/<id>/...`, or raise WireError."""
    parts = topic.split("/")
    if len(parts) != 4 or parts[0] != "cbtc" or parts[1] != "train":
        raise WireError("topic %r is not cbtc/train/<id>/<kind>" % topic)
    return check_train_id(parts[2])


def check_train_id(train_id):
    """`train_id` itself if it is 1-16 of A-Z a-z 0-9 _ -, else WireError naming the problem."""
    if not isinstance(train_id, str) or not 1 <= len(train_id) <= _ID_MAX_LEN:
        raise WireError("train id %r must be a string of 1-%d characters" % (train_id, _ID_MAX_LEN))
    for ch in train_id:
        if ch not in "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-":
            raise WireError("train id %r has %r: use letters, digits, '_' or '-'" % (train_id, ch))
    return train_id


# --- counters that wrap ---------------------------------------------------------------------------------------

def wrap_diff(a, b):
    """a - b for two counters modulo 2^30 (board times in ms, sequence numbers), in [-2^29, 2^29): how far a is
    after b, also across the wrap. Small ints throughout, as MicroPython's ticks_diff."""
    d = a - b
    if d >= _HALF:
        return d - _HALF - _HALF
    if d < -_HALF:
        return d + _HALF + _HALF
    return d


def wrap_add(a, b):
    """a + b modulo 2^30 for a counter a in [0, 2^30) and a step b in [0, 2^30)."""
    if a > WRAP_MASK - b:
        return a - _HALF - _HALF + b
    return a + b


# --- authentication -------------------------------------------------------------------------------------------

try:
    from hmac import digest as _C_HMAC  # CPython: C's; no board has it
except ImportError:
    _C_HMAC = None

_PADS = {}   # key -> its two padded blocks (inner, outer): made once per key, a train's key never changes


def hmac_sha256(key, *parts):
    """HMAC-SHA256 (RFC 2104) with `key` (bytes) of the concatenated `parts` (bytes): `_C_HMAC` where there is one
    (CPython's hmac.digest, or the controller's from cbtc.protocol), else hmac_sha256_hashlib."""
    if _C_HMAC is not None:
        return _C_HMAC(key, b"".join(parts), "sha256")
    return hmac_sha256_hashlib(key, *parts)


def hmac_sha256_hashlib(key, *parts):
    """HMAC-SHA256 from hashlib alone: MicroPython has no hmac module. The key's padded blocks are computed once per
    key, so a message costs two SHA-256 runs."""
    pads = _PADS.get(key)
    if pads is None:
        block = hashlib.sha256(key).digest() if len(key) > 64 else key
        pads = bytearray(128)   # the key padded to the 64-byte block, XORed with ipad, then again with opad
        pads[:len(block)] = block
        pads[64:64 + len(block)] = block
        for i in range(64):
            pads[i] ^= 0x36
            pads[64 + i] ^= 0x5C
        if len(_PADS) >= 1024:   # a board has one key; whoever has no C HMAC and many keys, bounded all the same
            _PADS.clear()
        _PADS[key] = pads = (bytes(pads[:64]), bytes(pads[64:]))
    inner = hashlib.sha256(pads[0])
    for part in parts:
        inner.update(part)
    outer = hashlib.sha256(pads[1])
    outer.update(inner.digest())
    return outer.digest()


def mac_hex(key, topic, body):
    """The MAC a payload of `body` (bytes) on `topic` carries after its '#': the first 16 bytes of
    HMAC-SHA256(key, topic + "\\n" + body), as 32 hex digits (bytes)."""
    return binascii.hexlify(memoryview(hmac_sha256(key, topic.encode(), b"\n", body))[:_MAC_BYTES])


def seal(key, topic, body):
    """Payload bytes for `body` (bytes) on `topic`, authenticated with `key` (bytes)."""
    return b"#".join((body, mac_hex(key, topic, body)))   # one new object: a + b + c makes two


# --- validation -----------------------------------------------------------------------------------------------

def check_ints(values, specs, topic, field=None):
    """Check integers against `specs`, flat (name, lo, hi) triples: the message's named fields (`field` None), or
    the elements of the list in message field `field`, in order."""
    get = values.get if field is None else None   # a message's dict: its lookup found once, not at every field
    for i in range(0, len(specs), 3):
        name = specs[i]
        value = get(name) if field is None else values[i // 3]
        if type(value) is not int or not specs[i + 1] <= value <= specs[i + 2]:   # a bool is not an integer here
            raise WireError("field %r on %s must be an integer in [%d, %d], got %r"   # a list item: ('ips', 'x_mm')
                            % (name if field is None else (field, name), topic, specs[i + 1], specs[i + 2], value))


def decode_sealed(key, topic, payload, kind, specs, mac=mac_hex, loads=json.loads):
    """The validated message dict of a sealed payload of `kind` ("rep" or "cmd") on `topic`: authenticated with
    `key` (`mac` gives the MAC it must carry: mac_hex, or the controller's faster one of the same bytes), a JSON
    object (read by `loads`) with header v, k, id and the integer fields of `specs` (see check_ints); WireError
    naming the problem otherwise."""
    train_id = train_id_of(topic)
    if not isinstance(payload, (bytes, bytearray)):
        raise WireError("payload on %s is %s, not bytes" % (topic, type(payload).__name__))
    if len(payload) > MAX_PAYLOAD:
        raise WireError("payload on %s is %d bytes, over the %d-byte limit" % (topic, len(payload), MAX_PAYLOAD))
    payload = bytes(payload)
    cut = payload.rfind(b"#")
    if cut < 0:
        raise WireError("payload on %s has no '#<mac>' authentication suffix" % topic)
    # a board (no compare_digest) reads the body in place: its hashlib and json take a memoryview, CPython's json not
    body = payload[:cut] if compare_digest is not None else memoryview(payload)[:cut]
    want = mac(key, topic, body)
    if compare_digest is not None:
        diff = not compare_digest(want, payload[cut + 1:])
    else:   # in time that depends on the lengths only, and with no copy of the payload's MAC
        cut += 1
        diff = len(want) ^ (len(payload) - cut)
        if not diff:
            for i in range(len(want)):
                diff |= want[i] ^ payload[cut + i]
    if diff:
        raise AuthError("payload on %s fails authentication (wrong key, or altered in transit)" % topic)
    try:
        msg = loads(body)
    except ValueError:
        raise WireError("payload on %s is not JSON" % topic)
    if not isinstance(msg, dict):
        raise WireError("payload on %s is not a JSON object" % topic)
    for field, word, want in (("v", "version", VERSION), ("k", "kind", kind), ("id", "train", train_id)):
        got = msg.get(field)
        if type(got) is not type(want) or got != want:   # a bool or a float is not the version
            raise WireError("message on %s names %s %r; this side expects %r" % (topic, word, got, want))
    check_ints(msg, specs, topic)
    return msg


def check_fields(msg, names, topic, more=()):
    """WireError naming the first field of `msg` that is neither a header field nor in `names` (check_ints specs) or
    `more`: a message carries exactly the documented fields. Called once the header and every field of `names` are
    found (decode_sealed), so counting the keys settles it; the names are looked at only when one is unknown."""
    known = 3 + len(names) // 3
    for name in more:
        if name in msg:
            known += 1
    if len(msg) == known:
        return
    for name in msg:
        if name not in names and name not in more and name not in ("v", "k", "id"):
            raise WireError("message on %s has the unknown field %r (see docs/protocol.md)" % (topic, name))


# --- reports ---------------------------------------------------------------------------------------------------

def encode_report(key, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid, ips, tags, faults,
                  rng=None, way=1):
    """Sealed report payload.

    boot: this boot's id (new_boot_id); t_ms: board uptime (ms) when sampled; odo_mm: encoder odometer (mm);
    v_mmps: encoder speed (mm/s); duty_pct: motor duty (%); mode: one of MODES (wire_zc.py); cseq: seq of the last
    accepted command (-1 if none); csid: the session id of that command (-1 if none: it tells the controller this
    report was made after its command arrived); ips: None or [t_ms, x_mm, y_mm] (newest fix since the last report,
    stamped on the board's clock); tags: list of [uid_hex, odo_mm, t_ms, span_ms] read since the last report
    (span_ms: the time since the reader's previous poll that answered, in which the reader entered the tag's field;
    a balise's telegram appended); faults: list of names from FAULTS (wire_zc.py); rng: None or [t_ms, gap_mm], the
    newest gap to the train ahead measured by the onboard ranging since the last report (board clock; gap from this
    head to the leader's tail, mm); way: -1 while the board drives backwards (the report's `dir` 1).
    """
    msg = {"v": VERSION, "k": "rep", "id": train_id, "boot": boot, "seq": seq, "t_ms": t_ms, "odo_mm": odo_mm,
           "v_mmps": v_mmps, "duty": duty_pct, "mode": mode, "cseq": cseq, "csid": csid, "ips": ips, "tags": tags,
           "flt": faults}
    if rng is not None:
        msg["rng"] = rng   # absent (read as null) on boards without ranging
    if way < 0:
        msg["dir"] = 1     # absent while it drives forward
    return seal(key, topic_report(train_id), dumps_compact(msg).encode())


# --- commands --------------------------------------------------------------------------------------------------
# a command's fields, all integers, all required: (name, lowest, highest) flat. The board's copy of messages.COMMAND,
# written out because the table's text would cost the board's heap; tests/test_messages.py holds the two equal
COMMAND_INTS = ("boot", 1, BOOT_MAX, "seq", 0, WRAP_MASK, "sid", 0, INT31, "rseq", 0, WRAP_MASK, "v_mmps", 0, 5000,
                "eoa_mm", -INT31, INT31,
                "ttl_ms", 1, 10000, "acc", 1, 10000, "dec", 1, 10000, "stop_mm", -INT31, INT31, "rpt_ms", 0, 10000,
                "odo_mm_per_m", ODO_MM_PER_M_MIN, ODO_MM_PER_M_MAX, "dir", 0, 1)


def decode_command(key, topic, payload, specs=COMMAND_INTS, mac=mac_hex, loads=json.loads):
    """The command dict of a sealed payload, validated against `specs` (see decode_sealed); WireError with the
    reason otherwise."""
    msg = decode_sealed(key, topic, payload, "cmd", specs, mac, loads)
    check_fields(msg, specs, topic)
    return msg
