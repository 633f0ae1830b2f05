"""Messages recorded by an adversary and sent again: none moves a train or the controller's picture of it.

Board side: a command recorded before the board restarted names another boot and is refused (also under the
MicroPython unix port: test_firmware_mpy). Controller side: a lower report sequence is taken only with a new boot id,
never after a silence, and a boot the train has left stays refused.
"""

import logging

import pytest

from cbtc.estimation.odometry_estimator import OdometryEstimator
from cbtc.layout_files import load_layout
from cbtc.protocol import wire
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import paper_scenario
from cbtc.zone.controller import ZoneController
from cbtc.zone.train_state import TrainSetup
from test_obu import CMD, Bench

KEY = b"0123456789abcdef"


@pytest.fixture
def square():
    return load_layout("itb_square")


def test_commands_recorded_before_a_reboot_are_refused_by_the_new_boot():
    before = Bench(boot_id=9)
    recorded = []
    for _ in range(6):
        before.step()
        recorded.append(before.command(eoa_mm=3000))
    assert before.unit.cseq == 6 and before.unit.rejected == 0
    after = Bench(boot_id=10)          # the same board restarted: reports count from 0 again, on a new clock
    for payload in recorded:           # each replayed when the report it names has just been sent again
        after.step()
        after.unit.on_message(CMD, payload, after.now_ms)
        assert "boot 9; this is boot 10" in after.unit.last_reject
    after.step()
    assert after.unit.cmd is None and after.unit.rejected == 6
    assert after.motor.mode == "brake" and after.unit.eoa_mm == 0


class _Bus:
    def __init__(self):
        self.sent = []

    def subscribe(self, topic, handler):
        pass

    def publish(self, topic, payload, retain=False):
        self.sent.append((topic, payload))


def _zone(now):
    zc = ZoneController(load_layout("itb_square"), [TrainSetup("A", KEY)], _Bus(), lambda: now[0], policy=None,
                        estimator_factory=OdometryEstimator)
    return zc


def _report(boot, seq, t_ms, odo_mm, csid=-1):
    return wire.encode_report(KEY, "A", boot, seq, t_ms, odo_mm, 0, 0, "idle", -1, csid, None, [], [])


def _stream(zc, now, boot, seqs, t0_ms=1000, answering=True):
    """Reports of `boot` for `seqs`, 50 ms apart on both clocks, each handed to `zc`; returns the payloads."""
    sent = []
    for seq in seqs:
        now[0] += 0.05
        sent.append(_report(boot, seq, t0_ms + 50 * seq, 10 * seq, zc.session_id if answering else -1))
        zc.on_report(wire.topic_report("A"), sent[-1])
    return sent


def test_an_old_report_after_a_silence_is_refused_and_a_new_boot_is_a_restart(caplog):
    now = [0.0]
    zc = _zone(now)
    topic = wire.topic_report("A")
    recorded = _stream(zc, now, 5, range(20))
    state = zc.state_of("A")
    assert state.boots.last_seq == 19 and state.reports_rejected == 0 and state.boots.answered
    now[0] += 9.0                                   # silent for 9 s: a replay is still a replay
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        for payload in recorded:
            zc.on_report(topic, payload)
    assert state.reports_rejected == 20 and state.boots.last_seq == 19 and state.restarts == 0
    assert state.report["odo_mm"] == 190
    zc.on_report(topic, _report(6, 0, 30, 0, zc.session_id))   # the board restarted: a new boot id
    assert state.restarts == 1 and state.boots.boot == 6 and state.report["odo_mm"] == 0
    for payload in recorded:                         # the boot it left stays refused
        zc.on_report(topic, payload)
    assert state.boots.boot == 6 and state.restarts == 1 and "has left" in state.last_reject


def test_reports_of_the_boot_a_board_restarted_from_are_refused_until_the_new_boot_answers():
    """The board restarts; its new boot is not located yet, so it has no command to answer. Reports recorded before
    the restart (they echo this controller's session) never take the train back to the old boot."""
    now = [0.0]
    zc = _zone(now)
    state = zc.state_of("A")
    recorded = _stream(zc, now, 5, range(20))
    _stream(zc, now, 6, range(3), t0_ms=0, answering=False)   # the restart: boot 6, not answering yet
    assert state.boots.boot == 6 and state.restarts == 1
    for payload in recorded[-5:]:
        zc.on_report(wire.topic_report("A"), payload)
    assert state.boots.boot == 6 and state.restarts == 1 and "the boot before the restart" in state.last_reject
    _stream(zc, now, 6, range(3, 6), t0_ms=0)             # it answers: the old boot is left for good
    assert state.boots.left == (5,)


