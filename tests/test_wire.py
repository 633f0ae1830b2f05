"""The wire protocol: authentication, validation with reasons, round trips (CPython; the unix-port run is in
test_firmware_mpy)."""

import hashlib
import hmac
import json
import os

import pytest

from cbtc.protocol import fast_wire, wire, wire_zc

KEY = bytes(range(16))
BOOT = 77


def report(**changes):
    fields = dict(seq=7, t_ms=1000, odo_mm=1234, v_mmps=400, duty_pct=55, mode="run", cseq=3, csid=99,
                  ips=[950, 100, -200], tags=[["04A1B2C3D4E5F6", 1200, 990, 8]], faults=["ips_crc"])
    fields.update(changes)
    return fast_wire.encode_report(KEY, "A", BOOT, **fields)


def test_hmac_matches_the_standard_library():
    """The board's hashlib-only HMAC (MicroPython has no hmac module) and the one CPython uses give the standard
    library's digest, messages in parts or whole, keys shorter and longer than a block."""
    for key in (b"", b"k", KEY, b"x" * 64, b"w" * 65, b"y" * 100):
        for msg in (b"", b"abc", b"z" * 1000):
            want = hmac.new(key, msg, hashlib.sha256).digest()
            assert wire.hmac_sha256(key, msg) == want
            assert fast_wire.hmac_sha256(key, msg) == want and fast_wire.hmac_sha256(key, msg) == want   # kept states
            assert wire.hmac_sha256_hashlib(key, msg[:2], msg[2:]) == want
            assert wire.hmac_sha256(key, msg[:2], msg[2:]) == want


def test_a_sealed_messages_mac_is_looked_up_when_checked_and_the_memory_of_them_is_bounded():
    """The controller's seal and MAC give the board's bytes; after remember_sealed() a body sealed in this process
    (then checked, in a simulation) is hashed once: its check takes the MAC the seal left; another key or topic is
    hashed anew; the MACs kept stay under their bound whatever the traffic."""
    body, topic = b'{"a":' + os.urandom(40).hex().encode() + b"}", "cbtc/train/A/report"
    saved = fast_wire._RECENT, fast_wire._WRITTEN
    fast_wire._RECENT = fast_wire._WRITTEN = None
    try:
        assert fast_wire.seal(KEY, topic, body) == wire.seal(KEY, topic, body)
        assert fast_wire.mac_hex(KEY, topic, body) == wire.mac_hex(KEY, topic, body)
        assert wire.seal(KEY, topic, body) == body + b"#" + wire.mac_hex(KEY, topic, body)
        fast_wire.remember_sealed()   # as a simulation does
        sealed = fast_wire.seal(KEY, topic, body)
        mac = fast_wire._RECENT[(KEY, topic, body)]
        assert fast_wire.mac_hex(KEY, topic, body) is mac and sealed == body + b"#" + mac
        assert (KEY, topic, body) not in fast_wire._RECENT   # taken: a second check hashes again
        assert fast_wire.mac_hex(KEY, topic, body) == mac
        assert fast_wire.mac_hex(b"other", topic, body) == wire.mac_hex(b"other", topic, body)
        assert fast_wire.mac_hex(KEY, "cbtc/train/B/report", body) == wire.mac_hex(KEY, "cbtc/train/B/report", body)
        for i in range(3 * fast_wire._RECENT_MAX):
            fast_wire.seal(KEY, topic, b"%d" % i)
        assert len(fast_wire._RECENT) <= fast_wire._RECENT_MAX
    finally:
        fast_wire._RECENT, fast_wire._WRITTEN = saved


def test_the_controllers_json_gives_the_standard_librarys_results():
    """fast_wire's loads and dumps_compact give what json gives: the same objects, the same text, the same errors,
    whatever the input."""
    compact = json.JSONEncoder(separators=(",", ":")).encode
    messages = [{"v": 1, "k": "rep", "id": "A", "ips": [1, -2, 3], "tags": [["04A1", 5, 6, 7]], "flt": [], "x": None},
                {"f": 1.5, "nan": float("nan"), "big": 2 ** 70, "t": True, "s": "caf\u00e9 \"q\"\n"}, [], "x", 3]
    for msg in messages:
        assert fast_wire.dumps_compact(msg) == compact(msg)
    with pytest.raises(TypeError):
        fast_wire.dumps_compact({"b": b"bytes"})
    texts = [compact(m).encode() for m in messages[:2]] + [
        b' {"a":1}', b'{"a":1}\n', b"[1,2]", b"null", b'"\xc3\xa9"', b"\xef\xbb\xbf{}", '{"a":1}'.encode("utf-16"),
        bytearray(b'{"a":[1]}'), '{"s":1}']
    for text in texts:
        want = json.loads(text)
        got = fast_wire.loads(text)
        assert json.dumps(got) == json.dumps(want) and type(got) is type(want)
    for bad in (b"", b"{", b'{"a":1}x', b"\xff", b"\x00{}", b"[1,]"):
        with pytest.raises(ValueError) as want:
            json.loads(bad)
        with pytest.raises(ValueError) as got:
            fast_wire.loads(bad)
        assert type(got.value) is type(want.value) and str(got.value) == str(want.value)


