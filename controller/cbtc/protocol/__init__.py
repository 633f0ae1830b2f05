"""The wire protocol, one definition for boards and controller: the firmware's own modules, imported as a package.

`wire` encodes, validates and authenticates every message; `telegram` is the Hamming-coded balise and speed-code
telegram. A board loads the zone controller's half of the protocol (wire_zc: report decoding, command encoding, zone
topics) through `wire.__getattr__` by its top-level name; here, where the firmware is a package, that half is
attached to `wire` once, so `wire.decode_report` means the same on both sides.
"""

import hashlib
import json
import types

from cbtc.firmware import telegram, wire, wire_zc

for _name, _value in list(vars(wire_zc).items()):
    if not _name.startswith("_") and _name not in vars(wire):
        setattr(wire, _name, _value)


def _no_attribute(name):
    raise AttributeError(f"module {wire.__name__!r} has no attribute {name!r}")


wire.__getattr__ = _no_attribute   # everything of wire_zc is attached; the board's lazy loader is not needed here


_KEYED = {}   # key -> (inner, outer): SHA-256 states that have taken the key's two padded blocks


def _hmac_sha256(key, msg, _digest_name="sha256"):
    """HMAC-SHA256 of `msg` with `key` (RFC 2104), as hmac.digest gives it, from SHA-256 states that have taken the
    key's padded blocks once: each message costs two copies and two short hashes, half of hmac.digest's time (it
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


wire._C_HMAC = _hmac_sha256   # the board's modules, run here by virtual trains, seal with it as well

_scan_once = json.decoder.JSONDecoder().scan_once


def _json_loads(data):
    """json.loads(data), the same object or the same error: a message's ASCII body is read by json's own C scanner
    at once, without the detours of loads (finding the encoding, skipping whitespace); any other input (whitespace
    around the value, another encoding, bad JSON) goes through json.loads itself. A zone and its virtual trains read
    two or three messages a report."""
    try:
        text = data.decode("ascii")
        value, end = _scan_once(text, 0)
        if end == len(text):
            return value
    except (AttributeError, UnicodeDecodeError, StopIteration, ValueError):
        pass
    return json.loads(data)


wire.json = types.SimpleNamespace(loads=_json_loads)   # what wire reads a message with here (decode_sealed)

__all__ = ["telegram", "wire"]