def test_a_recorded_boot_never_takes_over_a_board_that_answers():
    now = [0.0]
    zc = _zone(now)
    state = zc.state_of("A")
    _stream(zc, now, 5, range(200), t0_ms=60000)       # the real board, up for a minute, answering
    ghost = [_report(3, seq, 4000 + 50 * seq, 0) for seq in range(10)]   # recorded in a boot never seen here
    for payload in ghost:
        zc.on_report(wire.topic_report("A"), payload)
        _stream(zc, now, 5, [state.boots.last_seq + 1], t0_ms=60000)
    assert state.boots.boot == 5 and state.restarts == 0 and "a replay, not a restart" in state.last_reject


def test_a_replay_that_took_over_an_unreachable_board_gives_it_back_and_holds_the_zone_meanwhile():
    now = [0.0]
    zc = _zone(now)
    state = zc.state_of("A")
    _stream(zc, now, 5, range(20))
    now[0] += 30.0                                     # the real board out of reach for 30 s
    _stream(zc, now, 3, range(5), t0_ms=2000, answering=False)   # a recorded boot: it never answers
    assert state.boots.boot == 3 and state.restarts == 1 and not state.boots.answered
    assert not zc._all_located(zc.located())           # no authority rests on it
    _stream(zc, now, 5, range(20, 25))                 # the real board is back: not locked out
    assert state.boots.boot == 5 and state.restarts == 2 and state.boots.answered
    _stream(zc, now, 3, range(5, 8), t0_ms=2000, answering=False)
    assert state.boots.boot == 5 and "a replay, not a restart" in state.last_reject


def test_no_train_gets_authority_while_another_does_not_answer(square, caplog):
    sim = Simulation(paper_scenario(square, seed=1, laps=None, duration_s=15.0))
    deaf = sim.trains[1]
    deaf.obu.on_message = lambda topic, payload, now_ms: None   # a board that never takes a command of ours
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        sim.run()
    assert not sim.zc.state_of(deaf.train_id).boots.answered
    said = [r.getMessage() for r in caplog.records if "have not answered" in r.getMessage()]
    assert len(said) == 1 and said[0].startswith(f"train {deaf.train_id}:") and "same key" in said[0]
    assert sim.trains[0].travelled_m < 0.01 and deaf.travelled_m < 0.01
    sim = Simulation(paper_scenario(square, seed=1, laps=None, duration_s=15.0))
    sim.run()
    assert sim.trains[0].travelled_m > 2.0             # the same run with both answering moves


def test_a_session_the_board_has_left_is_never_taken_again():
    bench = Bench()
    bench.step()
    old = [bench.command(sid=1, eoa_mm=3000)]
    bench.step()
    old.append(bench.command(sid=1, eoa_mm=3000))          # the old controller's last command, for the newest report
    bench.command(sid=2, seq=1, eoa_mm=300)                 # a restarted controller answering the same report waits
    assert bench.unit.sid == 1 and "not after session 1's report" in bench.unit.last_reject
    bench.step(ms=60)
    bench.command(sid=2, seq=2, eoa_mm=300)                 # for the next report
    assert bench.unit.sid == 2 and bench.unit.eoa_mm == 300
    for payload in old * 3:                                 # replays of the old session, alternating with the new
        bench.unit.on_message(CMD, payload, bench.now_ms)
        assert "session 1, which this board has left" in bench.unit.last_reject
        bench.command(sid=2, eoa_mm=300)
        assert bench.unit.sid == 2 and bench.unit.eoa_mm == 300
    assert bench.unit.rejected == 7


def test_a_new_session_must_rest_on_a_report_after_the_current_command():
    bench = Bench()
    bench.step()
    first = bench.last_report()["seq"]
    bench.step(ms=60)
    assert bench.last_report()["seq"] == first + 1
    bench.command(sid=1)
    bench.command(sid=3, seq=1, rseq=first)
    assert bench.unit.sid == 1 and "not after session 1's report" in bench.unit.last_reject