def test_the_controllers_report_encoder_gives_the_boards_bytes():
    """fast_wire.encode_report is a template; whatever the fields, it gives the payload the board's own encoder
    gives (its dict written by dumps_compact), falling back to it where a field is not plain."""
    fast, board = fast_wire.encode_report, wire.encode_report
    base = dict(seq=7, t_ms=1000, odo_mm=1234, v_mmps=400, duty_pct=55, mode="run", cseq=3, csid=99,
                ips=[950, 100, -200], tags=[["04A1B2C3D4E5F6", 1200, 990, 8]], faults=["ips_crc"])
    cases = [{}, {"ips": None, "tags": [], "faults": []}, {"rng": [1000, 250]}, {"faults": ["roll", "undriven"]},
             {"faults": ["made_up"]}, {"faults": ("roll",)}, {"ips": (1, 2, 3)}, {"ips": [1, True, 3]},
             {"duty_pct": True}, {"v_mmps": 2.5}, {"seq": 2 ** 40}, {"mode": "fly"}, {"odo_mm": -5, "cseq": -1},
             {"tags": [["04A1", 5, 6, 7, "0123"]]}, {"rng": None}, {"ips": [1, 2.5, 3]}, {"faults": ["ips_crc", 3]}]
    for train_id in ("A", "T-12_x", "caf\u00e9", 'q"uote'):
        for case in cases:
            fields = dict(base, **case)
            assert fast(KEY, train_id, BOOT, **fields) == board(KEY, train_id, BOOT, **fields), (train_id, case)


def test_the_controllers_command_encoder_gives_the_boards_bytes():
    """fast_wire.encode_command gives the payload wire_zc's encoder gives, whatever the fields, with a simulation's
    memory of the messages written on or off."""
    fast, board = fast_wire.encode_command, wire_zc.encode_command
    base = (BOOT, 5, 99, 7, 500, 3000, 800, 600, 800)
    cases = [((), {}), ((), {"stop_mm": 2500, "rpt_ms": 40, "odo_mm_per_m": 1015}), ((), {"stop_mm": None}),
             ((True,), {}), ((2.5,), {}), ((-(2 ** 40),), {}), ((), {"rpt_ms": False})]
    for remember in (None, {}):
        saved, fast_wire._WRITTEN = fast_wire._WRITTEN, remember
        try:
            for train_id in ("A", "T-12_x", "caf\u00e9", 'q"uote'):
                for extra, kwargs in cases:
                    args = base[:-len(extra) or None] + extra
                    assert fast(KEY, train_id, *args, **kwargs) == board(KEY, train_id, *args, **kwargs)
        finally:
            fast_wire._WRITTEN = saved


def same(a, b):
    """a and b are equal and of the same types all through, dict keys in the same order."""
    if type(a) is not type(b):
        return False
    if type(a) is dict:
        return list(a) == list(b) and all(same(a[k], b[k]) for k in a)
    if type(a) is list:
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def test_a_simulation_reads_each_message_it_wrote_as_json_reads_it_once():
    """After remember_sealed(), a report or command body written here is read back (once) as the object json.loads
    gives for it, a fresh one; a body read again, or never written here, is scanned; the memory stays bounded."""
    saved = fast_wire._RECENT, fast_wire._WRITTEN
    fast_wire._RECENT, fast_wire._WRITTEN = {}, {}
    try:
        ips = [950, 100, -200]
        plain = [report(ips=ips, tags=[], faults=["roll", "undriven"], rng=[1000, 250]),
                 report(ips=None, tags=None, faults=()), report(ips=(1, 2, 3), tags=(), rng=(4, 5)),
                 fast_wire.encode_command(KEY, "A", BOOT, 5, 99, 7, 500, 3000, 800, 600, 800),
                 fast_wire.encode_command(KEY, "A", BOOT, 6, 99, 7, 500, -3000, 800, 600, 800, stop_mm=-2500,
                                          rpt_ms=40)]
        odd = [report(), report(tags=[], duty_pct=True), report(tags=[], faults=["made_up"]),
               report(tags=[], ips=[1, 2.5, 3]),
               fast_wire.encode_command(KEY, "A", BOOT, 7, 99, 7, True, 3000, 800, 600, 800)]
        ips.append(4)   # the caller's list, changed after its report is written: the report read keeps its ips
        for payload in plain + odd:
            body = payload[:payload.rfind(b"#")]
            assert (body in fast_wire._WRITTEN) == (payload in plain), body
            got = fast_wire.loads(bytes(body))
            assert same(got, json.loads(body)), body
            assert body not in fast_wire._WRITTEN
            got.clear()
            assert same(fast_wire.loads(body), json.loads(body)), "read again: scanned, the same object"
        assert same(fast_wire.loads(bytearray(b'{"a":[1]}')), {"a": [1]}), "an unhashable input is scanned"
        for i in range(3 * fast_wire._RECENT_MAX):
            fast_wire.encode_command(KEY, "A", BOOT, i, 99, 7, 500, 3000, 800, 600, 800)
        assert 0 < len(fast_wire._WRITTEN) <= fast_wire._RECENT_MAX
    finally:
        fast_wire._RECENT, fast_wire._WRITTEN = saved


