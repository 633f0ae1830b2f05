"""docs/protocol.md and the wire modules say the same: the topics, the payload limit, the replay windows (the field
tables: tests/test_messages.py)."""

import os

from cbtc.protocol import wire, wire_zc

DOC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "docs", "protocol.md")


def test_topics_and_limits_match():
    doc = open(DOC).read()
    for topic in (wire.topic_report("<id>"), wire.topic_command("<id>"), wire.topic_status("<id>"),
                  wire_zc.topic_zone_status("<zone>"), wire_zc.topic_zone_info("<zone>")):
        assert f"`{topic}`" in doc
    assert f"Payloads over {wire.MAX_PAYLOAD} bytes are refused" in doc
    assert wire_zc.decode_report.__module__.endswith("wire_zc") and wire.VERSION == 2 and "(version 2)" in doc


def test_documented_replay_windows_are_the_coded_ones():
    from cbtc.firmware import obu
    from cbtc.zone import boots

    doc = " ".join(open(DOC).read().split())
    assert f"one of the board's last {obu._HISTORY} reports" in doc
    assert f"a session the board has left (the last {obu._LEFT_SIDS})" in doc
    assert f"a boot the train has left (the last {boots.LEFT_BOOTS})" in doc
    assert f"plus {boots.UPTIME_SLACK_S} s and 2 %" in doc
