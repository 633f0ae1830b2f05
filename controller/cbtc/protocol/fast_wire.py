"""The controller's codec: the board's wire functions (firmware/wire.py, wire_zc.py) giving the same bytes and
objects for less work on CPython: the HMAC, the seal, reading and writing a message's JSON, decoding a report or a
command and encoding either. The zone calls these; a virtual train hands this module to its OnboardUnit as its codec
(the board's own is the wire module). tests/test_wire.py holds each to the standard library's results and the
board's. A simulation, which writes every message it reads, also keeps each message's payload and object from its
writing to its reading (remember_sealed)."""

import hashlib
import json
from binascii import hexlify
from json import encoder as _encoder

from cbtc.firmware import messages, wire, wire_zc

_KEYED = {}   # key -> (inner, outer): SHA-256 states that have taken the key's two padded blocks


_RECENT = None   # once remember_sealed() is called: (key, topic, body) -> its MAC, for bodies sealed once lately
_RECENT_MAX = 256
_WRITTEN = None  # once remember_sealed() is called: a body written here lately -> the object json.loads gives for it


def remember_sealed():
    """Keep each sealed message's MAC until its reader checks it, and the object each report or command body
    written here stands for until it is read: for a process that seals and checks the same messages (a simulation's
    boards and zone), each is then hashed once and its JSON never scanned. A live zone checks messages it did not
    seal and seals messages it does not check, so it does not call this: the memory would only cost it time."""
    global _RECENT, _WRITTEN
    if _RECENT is None:
        _RECENT, _WRITTEN = {}, {}


def _remember(table, key, value):
    """Keep `value` under `key` in `table` (_RECENT or _WRITTEN) until it is taken; a table at _RECENT_MAX starts
    again empty: what it held was never taken (its message lost on the way)."""
    if len(table) >= _RECENT_MAX:
        table.clear()
    table[key] = value


def _written(body, msg):
    """Remember that `body` reads as `msg` (a fresh object no one else holds), for loads to hand out once."""
    _remember(_WRITTEN, body, msg)


def hmac_sha256(key, msg, _digest_name="sha256"):
    """HMAC-SHA256 of `msg` with `key` (RFC 2104), as hmac.digest gives it, from SHA-256 states that have taken the
    key's padded blocks once: each message costs two copies and two short hashes, less than hmac.digest (it
    hashes both padded blocks again every message; a zone seals and checks two or three messages a report). The
    padding is wire.hmac_sha256_hashlib's, written inline there: as a function of its own it costs the board 224 B
    of a heap at its limit."""
    states = _KEYED.get(key)
    if states is None:
        block = hashlib.sha256(key).digest() if len(key) > 64 else key
        block = block + bytes(64 - len(block))
        if len(_KEYED) >= 1024:   # a zone has one key a train; bounded all the same
            _KEYED.clear()
        states = _KEYED[key] = (hashlib.sha256(bytes(b ^ 0x36 for b in block)),
                                hashlib.sha256(bytes(b ^ 0x5C for b in block)))
    inner, outer = states[0].copy(), states[1].copy()
    inner.update(msg)
    outer.update(inner.digest())
    return outer.digest()


def _macs():
    """(mac_hex, seal): wire.mac_hex and wire.seal, the same bytes from hmac_sha256 in one piece; after
    remember_sealed(), the MAC of a body sealed here is looked up, not hashed again, when its reader checks it."""
    mac_bytes = wire._MAC_BYTES

    def mac_hex(key, topic, body):
        recent = _RECENT
        if recent is not None:
            mac = recent.pop((key, topic, body), None)
            if mac is not None:
                return mac
        return hexlify(hmac_sha256(key, topic.encode() + b"\n" + body)[:mac_bytes])

    def seal(key, topic, body):
        mac = hexlify(hmac_sha256(key, topic.encode() + b"\n" + body)[:mac_bytes])
        if _RECENT is not None:
            _remember(_RECENT, (key, topic, body), mac)
        return body + b"#" + mac

    mac_hex.__doc__ = wire.mac_hex.__doc__
    seal.__doc__ = wire.seal.__doc__
    return mac_hex, seal


mac_hex, seal = _macs()


_scan_once = json.decoder.JSONDecoder().scan_once


def loads(data):
    """json.loads(data), the same object or the same error: a message's ASCII body is read by json's own C scanner
    at once, without the detours of loads (finding the encoding, skipping whitespace); any other input (whitespace
    around the value, another encoding, bad JSON) goes through json.loads itself. After remember_sealed(), a body
    written here is not scanned: the object it stands for, made as it was written, is handed out (once: a second
    read scans)."""
    if _WRITTEN is not None and type(data) is bytes:
        msg = _WRITTEN.pop(data, None)
        if msg is not None:
            return msg
    try:
        text = data.decode("ascii")
        value, end = _scan_once(text, 0)
        if end == len(text):
            return value
    except (AttributeError, UnicodeDecodeError, StopIteration, ValueError):
        pass
    return json.loads(data)


def decode_command(key, topic, payload):
    """wire.decode_command: the command dict of a sealed payload, validated; WireError with the reason otherwise."""
    return _decode_command(key, topic, payload, _COMMAND_INTS, mac_hex, loads)


def decode_report(key, topic, payload):
    """wire_zc.decode_report: the report dict of a sealed payload, validated; WireError with the reason otherwise."""
    return _check_report(_decode_sealed(key, topic, payload, "rep", _REPORT_INTS, mac_hex, loads), topic)