def test_report_round_trip():
    msg = wire_zc.decode_report(KEY, "cbtc/train/A/report", report())
    assert msg["odo_mm"] == 1234 and msg["ips"] == [950, 100, -200] and msg["tags"][0][0] == "04A1B2C3D4E5F6"


def test_command_round_trip():
    payload = wire_zc.encode_command(KEY, "A", BOOT, 5, 99, 7, 500, 3000, 800, 600, 800)
    msg = wire.decode_command(KEY, "cbtc/train/A/cmd", payload)
    assert (msg["seq"], msg["sid"], msg["rseq"], msg["eoa_mm"], msg["ttl_ms"]) == (5, 99, 7, 3000, 800)
    assert msg["odo_mm_per_m"] == 1000, "a wheel that reads true unless the controller states its scale"
    scaled = wire_zc.encode_command(KEY, "A", BOOT, 6, 99, 7, 500, 3000, 800, 600, 800, odo_mm_per_m=1015)
    assert wire.decode_command(KEY, "cbtc/train/A/cmd", scaled)["odo_mm_per_m"] == 1015


@pytest.mark.parametrize("scale", [0, 499, 2001])
def test_an_encoder_scale_out_of_range_is_refused_naming_the_field(scale):
    payload = wire_zc.encode_command(KEY, "A", BOOT, 5, 99, 7, 500, 3000, 800, 600, 800, odo_mm_per_m=scale)
    with pytest.raises(wire.WireError) as err:
        wire.decode_command(KEY, "cbtc/train/A/cmd", payload)
    assert "'odo_mm_per_m'" in err.value.reason


def reseal(body: dict, topic="cbtc/train/A/report"):
    return wire.seal(KEY, topic, json.dumps(body).encode())


@pytest.mark.parametrize("change, reason", [
    ({"v": 1}, "version 1"),                          # a board of the version before: reflash it
    ({"k": "cmd"}, "kind"),
    ({"id": "B"}, "names train 'B'"),
    ({"seq": -1}, "'seq'"),
    ({"seq": "7"}, "must be an integer"),
    ({"duty": 150}, "'duty'"),
    ({"mode": "fly"}, "'mode'"),
    ({"ips": [1, 2]}, "'ips'"),
    ({"tags": [["x", 1]]}, "'tags'"),
    ({"flt": ["meltdown"]}, "'flt'"),
    ({"v": True}, "version True"),                      # a bool is not a number
    ({"v": 2.0}, "version 2.0"),
    ({"id": None}, "names train None"),
    ({"seq": True}, "must be an integer"),
    ({"t_ms": 2 ** 40}, "'t_ms'"),
    ({"odo_mm": 1.5}, "'odo_mm'"),
    ({"tags": [["04A1B2", 1200, 990, 8]]}, "8, 14 or 20 hex digits"),          # a uid no reader gives
    ({"tags": [["04A1B2ZZ", 1200, 990, 8]]}, "8, 14 or 20 hex digits"),
    ({"tags": [[1234, 1200, 990, 8]]}, "8, 14 or 20 hex digits"),
    ({"tags": [["04A1B2C3", True, 990, 8]]}, "('tags', 'odo_mm')"),
    ({"tags": [["04A1B2C3", 10 ** 400, 990, 8]]}, "('tags', 'odo_mm')"),
    ({"tags": [["04A1B2C3", 1200, -1, 8]]}, "('tags', 't_ms')"),
    ({"tags": [["04A1B2C3", 1200, 990, 8, "00" * 15 + "GG"]]}, "32 hex digits"),
    ({"tags": [["04A1B2C3", 1200, 990, -1]]}, "('tags', 'span_ms')"),              # a time is never negative
    ({"tags": [["04A1B2C3", 1200, 990, 70000]]}, "('tags', 'span_ms')"),
    ({"tags": [["04A1B2C3", 1200, 990]]}, "span_ms]"),                            # no span: version 1's entry
    ({"tags": [["04A1B2C3", 1200, 990, "00" * 16]]}, "('tags', 'span_ms')"),       # its telegram where the span goes
    ({"ips": [950, True, -200]}, "('ips', 'x_mm')"),
    ({"rng": [950, 1.5]}, "('rng', 'gap_mm')"),
    ({"extra": 1}, "unknown field 'extra'"),
])
def test_invalid_report_fields_are_rejected_with_the_reason(change, reason):
    body = json.loads(report().rsplit(b"#", 1)[0])
    body.update(change)
    with pytest.raises(wire.WireError) as err:
        wire_zc.decode_report(KEY, "cbtc/train/A/report", reseal(body))
    assert reason in err.value.reason


