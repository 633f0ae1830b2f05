"""The zone's retained information (`cbtc/zc/<zone>/info`, messages.ZONE_INFO): what the zone runs, so that those
who run trains beside it can see at start that they run the same protocol version, layout and keys.

Plain JSON, not sealed: it grants nothing (only the zone's broker user may write `cbtc/zc/#`), and it lets a trains
process refuse to run beside a zone it does not match, with one line that names the mismatch and the fix.
"""

import hashlib
import hmac
import json

from cbtc.protocol import messages, wire, wire_zc

KEY_CHECK_TEXT = b"cbtc key check"
_HEX = "0123456789abcdef"
INFO_FILTER = wire_zc.topic_zone_info("+")
STATUS_FILTER = wire_zc.topic_zone_status("+")


def key_check(key: bytes) -> str:
    """The check of a train's key that the zone publishes: HMAC-SHA256(key, KEY_CHECK_TEXT), its first hex digits."""
    digits = messages.field(messages.ZONE_INFO, "checks")[2]
    return hmac.new(key, KEY_CHECK_TEXT, hashlib.sha256).hexdigest()[:digits]


def encode_info(zone_id: str, session_id: int, layout_name: str, layout_digest: str, keys: dict) -> bytes:
    """The zone's info payload (keys: {train id: 16-byte key}): its fields in the table's order."""
    body = {"v": wire.VERSION, "k": messages.ZONE_INFO[0], "id": zone_id, "sid": session_id,
            "layout": layout_name[:messages.field(messages.ZONE_INFO, "layout")[2]], "digest": layout_digest,
            "checks": {train_id: key_check(key) for train_id, key in sorted(keys.items())}}
    return json.dumps(body, separators=(",", ":")).encode()


def decode_info(topic: str, payload: bytes) -> dict:
    """The info of `payload` on `topic`, checked against the table; WireError naming what is wrong. A message of
    another protocol version is returned as it is, with its `v`, for `mismatches` to name."""
    zone_id = topic.split("/")[2] if topic.count("/") == 3 else None
    try:
        msg = json.loads(bytes(payload).decode())
    except (UnicodeDecodeError, ValueError):
        raise wire.WireError(f"payload on {topic} is not JSON") from None
    if not isinstance(msg, dict):
        raise wire.WireError(f"payload on {topic} is not a JSON object")
    if type(msg.get("v")) is int and msg["v"] != wire.VERSION:
        return msg
    for name, want in (("v", wire.VERSION), ("k", messages.ZONE_INFO[0]), ("id", zone_id)):
        if msg.get(name) != want:
            raise wire.WireError(f"message on {topic} names {name} {msg.get(name)!r}; this side expects {want!r}")
    for name, kind, bounds, _unit, _meaning in messages.ZONE_INFO[1]:
        value = msg.get(name)
        if kind == "int":
            ok = type(value) is int and bounds[0] <= value <= bounds[1]
        elif kind == "text":
            ok = isinstance(value, str) and 1 <= len(value) <= bounds
        elif kind == "hex":
            ok = _is_hex(value, bounds)
        else:   # checks
            ok = isinstance(value, dict) and all(_is_id(t) and _is_hex(c, bounds) for t, c in value.items())
        if not ok:
            raise wire.WireError(f"message on {topic}: field {name!r} is not what docs/protocol.md says, got "
                                 f"{value!r}")
    if len(msg) != 3 + len(messages.ZONE_INFO[1]):
        unknown = sorted(set(msg) - {"v", "k", "id"} - set(messages.names(messages.ZONE_INFO)))
        raise wire.WireError(f"message on {topic} has the unknown field {unknown[0]!r} (see docs/protocol.md)")
    return msg


def _is_hex(value, digits):
    return isinstance(value, str) and len(value) == digits and all(ch in _HEX for ch in value)


def _is_id(value):
    try:
        wire.check_train_id(value)
    except wire.WireError:
        return False
    return True


def mismatches(info: dict, layout_name: str, layout_digest: str, keys: dict, key_source: str) -> list:
    """What differs between a zone's `info` and trains run on (layout, keys {train id: key}, this protocol
    version), each as a sentence naming the mismatch and the fix; [] when they match."""
    zone = f"zone {info.get('id')}"
    if info.get("v") != wire.VERSION:
        return [f"{zone} speaks protocol version {info.get('v')} and these trains version {wire.VERSION}: run the "
                f"zone and the trains from one install of the same version"]
    found = []
    if info["digest"] != layout_digest:
        same_name = info["layout"] == layout_name
        found.append(f"{zone} runs layout {info['layout']!r}"
                     + (" (another file of that name)" if same_name else "")
                     + f" and these trains {layout_name!r}: give both the same --layout or --scenario (or start "
                       f"both from one `cbtc setup` folder, --setup DIR)")
    checks = info["checks"]
    strangers = sorted(set(keys) - set(checks))
    if strangers:
        found.append(f"{zone} does not govern train{'s' if len(strangers) > 1 else ''} {', '.join(strangers)} "
                     f"(its trains: {', '.join(sorted(checks)) or 'none'}): give both the same --trains, "
                     f"--train-ids or --scenario")
    wrong = sorted(t for t in set(keys) & set(checks) if key_check(keys[t]) != checks[t])
    if wrong:
        found.append(f"the key{'s' if len(wrong) > 1 else ''} of train{'s' if len(wrong) > 1 else ''} "
                     f"{', '.join(wrong)} ({key_source}) {'are' if len(wrong) > 1 else 'is'} not {zone}'s: give "
                     f"both the same --keys FILE (or start both from one `cbtc setup` folder, --setup DIR)")
    return found
