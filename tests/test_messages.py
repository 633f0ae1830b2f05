"""The message table (firmware/messages.py) is what both sides and the document follow: the board's copy of the
command's bounds, the order a report is written in, docs/protocol.md's tables; and a field added to a copy of the
command table is encoded, checked and decoded by both sides with no other change."""

import json
import os

import pytest

from cbtc.protocol import fast_wire, messages, wire, wire_zc
from cbtc.protocol.message_docs import markdown
from cbtc.protocol.records import Command

DOC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "protocol.md")
KEY = b"0123456789abcdef"
TOPIC = wire.topic_command("A")


def _body(payload):
    return json.loads(payload[:payload.rindex(b"#")])


def test_the_boards_command_bounds_are_the_tables():
    assert wire.COMMAND_INTS == messages.int_specs(messages.COMMAND)
    assert (wire.ODO_MM_PER_M_MIN, wire.ODO_MM_PER_M_MAX) == messages.field(messages.COMMAND, "odo_mm_per_m")[2]
    assert Command._fields == messages.names(messages.COMMAND)


def test_the_zones_checks_are_made_from_the_table():
    assert wire_zc.REPORT_INTS == messages.int_specs(messages.REPORT)
    assert set(wire_zc.REPORT_INTS[::3]) | set(wire_zc.REPORT_OTHER) == set(messages.names(messages.REPORT))
    for name, specs in (("ips", wire_zc.IPS_INTS), ("rng", wire_zc.RNG_INTS), ("tags", wire_zc.TAG_INTS)):
        assert messages.field(messages.REPORT, name)[2] == specs
    assert messages.field(messages.REPORT, "mode")[2] == wire_zc.MODES
    assert messages.field(messages.REPORT, "flt")[2] == wire_zc.FAULTS


def test_the_board_writes_a_report_in_the_tables_order():
    payload = wire.encode_report(KEY, "A", 1, 1, 100, 5, 0, 0, "run", -1, -1, None, [], [], rng=[90, 400], way=-1)
    assert list(_body(payload)) == ["v", "k", "id"] + list(messages.names(messages.REPORT))
    assert fast_wire.encode_report(KEY, "A", 1, 1, 100, 5, 0, 0, "run", -1, -1, None, [], [], [90, 400], -1) == payload
    forward = wire.encode_report(KEY, "A", 1, 1, 100, 5, 0, 0, "run", -1, -1, None, [], [])
    assert "dir" not in _body(forward)   # absent while the board drives forward: read as 0
    assert fast_wire.encode_report(KEY, "A", 1, 1, 100, 5, 0, 0, "run", -1, -1, None, [], []) == forward
    assert wire_zc.decode_report(KEY, wire.topic_report("A"), payload)["dir"] == 1


def test_the_document_shows_the_tables_as_they_are():
    doc = open(DOC).read()
    for message in (messages.REPORT, messages.COMMAND, messages.ZONE_INFO):
        assert markdown(message) in doc, "paste in what `python -m cbtc.protocol.message_docs` prints"


def test_a_field_added_to_the_command_table_is_encoded_checked_and_decoded_by_both_sides():
    kind, fields = messages.COMMAND
    table = (kind, fields + (("prio", "int", (0, 9), "", "a priority a test adds"),))
    defaults = dict(messages.COMMAND_DEFAULTS, prio=0)
    specs = messages.int_specs(table)
    base = dict(boot=1, seq=2, sid=7, rseq=1, v_mmps=300, eoa_mm=1000, ttl_ms=800, acc=600, dec=800)
    zone_encode, _plain = wire_zc.command_encoder(table, defaults)
    fast_encode = fast_wire.command_encoder(table, defaults)
    for encode in (zone_encode, fast_encode):
        payload = encode(KEY, "A", prio=4, **base)
        command = wire.decode_command(KEY, TOPIC, payload, specs)   # the board's check, on the copied table
        assert command["prio"] == 4 and command["stop_mm"] == 1000 and command["odo_mm_per_m"] == 1000
        assert wire.decode_command(KEY, TOPIC, encode(KEY, "A", **base), specs)["prio"] == 0   # its default
        with pytest.raises(wire.WireError, match="'prio'.*in \\[0, 9\\]"):
            wire.decode_command(KEY, TOPIC, encode(KEY, "A", prio=12, **base), specs)
        with pytest.raises(wire.WireError, match="unknown field 'prio'"):   # a board of the old table refuses it
            wire.decode_command(KEY, TOPIC, payload)
    assert zone_encode(KEY, "A", prio=4, **base) == fast_encode(KEY, "A", prio=4, **base)
    record = Command(**dict(base, stop_mm=900, rpt_ms=0, odo_mm_per_m=1000, dir=0))
    assert wire.decode_command(KEY, TOPIC, fast_wire.encode_command(KEY, "A", *record))["stop_mm"] == 900


def test_an_encoder_given_fields_wrong_names_them():
    with pytest.raises(wire.WireError, match="'ttl_ms' is missing"):
        wire_zc.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000)
    with pytest.raises(wire.WireError, match="'speed' is not in the message"):
        wire_zc.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000, 800, 600, 800, speed=3)
    with pytest.raises(wire.WireError, match="'seq' is given twice"):
        wire_zc.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000, 800, 600, 800, seq=3)


def test_every_topic_is_in_the_table_as_the_document_and_both_sides_have_it():
    from cbtc.bus import client

    doc = open(DOC).read()
    assert [t[0] for t in messages.TOPICS] == [wire.topic_report("<id>"), wire.topic_command("<id>"),
                                              wire.topic_status("<id>"), wire_zc.topic_zone_status("<zone>"),
                                              wire_zc.topic_zone_info("<zone>")]
    for topic, direction, qos, retained, carries in messages.TOPICS:
        row = next(line for line in doc.splitlines() if line.startswith(f"| `{topic}` |"))
        cells = [cell.strip() for cell in row.split("|")[1:-1]]
        assert cells[1:4] == [direction, str(qos), "yes" if retained else "no"], row
        if carries is messages.STATUS:
            assert cells[5] == "`online` / `offline` (last will)"
    assert (client.ONLINE.decode(), client.OFFLINE.decode()) == messages.STATUS


def test_a_field_given_as_none_takes_its_default():
    full = wire_zc.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000, 800, 600, 800, None, 0, 1000)
    assert full == wire_zc.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000, 800, 600, 800)
    assert full == fast_wire.encode_command(KEY, "A", 1, 2, 7, 1, 300, 1000, 800, 600, 800, None, 0, 1000)
    assert _body(full)["stop_mm"] == 1000