_decode_command, _decode_sealed, _check_report = wire.decode_command, wire.decode_sealed, wire_zc.check_report
_COMMAND_INTS, _REPORT_INTS = wire.COMMAND_INTS, wire_zc.REPORT_INTS


_compact = json.JSONEncoder(separators=(",", ":"))
# json's C encoder, made once: JSONEncoder.encode makes one per call. Made without the check for cycles, which only
# turns the ValueError of a message that holds itself into a RecursionError: a message is numbers, strings and lists
_c_encode = None if _encoder.c_make_encoder is None else _encoder.c_make_encoder(
    None, _compact.default, _encoder.encode_basestring_ascii, None, ":", ",", False, False, True)


def dumps_compact(msg):
    """The JSON text of `msg`, as json.JSONEncoder(separators=(",", ":")).encode(msg) writes it."""
    if _c_encode is None:
        return _compact.encode(msg)
    return "".join(_c_encode(msg, 0))


# a report's JSON up to its optional `rng`, as dumps_compact writes it when every integer field is an int and the id
# and mode need no escaping; the list fields are filled in by _list_json
_REPORT_JSON = ('{"v":%d,"k":"rep","id":"%s","boot":%d,"seq":%d,"t_ms":%d,"odo_mm":%d,"v_mmps":%d,"duty":%d,'
                '"mode":"%s","cseq":%d,"csid":%d,"ips":%s,"tags":%s,"flt":%s')
_INT_ONLY = {int}   # the types of a report's integer fields when every one is an int (a bool is not)


_ODD = object()   # _list_json's reading of a value dumps_compact writes: not remembered


def _list_json(value, names):
    """(dumps_compact(value), a fresh copy of what json.loads reads back from it) for a report's list field when it
    is None, a list of ints or a list of `names` (strings JSON writes unescaped); (dumps_compact(value), _ODD)
    otherwise."""
    if value is None:
        return "null", None
    if type(value) is list or type(value) is tuple:
        if not value:
            return "[]", []
        kinds = set(map(type, value))
        if kinds == _INT_ONLY:
            return "[" + ",".join(map(str, value)) + "]", list(value)
        if kinds == {str} and names.issuperset(value):
            return '["' + '","'.join(value) + '"]', list(value)
    return dumps_compact(value), _ODD


def _report_encoder():
    """wire.encode_report, giving the same payload from a template where the board's builds a dict and writes it as
    JSON, which costs more: every virtual train seals a report 20 to 50 times a second. After remember_sealed(), the
    report a plain body stands for is remembered for loads."""
    board_encode, plain_id = wire.encode_report, wire_zc._plain_id
    modes, names = frozenset(wire_zc.MODES), frozenset(wire_zc.FAULTS)
    version, topic_report = wire.VERSION, wire.topic_report

    def encode_report(key, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid, ips, tags, faults,
                      rng=None, way=1):
        if not (set(map(type, (boot, seq, t_ms, odo_mm, v_mmps, duty_pct, cseq, csid))) == _INT_ONLY and way in (1, -1)
                and type(mode) is str and mode in modes and plain_id(train_id)):
            return board_encode(key, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid, ips,
                                tags, faults, rng, way)
        ips_json, ips = _list_json(ips, names)
        tags_json, tags = _list_json(tags, names)
        faults_json, faults = _list_json(faults, names)
        body = _REPORT_JSON % (version, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid,
                               ips_json, tags_json, faults_json)
        if rng is not None:
            rng_json, rng = _list_json(rng, names)
            body += ',"rng":' + rng_json
        body = (body + (',"dir":1}' if way < 0 else "}")).encode()
        if _WRITTEN is not None and ips is not _ODD and tags is not _ODD and faults is not _ODD and rng is not _ODD:
            msg = {"v": version, "k": "rep", "id": train_id, "boot": boot, "seq": seq, "t_ms": t_ms, "odo_mm": odo_mm,
                   "v_mmps": v_mmps, "duty": duty_pct, "mode": mode, "cseq": cseq, "csid": csid, "ips": ips,
                   "tags": tags, "flt": faults}
            if rng is not None:
                msg["rng"] = rng
            if way < 0:
                msg["dir"] = 1
            _written(body, msg)
        return seal(key, topic_report(train_id), body)

    encode_report.__doc__ = board_encode.__doc__
    return encode_report


def command_encoder(message=messages.COMMAND, defaults=messages.COMMAND_DEFAULTS):
    """wire_zc.command_encoder's encoder, the same payload sealed by this module's seal; after remember_sealed(), the
    command a plain body stands for is remembered for loads (a zone sends one for most reports)."""
    board_encode, plain_body = wire_zc.command_encoder(message, defaults, seal)
    keys, fields_of = messages.names(message), wire_zc.fields_of
    version, topic_command = wire.VERSION, wire.topic_command

    def encode_command(key, train_id, *values, **named):
        if _WRITTEN is None:
            return board_encode(key, train_id, *values, **named)
        ints = fields_of(keys, defaults, values, named)
        text = plain_body(train_id, ints)
        if text is None:
            return board_encode(key, train_id, *ints)
        body = text.encode()
        msg = {"v": version, "k": "cmd", "id": train_id}
        msg.update(zip(keys, ints))
        _written(body, msg)
        return seal(key, topic_command(train_id), body)

    encode_command.__doc__ = board_encode.__doc__
    return encode_command


encode_report = _report_encoder()
encode_command = command_encoder()
