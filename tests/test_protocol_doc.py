"""docs/protocol.md and the wire module say the same: the fields of a report and a command and their ranges, the
modes, the faults, the topics and the payload limit."""

import json
import os
import re

from cbtc.protocol import wire

DOC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "protocol.md")
KEY = b"0123456789abcdef"


def _section(text, heading):
    start = text.index(heading)
    end = text.find("\n#", start + len(heading))
    return text[start:end if end >= 0 else None]


def _table_fields(section):
    """The backticked names in the first column of a markdown table."""
    names = set()
    for line in section.splitlines():
        if line.startswith("| `"):
            names.update(re.findall(r"`([a-z_]+)`", line.split("|")[1]))
    return names


def _body(payload):
    return json.loads(payload[:payload.rindex(b"#")])


def test_report_table_lists_exactly_the_report_fields():
    doc = open(DOC).read()
    payload = wire.encode_report(KEY, "A", 1, 1, 100, 5, 0, 0, "run", -1, -1, None, [], [], rng=[90, 400])
    assert _table_fields(_section(doc, "### Report")) == set(_body(payload))


def test_command_table_lists_exactly_the_command_fields():
    doc = open(DOC).read()
    payload = wire.encode_command(KEY, "A", 1, 1, 7, 1, 300, 1000, 800, 600, 800)
    assert _table_fields(_section(doc, "### Command")) == set(_body(payload))


def test_modes_faults_topics_and_limits_match():
    doc = open(DOC).read()
    report = _section(doc, "### Report")
    mode_row = next(line for line in report.splitlines() if line.startswith("| `mode`"))
    assert set(re.findall(r"`([a-z_]+)`", mode_row.split("|")[4])) == set(wire.MODES)
    fault_row = next(line for line in report.splitlines() if line.startswith("| `flt`"))
    assert set(re.findall(r"`([a-z_]+)`", fault_row.split("|")[4])) == set(wire.FAULTS)
    for topic in (wire.topic_report("<id>"), wire.topic_command("<id>"), wire.topic_status("<id>"),
                  wire.topic_zone_status("<zone>")):
        assert f"`{topic}`" in doc
    assert f"Payloads over {wire.MAX_PAYLOAD} bytes are refused" in doc
    assert wire.decode_report.__module__.endswith("wire_zc") and wire.VERSION == 2 and "(version 2)" in doc


def _number(text):
    text = text.strip()
    if text.startswith("-(") and text.endswith(")"):
        return -_number(text[2:-1])
    power = re.fullmatch(r"2\^(\d+)-1", text)
    return 2 ** int(power[1]) - 1 if power else int(text)


def _int_ranges(section):
    """{field: (lo, hi)} of the table rows typed `int` with a range `[lo, hi]`."""
    ranges = {}
    for line in section.splitlines():
        cells = line.split("|")
        if line.startswith("| `") and len(cells) > 4 and cells[2].strip() == "int":
            match = re.fullmatch(r"\[(.+), (.+)\]", cells[3].strip())
            if match:
                ranges[re.findall(r"`([a-z_]+)`", cells[1])[0]] = (_number(match[1]), _number(match[2]))
    return ranges


def _spec_ranges(specs):
    return {specs[i]: (specs[i + 1], specs[i + 2]) for i in range(0, len(specs), 3)}


def test_documented_integer_ranges_are_the_checked_ones():
    doc = open(DOC).read()
    assert _int_ranges(_section(doc, "### Report")) == _spec_ranges(wire.REPORT_INTS)
    assert _int_ranges(_section(doc, "### Command")) == _spec_ranges(wire.COMMAND_INTS)
    tags_row = next(line for line in doc.splitlines() if line.startswith("| `tags`"))
    assert f"at most {wire.MAX_TAGS}" in tags_row
    assert "uid %d, %d or %d hex digits" % wire.UID_HEX_LENGTHS in tags_row
    assert "t_ms " + _doc_range(wire.TAG_INTS[4:6]) in tags_row


def _doc_range(bounds):
    lo, hi = bounds
    powers = {2 ** 31 - 1: "2^31-1", -(2 ** 31 - 1): "-(2^31-1)", 2 ** 30 - 1: "2^30-1"}
    text = lambda n: powers.get(n, str(n))
    return f"[{text(lo)}, {text(hi)}]"


def test_documented_replay_windows_are_the_coded_ones():
    from cbtc.firmware import obu
    from cbtc.zone import boots

    doc = " ".join(open(DOC).read().split())
    assert f"one of the board's last {obu._HISTORY} reports" in doc
    assert f"a session the board has left (the last {obu._LEFT_SIDS})" in doc
    assert f"a boot the train has left (the last {boots.LEFT_BOOTS})" in doc
    assert f"plus {boots.UPTIME_SLACK_S} s and 2 %" in doc
