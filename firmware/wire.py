"""The wire protocol between train boards and the zone controller: one definition for both sides.

MicroPython-compatible (runs on the ESP8266 and under CPython). Messages are compact JSON objects; each payload is
`<json body>#<mac>` where mac is the first 16 bytes of HMAC-SHA256(key, topic + "\\n" + body), hex-encoded. The MAC is
checked over the bytes exactly as received, so key order and number formatting never matter. See docs/protocol.md.

Topics (train id `T`, zone `Z`):
  cbtc/train/T/report   board -> controller, 10 Hz, QoS 0
  cbtc/train/T/cmd      controller -> board, 10 Hz, QoS 0
  cbtc/train/T/status   board's retained "online"/"offline" (last will)
  cbtc/zc/Z/status      controller's retained "online"/"offline" (last will)
"""

import json

try:
    import hashlib
except ImportError:  # pragma: no cover - MicroPython ports without hashlib alias
    import uhashlib as hashlib

try:
    import binascii
except ImportError:  # pragma: no cover
    import ubinascii as binascii

VERSION = 1
MAC_BYTES = 16
MAX_PAYLOAD = 1024
MAX_TAGS = 4
ID_CHARS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-"
ID_MAX_LEN = 16
INT31 = 2147483647

KIND_REPORT = "rep"
KIND_COMMAND = "cmd"

MODES = ("idle", "run", "stop", "trip")
FAULTS = ("ips_silent", "ips_crc", "rfid_absent", "enc_stall", "cmd_timeout", "cmd_reject", "broker_lost",
          "guard")


class WireError(ValueError):
    """A message that must be ignored; `reason` says why in words a log reader can act on."""

    def __init__(self, reason):
        super().__init__(reason)
        self.reason = reason


def topic_report(train_id):
    return "cbtc/train/" + train_id + "/report"


def topic_command(train_id):
    return "cbtc/train/" + train_id + "/cmd"


def topic_status(train_id):
    return "cbtc/train/" + train_id + "/status"


def topic_zone_status(zone_id):
    return "cbtc/zc/" + zone_id + "/status"


REPORT_FILTER = "cbtc/train/+/report"


def train_id_of(topic):
    """The train id in `cbtc/train/<id>/...`, or raise WireError."""
    parts = topic.split("/")
    if len(parts) != 4 or parts[0] != "cbtc" or parts[1] != "train":
        raise WireError("topic %r is not cbtc/train/<id>/<kind>" % topic)
    check_train_id(parts[2])
    return parts[2]


def check_train_id(train_id):
    if not isinstance(train_id, str) or not (1 <= len(train_id) <= ID_MAX_LEN):
        raise WireError("train id %r must be a string of 1-%d characters" % (train_id, ID_MAX_LEN))
    for ch in train_id:
        if ch not in ID_CHARS:
            raise WireError("train id %r has %r: use letters, digits, '_' or '-'" % (train_id, ch))
    return train_id


# --- authentication -------------------------------------------------------------------------------------------

def hmac_sha256(key, msg):
    """HMAC-SHA256 (RFC 2104) from hashlib alone: MicroPython has no hmac module."""
    block = 64
    if len(key) > block:
        key = hashlib.sha256(key).digest()
    key = key + b"\x00" * (block - len(key))
    inner = hashlib.sha256(bytes(b ^ 0x36 for b in key))
    inner.update(msg)
    outer = hashlib.sha256(bytes(b ^ 0x5C for b in key))
    outer.update(inner.digest())
    return outer.digest()


def _mac_hex(key, topic, body):
    return binascii.hexlify(hmac_sha256(key, topic.encode() + b"\n" + body)[:MAC_BYTES])


def _same(a, b):
    """Constant-time comparison of two byte strings."""
    if len(a) != len(b):
        return False
    diff = 0
    for i in range(len(a)):
        diff |= a[i] ^ b[i]
    return diff == 0