@pytest.mark.parametrize("payload, reason", [
    (b"", "no '#<mac>'"),
    (b"not json#00", "fails authentication"),
    (b"x" * 2000, "limit"),
    ("text", "not bytes"),
])
def test_malformed_payloads_are_rejected(payload, reason):
    with pytest.raises(wire.WireError) as err:
        wire_zc.decode_report(KEY, "cbtc/train/A/report", payload)
    assert reason in err.value.reason


def test_sealed_garbage_is_rejected_as_not_json():
    with pytest.raises(wire.WireError, match="not JSON"):
        wire_zc.decode_report(KEY, "cbtc/train/A/report", wire.seal(KEY, "cbtc/train/A/report", b"\xff\x00garbage"))


def test_wrong_key_tampering_and_topic_swap_fail_authentication():
    good = report()
    with pytest.raises(wire.WireError, match="authentication"):
        wire_zc.decode_report(b"another key 1234", "cbtc/train/A/report", good)
    tampered = good.replace(b'"odo_mm":1234', b'"odo_mm":9234')
    with pytest.raises(wire.WireError, match="authentication"):
        wire_zc.decode_report(KEY, "cbtc/train/A/report", tampered)
    cmd = wire_zc.encode_command(KEY, "A", BOOT, 5, 99, 7, 500, 3000, 800, 600, 800)
    with pytest.raises(wire.WireError):
        wire.decode_command(KEY, "cbtc/train/B/cmd", cmd)


@pytest.mark.parametrize("topic", ["cbtc/train/A", "cbtc/train//report", "x/train/A/report", "cbtc/train/A B/report",
                                   "cbtc/train/" + "X" * 17 + "/report"])
def test_bad_topics_name_the_problem(topic):
    with pytest.raises(wire.WireError) as err:
        wire.train_id_of(topic)
    assert "train id" in err.value.reason or "not cbtc/train" in err.value.reason


def test_a_report_without_its_ips_field_is_refused():
    body = json.loads(report().rsplit(b"#", 1)[0])
    del body["ips"]
    with pytest.raises(wire.WireError, match="'ips' .* is missing"):
        wire_zc.decode_report(KEY, "cbtc/train/A/report", reseal(body))


@pytest.mark.parametrize("change, reason", [
    ({"v": True}, "version True"),
    ({"eoa_mm": 3000.0}, "'eoa_mm'"),
    ({"ttl_ms": False}, "'ttl_ms'"),
    ({"sid": 2 ** 31}, "'sid'"),
    ({"boost": 1}, "unknown field 'boost'"),
])
def test_invalid_command_fields_are_rejected_with_the_reason(change, reason):
    payload = wire_zc.encode_command(KEY, "A", BOOT, 5, 99, 7, 500, 3000, 800, 600, 800)
    body = json.loads(payload.rsplit(b"#", 1)[0])
    body.update(change)
    with pytest.raises(wire.WireError) as err:
        wire.decode_command(KEY, "cbtc/train/A/cmd", reseal(body, "cbtc/train/A/cmd"))
    assert reason in err.value.reason


def test_encoding_is_compact_json_by_its_separators():
    body = report().rsplit(b"#", 1)[0]
    assert json.loads(body) == json.loads(json.dumps(json.loads(body), separators=(",", ":")))
    assert body == json.dumps(json.loads(body), separators=(",", ":")).encode()
