"""The controller's versions of four things the board's wire module does, each giving the same bytes or objects for
less work on CPython: the HMAC, reading a message's JSON, writing a message's JSON and writing a report.
`cbtc.protocol` installs them into `wire`, so the zone and the virtual trains running the board's code use them;
tests/test_wire.py holds them to the standard library's results and the board's."""

import hashlib
import json
import types
from json import encoder as _encoder

_KEYED = {}   # key -> (inner, outer): SHA-256 states that have taken the key's two padded blocks


_RECENT = None   # once remember_macs() is called: (key, message) -> its MAC, for messages MACed once lately
_RECENT_MAX = 256


def remember_macs():
    """Keep each message's MAC until the message is MACed again, for a process that seals and checks the same
    messages (a simulation's boards and zone): each is then hashed once. A live zone checks messages it did not seal
    and seals messages it does not check, so it does not call this: the memory would only cost it time."""
    global _RECENT
    if _RECENT is None:
        _RECENT = {}


def hmac_sha256(key, msg, _digest_name="sha256"):
    """HMAC-SHA256 of `msg` with `key` (RFC 2104), as hmac.digest gives it, from SHA-256 states that have taken the
    key's padded blocks once: each message costs two copies and two short hashes, half of hmac.digest's time (it
    hashes both padded blocks again every message; a zone seals and checks two or three messages a report). The
    padding is wire.hmac_sha256_hashlib's, written inline there: as a function of its own it costs the board 224 B
    of a heap at its limit. After remember_macs(), a message MACed a second time is looked up instead."""
    recent = _RECENT
    if recent is not None:
        mac = recent.pop((key, msg), None)
        if mac is not None:
            return mac
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
    mac = outer.digest()
    if recent is not None:
        if len(recent) >= _RECENT_MAX:   # messages never MACed again (their copy lost on the way): forgotten
            recent.clear()
        recent[(key, msg)] = mac
    return mac


_scan_once = json.decoder.JSONDecoder().scan_once


def loads(data):
    """json.loads(data), the same object or the same error: a message's ASCII body is read by json's own C scanner
    at once, without the detours of loads (finding the encoding, skipping whitespace); any other input (whitespace
    around the value, another encoding, bad JSON) goes through json.loads itself."""
    try:
        text = data.decode("ascii")
        value, end = _scan_once(text, 0)
        if end == len(text):
            return value
    except (AttributeError, UnicodeDecodeError, StopIteration, ValueError):
        pass
    return json.loads(data)


JSON = types.SimpleNamespace(loads=loads)   # `json` as wire's decode_sealed reads a message with it


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


def _list_json(value, names):
    """dumps_compact(value) for a report's list field: written here when it is None, a list of ints or a list of
    `names` (strings JSON writes unescaped), by dumps_compact otherwise."""
    if value is None:
        return "null"
    if type(value) is list or type(value) is tuple:
        if not value:
            return "[]"
        kinds = set(map(type, value))
        if kinds == _INT_ONLY:
            return "[" + ",".join(map(str, value)) + "]"
        if kinds == {str} and names.issuperset(value):
            return '["' + '","'.join(value) + '"]'
    return dumps_compact(value)


def report_encoder(wire, wire_zc):
    """wire.encode_report, giving the same payload from a template where the board's builds a dict and writes it as
    JSON (a third of the time): every virtual train seals a report 20 to 50 times a second."""
    board_encode, plain_id = wire.encode_report, wire_zc._plain_id
    modes, names = frozenset(wire_zc.MODES), frozenset(wire_zc.FAULTS)
    version, seal, topic_report = wire.VERSION, wire.seal, wire.topic_report

    def encode_report(key, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid, ips, tags, faults,
                      rng=None):
        if not (set(map(type, (boot, seq, t_ms, odo_mm, v_mmps, duty_pct, cseq, csid))) == _INT_ONLY
                and type(mode) is str and mode in modes and plain_id(train_id)):
            return board_encode(key, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid, ips,
                                tags, faults, rng)
        body = _REPORT_JSON % (version, train_id, boot, seq, t_ms, odo_mm, v_mmps, duty_pct, mode, cseq, csid,
                               _list_json(ips, names), _list_json(tags, names), _list_json(faults, names))
        body += "}" if rng is None else ',"rng":' + _list_json(rng, names) + "}"
        return seal(key, topic_report(train_id), body.encode())

    encode_report.__doc__ = board_encode.__doc__
    encode_report.board_encode = board_encode   # the board's own, which tests/test_wire.py holds this one to
    return encode_report