def seal(key, topic, body):
    """Payload bytes for `body` (bytes) on `topic`, authenticated with `key` (bytes)."""
    return body + b"#" + _mac_hex(key, topic, body)


def open_sealed(key, topic, payload):
    """The body of an authenticated payload, or WireError if the payload is malformed or its MAC is wrong."""
    if not isinstance(payload, (bytes, bytearray)):
        raise WireError("payload on %s is %s, not bytes" % (topic, type(payload).__name__))
    if len(payload) > MAX_PAYLOAD:
        raise WireError("payload on %s is %d bytes, over the %d-byte limit" % (topic, len(payload), MAX_PAYLOAD))
    cut = bytes(payload).rfind(b"#")
    if cut < 0:
        raise WireError("payload on %s has no '#<mac>' authentication suffix" % topic)
    body = bytes(payload[:cut])
    if not _same(bytes(payload[cut + 1:]), _mac_hex(key, topic, body)):
        raise WireError("payload on %s fails authentication (wrong key, or altered in transit)" % topic)
    return body


# --- field validation -----------------------------------------------------------------------------------------

def _parse(body, topic):
    try:
        msg = json.loads(body)
    except ValueError:
        raise WireError("payload on %s is not JSON" % topic)
    if not isinstance(msg, dict):
        raise WireError("payload on %s is not a JSON object" % topic)
    return msg


def _int(msg, name, lo, hi, topic):
    value = msg.get(name)
    if not isinstance(value, int) or isinstance(value, bool):
        raise WireError("field %r on %s must be an integer, got %r" % (name, topic, value))
    if value < lo or value > hi:
        raise WireError("field %r on %s is %d, outside [%d, %d]" % (name, topic, value, lo, hi))
    return value


def _header(msg, kind, topic, train_id):
    version = msg.get("v")
    if version != VERSION:
        raise WireError("message on %s has version %r; this side speaks version %d" % (topic, version, VERSION))
    if msg.get("k") != kind:
        raise WireError("message on %s has kind %r, expected %r" % (topic, msg.get("k"), kind))
    if msg.get("id") != train_id:
        raise WireError("message on %s names train %r, but the topic names %r" % (topic, msg.get("id"), train_id))
    _int(msg, "seq", 0, INT31, topic)


def _dump(msg):
    return json.dumps(msg).replace(" ", "").encode()


# --- reports ---------------------------------------------------------------------------------------------------

def encode_report(key, train_id, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, ips, tags, faults, rng=None):
    """Sealed report payload.

    t_ms: board uptime (ms) when sampled; odo_mm: encoder odometer (mm); v_mmps: encoder speed (mm/s);
    duty_pct: motor duty (%); mode: one of MODES; cseq: seq of the last accepted command (-1 if none);
    ips: None or [t_ms, x_mm, y_mm] (newest fix since the last report, stamped on the board's clock);
    tags: list of [uid_hex, odo_mm, t_ms] read since the last report; faults: list of names from FAULTS;
    rng: None or [t_ms, gap_mm], the newest gap to the train ahead measured by the onboard ranging since the last
    report (board clock; gap from this head to the leader's tail, mm).
    """
    msg = {"v": VERSION, "k": KIND_REPORT, "id": train_id, "seq": seq, "t_ms": t_ms, "odo_mm": odo_mm,
           "v_mmps": v_mmps, "duty": duty_pct, "mode": mode, "cseq": cseq, "ips": ips, "tags": tags, "flt": faults}
    if rng is not None:
        msg["rng"] = rng   # absent (read as null) on boards without ranging
    return seal(key, topic_report(train_id), _dump(msg))


