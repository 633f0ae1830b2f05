"""`cbtc trains` says what its boards refused, and a silent zone, at most once per train per 10 s."""

import logging
from types import SimpleNamespace

import pytest

from cbtc.live.board_notes import BoardNotes
from cbtc.protocol import wire, wire_zc


def wrong_key_reason():
    """The reason the wire module gives a command sealed with a key other than the board's."""
    payload = wire_zc.encode_command(b"another key 16 b", "A", 1, 1, 7, 1, 400, 1000, 800, 600, 800)
    with pytest.raises(wire.AuthError) as refused:
        wire.decode_command(bytes(16), wire.topic_command("A"), payload)
    return refused.value.reason


def unit(rejected=0, last_reject=None, cseq=-1):
    return SimpleNamespace(rejected=rejected, last_reject=last_reject, cseq=cseq)


def test_a_flood_of_refused_commands_is_one_line_with_its_count_and_the_fix_for_a_wrong_key(caplog):
    train = SimpleNamespace(train_id="A", obu=unit())
    notes = BoardNotes([train], "keys file k.json")
    caplog.set_level(logging.WARNING, "cbtc.trains")
    notes.check(0.0)
    for k in range(1, 200):   # 1200 stale commands in 0.2 s, then a wrong key: one line each 10 s
        train.obu.rejected += 6
        train.obu.cseq = k
        train.obu.last_reject = "stale command: based on report 7, 900 ms old (limit 500 ms)"
        notes.check(k * 0.1)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2, lines
    assert lines[0].startswith("train A: refused 6 commands since its last line; the newest: stale command")
    assert "refused 600 commands" in lines[1]
    caplog.clear()
    train.obu.rejected += 3
    train.obu.last_reject = wrong_key_reason()   # what the board keeps of a command sealed with another key
    notes.check(30.0)
    (line,) = [r.getMessage() for r in caplog.records]
    assert "refused 591 commands" in line and "key (from keys file k.json) is not the zone's" in line


def test_a_zone_that_answers_nothing_is_said_every_10_s_and_a_reboot_starts_the_counts_again(caplog):
    train = SimpleNamespace(train_id="B", obu=unit())
    notes = BoardNotes([train], "--sim-seed 0")
    caplog.set_level(logging.WARNING, "cbtc.trains")
    for k in range(0, 251):
        notes.check(k * 0.1)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 2 and "no command taken for 10 s" in lines[0] and "for 20 s" in lines[1]
    assert "--sim-seed 0" in lines[1]
    caplog.clear()
    train.obu = unit(rejected=0, cseq=5)   # rebooted: a new unit, taking commands
    for k in range(251, 300):
        train.obu.cseq += 1
        notes.check(k * 0.1)
    assert not caplog.records
