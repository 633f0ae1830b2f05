"""Property-based checks (Hypothesis) of every parser that meets outside data: the wire module both ways, the
balise telegram decoder, the IPS frame parser, the MFRC522 driver's answers and the layout loader.

Each property is a plain function of generated values, run by tests/test_properties.py twice: bounded in the normal
suite and long under `pytest -m fuzz`. The properties: no uncaught exception, every rejection with a reason,
nothing accepted that breaks the schema, round trips exact.
"""

import json
import string

import yaml
from hypothesis import strategies as st

from cbtc.errors import LayoutError
from cbtc.firmware import telegram
from cbtc.layout_files import resolve_layout
from cbtc.protocol import wire, wire_zc
from cbtc.railway.layout_dict import layout_from_dict

KEY = b"0123456789abcdef"
REPORT_TOPIC = wire.topic_report("A")
CMD_TOPIC = wire.topic_command("A")
INT31 = wire.INT31
WRAP = wire.WRAP_MASK

# --- strategies --------------------------------------------------------------------------------------------------

json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-2 ** 70, 2 ** 70) | st.floats(allow_nan=False) | st.text(max_size=12),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=6), inner, max_size=4),
    max_leaves=12)
hex_text = st.sampled_from(wire_zc.UID_HEX_LENGTHS).flatmap(
    lambda n: st.text("0123456789ABCDEFabcdef", min_size=n, max_size=n))
board_ms = st.integers(0, WRAP)
span_ms = st.integers(0, wire_zc.SPAN_MAX_MS)
tags = st.lists(st.one_of(
    st.tuples(hex_text, st.integers(-INT31, INT31), board_ms, span_ms).map(list),
    st.tuples(hex_text, st.integers(-INT31, INT31), board_ms, span_ms,
              st.text("0123456789abcdef", min_size=32, max_size=32)).map(list)), max_size=wire.MAX_TAGS)
report_fields = st.fixed_dictionaries({
    "boot": st.integers(1, wire.BOOT_MAX), "seq": board_ms, "t_ms": board_ms, "odo_mm": st.integers(-INT31, INT31),
    "v_mmps": st.integers(-20000, 20000), "duty_pct": st.integers(-100, 100), "mode": st.sampled_from(wire_zc.MODES),
    "cseq": st.integers(-1, WRAP), "csid": st.integers(-1, INT31),
    "ips": st.none() | st.tuples(board_ms, st.integers(-10 ** 6, 10 ** 6), st.integers(-10 ** 6, 10 ** 6)).map(list),
    "tags": tags, "faults": st.lists(st.sampled_from(wire_zc.FAULTS), max_size=4),
    "rng": st.none() | st.tuples(board_ms, st.integers(-100000, 10 ** 6)).map(list)})
command_fields = st.fixed_dictionaries({
    "boot": st.integers(1, wire.BOOT_MAX), "seq": board_ms, "sid": st.integers(0, INT31), "rseq": board_ms,
    "v_mmps": st.integers(0, 5000), "eoa_mm": st.integers(-INT31, INT31), "ttl_ms": st.integers(1, 10000),
    "acc_mmps2": st.integers(1, 10000), "dec_mmps2": st.integers(1, 10000), "stop_mm": st.integers(-INT31, INT31),
    "rpt_ms": st.integers(0, 10000),
    "odo_mm_per_m": st.integers(wire.ODO_MM_PER_M_MIN, wire.ODO_MM_PER_M_MAX), "dir": st.integers(0, 1)})


@st.composite
def mutated_bodies(draw, fields, encode):
    """The JSON body of a valid message with one to three fields replaced by any JSON value, dropped or added."""
    body = json.loads(encode(draw(fields)).rsplit(b"#", 1)[0])
    for _ in range(draw(st.integers(1, 3))):
        name = draw(st.sampled_from(sorted(body)) | st.text(max_size=6))
        if draw(st.booleans()) and name in body:
            del body[name]
        else:
            body[name] = draw(json_values)
    return body


