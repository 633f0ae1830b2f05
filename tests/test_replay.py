"""Messages recorded by an adversary and sent again: none moves a train or the controller's picture of it.

Board side: a command recorded before the board restarted names another boot and is refused (also under the
MicroPython unix port: test_firmware_mpy). Controller side: a lower report sequence is taken only with a new boot id,
never after a silence, and a boot the train has left stays refused.
"""

import logging

from cbtc.estimation.odometry_estimator import OdometryEstimator
from cbtc.layout_files import load_layout
from cbtc.protocol import wire
from cbtc.zone.controller import TrainSetup, ZoneController
from test_obu import CMD, Bench

KEY = b"0123456789abcdef"


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


def _report(boot, seq, t_ms, odo_mm):
    return wire.encode_report(KEY, "A", boot, seq, t_ms, odo_mm, 0, 0, "idle", -1, None, [], [])


def test_an_old_report_after_a_silence_is_refused_and_a_new_boot_is_a_restart(caplog):
    now = [0.0]
    zc = _zone(now)
    topic = wire.topic_report("A")
    recorded = []
    for seq in range(20):
        now[0] = seq * 0.05
        recorded.append(_report(5, seq, 1000 + 50 * seq, 10 * seq))
        zc.on_report(topic, recorded[-1])
    state = zc.trains["A"]
    assert state.last_report_seq == 19 and state.reports_rejected == 0
    now[0] = 10.0                                   # silent for 9 s: a replay is still a replay
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        for payload in recorded:
            zc.on_report(topic, payload)
    assert state.reports_rejected == 20 and state.last_report_seq == 19 and state.restarts == 0
    assert state.report["odo_mm"] == 190
    zc.on_report(topic, _report(6, 0, 30, 0))       # the board restarted: a new boot id
    assert state.restarts == 1 and state.boot == 6 and state.report["odo_mm"] == 0
    for payload in recorded:                         # the boot it left stays refused
        zc.on_report(topic, payload)
    assert state.boot == 6 and state.restarts == 1 and "has left" in state.last_reject


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