def decode_report(key, topic, payload):
    """The report dict of a sealed payload, validated; WireError with the reason otherwise."""
    train_id = train_id_of(topic)
    msg = _parse(open_sealed(key, topic, payload), topic)
    _header(msg, KIND_REPORT, topic, train_id)
    _int(msg, "t_ms", 0, INT31, topic)
    _int(msg, "odo_mm", -INT31, INT31, topic)
    _int(msg, "v_mmps", -20000, 20000, topic)
    _int(msg, "duty", -100, 100, topic)
    _int(msg, "cseq", -1, INT31, topic)
    if msg.get("mode") not in MODES:
        raise WireError("field 'mode' on %s is %r, not one of %s" % (topic, msg.get("mode"), ", ".join(MODES)))
    ips = msg.get("ips")
    if ips is not None:
        if not isinstance(ips, list) or len(ips) != 3:
            raise WireError("field 'ips' on %s must be null or [t_ms, x_mm, y_mm]" % topic)
        _int({"ips.t_ms": ips[0]}, "ips.t_ms", 0, INT31, topic)
        _int({"ips.x_mm": ips[1]}, "ips.x_mm", -1000000, 1000000, topic)
        _int({"ips.y_mm": ips[2]}, "ips.y_mm", -1000000, 1000000, topic)
    tags = msg.get("tags")
    if not isinstance(tags, list) or len(tags) > MAX_TAGS:
        raise WireError("field 'tags' on %s must be a list of at most %d [uid, odo_mm, t_ms]" % (topic, MAX_TAGS))
    for tag in tags:
        if (not isinstance(tag, list) or len(tag) != 3 or not isinstance(tag[0], str)
                or not isinstance(tag[1], int) or not isinstance(tag[2], int)):
            raise WireError("entry %r of 'tags' on %s must be [uid_hex, odo_mm, t_ms]" % (tag, topic))
    rng = msg.get("rng")
    if rng is not None:
        if not isinstance(rng, list) or len(rng) != 2:
            raise WireError("field 'rng' on %s must be null or [t_ms, gap_mm]" % topic)
        _int({"rng.t_ms": rng[0]}, "rng.t_ms", 0, INT31, topic)
        _int({"rng.gap_mm": rng[1]}, "rng.gap_mm", -100000, 1000000, topic)
    msg["rng"] = rng
    faults = msg.get("flt")
    if not isinstance(faults, list) or any(f not in FAULTS for f in faults):
        raise WireError("field 'flt' on %s must list fault names from %s" % (topic, ", ".join(FAULTS)))
    return msg


# --- commands --------------------------------------------------------------------------------------------------

def encode_command(key, train_id, seq, sid, rseq, v_mmps, eoa_mm, ttl_ms, acc_mmps2, dec_mmps2):
    """Sealed command payload.

    sid: the controller's session id (a new random int each start); seq: increasing within a session;
    rseq: the report this command is based on; v_mmps: speed ceiling (mm/s, >= 0); eoa_mm: end of authority as a
    value of the train's own odometer (mm) that its head must not pass; ttl_ms: validity, counted on the board's clock
    from the time of report rseq; acc_mmps2 / dec_mmps2: acceleration and service deceleration to use (mm/s^2).
    """
    msg = {"v": VERSION, "k": KIND_COMMAND, "id": train_id, "seq": seq, "sid": sid, "rseq": rseq,
           "v_mmps": v_mmps, "eoa_mm": eoa_mm, "ttl_ms": ttl_ms, "acc": acc_mmps2, "dec": dec_mmps2}
    return seal(key, topic_command(train_id), _dump(msg))


def decode_command(key, topic, payload):
    """The command dict of a sealed payload, validated; WireError with the reason otherwise."""
    train_id = train_id_of(topic)
    msg = _parse(open_sealed(key, topic, payload), topic)
    _header(msg, KIND_COMMAND, topic, train_id)
    _int(msg, "sid", 0, INT31, topic)
    _int(msg, "rseq", 0, INT31, topic)
    _int(msg, "v_mmps", 0, 5000, topic)
    _int(msg, "eoa_mm", -INT31, INT31, topic)
    _int(msg, "ttl_ms", 1, 10000, topic)
    _int(msg, "acc", 1, 10000, topic)
    _int(msg, "dec", 1, 10000, topic)
    return msg