def encode_report(fields):
    f = dict(fields)
    return wire.encode_report(KEY, "A", f.pop("boot"), f.pop("seq"), f.pop("t_ms"), f.pop("odo_mm"),
                              f.pop("v_mmps"), f.pop("duty_pct"), f.pop("mode"), f.pop("cseq"), f.pop("csid"),
                              f.pop("ips"), f.pop("tags"), f.pop("faults"), f.pop("rng"))


def encode_command(fields):
    f = dict(fields)
    return wire_zc.encode_command(KEY, "A", f.pop("boot"), f.pop("seq"), f.pop("sid"), f.pop("rseq"), f.pop("v_mmps"),
                               f.pop("eoa_mm"), f.pop("ttl_ms"), f.pop("acc_mmps2"), f.pop("dec_mmps2"),
                               f.pop("stop_mm"), f.pop("rpt_ms"), f.pop("odo_mm_per_m"), f.pop("dir"))


# --- the schema, written out independently of wire's checks ------------------------------------------------------

def _int_in(value, lo, hi):
    return type(value) is int and lo <= value <= hi


def _ints(values, bounds):
    return type(values) is list and len(values) == len(bounds) and all(
        _int_in(v, lo, hi) for v, (lo, hi) in zip(values, bounds))


def _hex(value, lengths):
    return type(value) is str and len(value) in lengths and all(c in string.hexdigits for c in value)


def report_conforms(msg):
    ints = {"boot": (1, wire.BOOT_MAX), "seq": (0, WRAP), "t_ms": (0, WRAP), "odo_mm": (-INT31, INT31),
            "v_mmps": (-20000, 20000), "duty": (-100, 100), "cseq": (-1, WRAP), "csid": (-1, INT31)}
    allowed = set(ints) | {"v", "k", "id", "mode", "ips", "tags", "rng", "flt"}
    return (set(msg) <= allowed and msg["v"] == wire.VERSION and type(msg["v"]) is int and msg["k"] == "rep"
            and msg["id"] == "A" and all(_int_in(msg[k], *b) for k, b in ints.items()) and msg["mode"] in wire_zc.MODES
            and (msg["ips"] is None or _ints(msg["ips"], [(0, WRAP), (-10 ** 6, 10 ** 6), (-10 ** 6, 10 ** 6)]))
            and (msg["rng"] is None or _ints(msg["rng"], [(0, WRAP), (-100000, 10 ** 6)]))
            and type(msg["tags"]) is list and len(msg["tags"]) <= wire.MAX_TAGS
            and all(type(t) is list and len(t) in (4, 5) and _hex(t[0], (8, 14, 20))
                    and _ints(t[1:4], [(-INT31, INT31), (0, WRAP), (0, wire_zc.SPAN_MAX_MS)])
                    and (len(t) == 4 or _hex(t[4], (32,)))
                    for t in msg["tags"])
            and type(msg["flt"]) is list and all(f in wire_zc.FAULTS for f in msg["flt"]))


def command_conforms(msg):
    ints = {"boot": (1, wire.BOOT_MAX), "seq": (0, WRAP), "sid": (0, INT31), "rseq": (0, WRAP), "v_mmps": (0, 5000),
            "eoa_mm": (-INT31, INT31), "ttl_ms": (1, 10000), "acc": (1, 10000), "dec": (1, 10000),
            "stop_mm": (-INT31, INT31), "rpt_ms": (0, 10000), "odo_mm_per_m": (500, 2000), "dir": (0, 1)}
    return (set(msg) == set(ints) | {"v", "k", "id"} and msg["v"] == wire.VERSION and type(msg["v"]) is int
            and msg["k"] == "cmd" and msg["id"] == "A" and all(_int_in(msg[k], *b) for k, b in ints.items()))


def decoded_or_reason(decode, key, topic, payload):
    """("ok", message) or ("refused", reason): the only two outcomes a decoder may have."""
    try:
        return "ok", decode(key, topic, payload)
    except wire.WireError as exc:
        assert isinstance(exc.reason, str) and exc.reason, "a refusal names its reason"
        return "refused", exc.reason


# --- properties ----------------------------------------------------------------------------------------------------

def report_round_trip(fields):
    msg = wire_zc.decode_report(KEY, REPORT_TOPIC, encode_report(fields))
    expected = {"v": wire.VERSION, "k": "rep", "id": "A", "boot": fields["boot"], "seq": fields["seq"],
                "t_ms": fields["t_ms"], "odo_mm": fields["odo_mm"], "v_mmps": fields["v_mmps"],
                "duty": fields["duty_pct"], "mode": fields["mode"], "cseq": fields["cseq"], "csid": fields["csid"],
                "ips": fields["ips"],
                "tags": fields["tags"], "flt": fields["faults"], "rng": fields["rng"]}
    assert msg == expected


def command_round_trip(fields):
    msg = wire.decode_command(KEY, CMD_TOPIC, encode_command(fields))
    assert msg == {"v": wire.VERSION, "k": "cmd", "id": "A", "boot": fields["boot"], "seq": fields["seq"],
                   "sid": fields["sid"], "rseq": fields["rseq"], "v_mmps": fields["v_mmps"], "eoa_mm": fields["eoa_mm"],
                   "ttl_ms": fields["ttl_ms"], "acc": fields["acc_mmps2"], "dec": fields["dec_mmps2"],
                   "stop_mm": fields["stop_mm"], "rpt_ms": fields["rpt_ms"], "odo_mm_per_m": fields["odo_mm_per_m"],
                   "dir": fields["dir"]}


def mutated_report_is_refused_or_conforms(body):
    payload = wire.seal(KEY, REPORT_TOPIC, json.dumps(body).encode())
    verdict, value = decoded_or_reason(wire_zc.decode_report, KEY, REPORT_TOPIC, payload)
    assert verdict == "refused" or report_conforms(value), value


def mutated_command_is_refused_or_conforms(body):
    payload = wire.seal(KEY, CMD_TOPIC, json.dumps(body).encode())
    verdict, value = decoded_or_reason(wire.decode_command, KEY, CMD_TOPIC, payload)
    assert verdict == "refused" or command_conforms(value), value


def any_bytes_are_refused_with_a_reason(payload, sealed):
    for topic, decode in ((REPORT_TOPIC, wire_zc.decode_report), (CMD_TOPIC, wire.decode_command)):
        data = wire.seal(KEY, topic, payload) if sealed else payload
        verdict, value = decoded_or_reason(decode, KEY, topic, data)
        assert verdict == "refused" or (report_conforms(value) if topic == REPORT_TOPIC else command_conforms(value))


def telegram_round_trip_corrects_one_error_and_detects_two(data, flips):
    frame = telegram.encode(data)
    assert telegram.decode(frame) == (data, telegram.OK)
    one = bytearray(frame)
    one[flips[0] % len(frame)] ^= 1
    assert telegram.decode(one) == (data, telegram.CORRECTED)
    a, b = flips[0] % len(frame), flips[1] % len(frame)
    if a != b:
        one[b] ^= 1
        assert telegram.decode(one) == (None, telegram.DETECTED)


def telegram_decodes_any_bits_without_surprise(bits):
    try:
        data, status = telegram.decode(bytearray(bits))
    except ValueError as exc:           # a length no telegram has, said so
        assert "length" in str(exc)
        return
    assert status in (telegram.OK, telegram.CORRECTED, telegram.DETECTED)
    assert (data is None) == (status == telegram.DETECTED)


def layout_mutation_loads_or_names_the_problem(name, path, value):
    """A shipped layout with one value anywhere in its tree replaced: a Layout, or a LayoutError naming the file."""
    with open(resolve_layout(name)) as fh:
        data = yaml.safe_load(fh)
    node = data
    for step in path[:-1]:
        keys = list(node) if isinstance(node, dict) else list(range(len(node))) if isinstance(node, list) else []
        if not keys:
            break
        child = node[keys[step % len(keys)]]
        if not isinstance(child, (dict, list)) or not child:
            break
        node = child
    keys = list(node) if isinstance(node, dict) else list(range(len(node)))
    if keys:
        node[keys[path[-1] % len(keys)]] = value
    try:
        layout_from_dict(data, f"{name}.yaml")
    except LayoutError as exc:
        assert str(exc).startswith(f"{name}.yaml: "), str(exc)
