"""One train's reports, however extreme, never stop the zone nor touch another train: every field in range and sealed
with the train's own key, at the limits the wire allows; then the zone still governs both trains, in truth."""

import logging
import math
import random

import pytest

from cbtc.layout_files import load_layout
from cbtc.protocol import wire, wire_zc
from cbtc.sim.simulation import Simulation
from cbtc.zone import plausibility
from cbtc.zone.config import paper_scenario

INT31 = 2 ** 31 - 1
W = wire.WRAP_MASK


def extreme(rng, lo, hi, near=None):
    values = [lo, hi, 0, 1, -1, hi // 2, lo // 2]
    if near is not None:
        values += [near, near + 1, near - 1, near + 2 ** 29 - 1, near - 2 ** 29, near + 1000000, near + 40]
    return max(lo, min(hi, rng.choice(values)))


def extreme_report(rng, zc, key):
    """A sealed report of train A with every field in range, most at an extreme, near its newest accepted one."""
    base = zc.state_of("A").report or {}
    t = base.get("t_ms", 0)
    odo = base.get("odo_mm")
    fields = dict(
        boot=base.get("boot", 1),   # another boot with the key is a restart of the board: tests/test_replay.py
        seq=(base.get("seq", 0) + rng.choice([1, 1, 1, 2, 1000, 2 ** 29])) & W,
        t_ms=extreme(rng, 0, W, t) & W, odo_mm=extreme(rng, -INT31, INT31, odo), v_mmps=extreme(rng, -20000, 20000),
        duty_pct=extreme(rng, -100, 100), mode=rng.choice(wire_zc.MODES), cseq=extreme(rng, -1, W),
        csid=rng.choice([zc.session_id, -1, extreme(rng, -1, INT31)]),
        ips=rng.choice([None, [extreme(rng, 0, W, t) & W, extreme(rng, -10 ** 6, 10 ** 6),
                               extreme(rng, -10 ** 6, 10 ** 6)]]),
        tags=rng.choice([[], [["04A1B2C3", extreme(rng, -INT31, INT31, odo), extreme(rng, 0, W, t) & W,
                               extreme(rng, 0, wire_zc.SPAN_MAX_MS)]]]),
        faults=rng.choice([[], [], ["enc_fail"]]),
        rng=rng.choice([None, [extreme(rng, 0, W, t) & W, extreme(rng, -100000, 10 ** 6)]]))
    return wire.encode_report(key, "A", **fields)


def finite_picture(zc):
    for state in zc.trains.values():
        assert state.estimator.healthy(), state.train_id
        est = state.estimator.estimate(zc.now_fn()) if state.estimator.localized else None
        assert est is None or (math.isfinite(est.s_m) and math.isfinite(est.sigma_s_m)), state.train_id


def test_extreme_reports_of_one_train_never_escape_nor_poison_the_zone(caplog):
    sim = Simulation(paper_scenario(load_layout("itb_square"), seed=0, laps=50, duration_s=60))
    sim.scheduler.run_until(10.0)
    zc = sim.zc
    rng = random.Random(5)
    key = sim.trains[0]._key
    travelled_b = sim.trains[1].travelled_m
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        for n in range(1500):
            zc.on_report(wire.topic_report("A"), extreme_report(rng, zc, key))   # raises nothing, or the test fails
            if n % 50 == 0:
                sim.scheduler.run_until(sim.scheduler.now_s() + 0.1)
                finite_picture(zc)
    finite_picture(zc)
    state = zc.state_of("A")
    assert state.reports_rejected > 300 and state.odometer_jumps + state.failures + state.encoder_failures > 0
    assert len(caplog.records) < 200 and all(len(r.getMessage()) <= 200 for r in caplog.records)
    # the real boards go on: both trains are located again and run, with no collision and no overrun
    sim.scheduler.run_until(32.0)
    travelled_32 = [t.travelled_m for t in sim.trains]
    sim.scheduler.run_until(40.0)
    finite_picture(zc)
    summary = sim.recorder.summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    assert all(zc.state_of(t).estimator.localized for t in ("A", "B"))
    assert sim.trains[1].travelled_m > travelled_b + 2.0
    assert all(t.travelled_m > before + 1.0 for t, before in zip(sim.trains, travelled_32)), "both run on"


@pytest.mark.parametrize("change, refused", [
    ({"t_ms": 5000}, "ran back"),
    ({"t_ms": 200000 + 400000}, "ran 400.0 s ahead"),
    ({"seq": 5000}, "skips"),
])
def test_a_board_clock_and_sequence_move_no_faster_than_time(change, refused):
    previous = {"t_ms": 200000, "seq": 100, "odo_mm": 0}
    report = dict(previous, t_ms=200050, seq=101)
    assert plausibility.time_refusal(report, previous, 10.05, 10.0) == ""
    assert refused in plausibility.time_refusal(dict(report, **change), previous, 10.05, 10.0)


def test_stamps_outside_their_report_are_dropped_and_odometer_jumps_measured():
    report = {"t_ms": 10000, "odo_mm": 1000, "ips": [9990, 1, 2], "tags": [["04A1B2C3", 990, 9980, 8]], "rng": None}
    assert plausibility.plausible_parts(report, 980) == (report, 0)
    bad = dict(report, ips=[10010, 1, 2], tags=[["04A1B2C3", 5000, 9980, 8], ["04A1B2C4", 990, 2000, 8]], rng=[3, 100])
    kept, dropped = plausibility.plausible_parts(bad, 980)
    assert dropped == 4 and kept["ips"] is None and kept["tags"] == [] and kept["rng"] is None
    assert plausibility.odometer_jump_mm({"t_ms": 10050, "odo_mm": 1060}, {"t_ms": 10000, "odo_mm": 1000}, 0.75) == 0
    assert plausibility.odometer_jump_mm({"t_ms": 10050, "odo_mm": 1300}, {"t_ms": 10000, "odo_mm": 1000}, 0.75) == 175


def test_the_zones_order_of_trains_is_always_what_sorting_them_afresh_gives():
    """The zone keeps its located trains in position order as an index, placing again only the trains with news, and
    which trains answer it and whose data is oldest as a set and a heap:
    through a run with a controller restart, a board's reboot, an encoder burst (the train is located afresh) and lost
    reports, at every tick it equals the order a full sort of every train's position gives."""
    from cbtc.sim.runs import sim_config

    config = sim_config(load_layout("lego_oval"), 5, seed=3, duration_s=40.0,
                        fault_texts=["encoder_burst:train=T2,at_s=8", "link_loss:train=T4,at_s=12,duration_s=3",
                                     "reboot:train=T1,at_s=18",
                                     "controller_restart:at_s=25,duration_s=2"])
    sim = Simulation(config)
    checked = []

    def check(_now_s):
        zc = sim.zc
        located = zc.located()
        found = [(zc._position_m(st), st.rank, st) for st in zc.trains.values()
                 if st.report is not None and st.estimator.localized]
        assert located == [st for _s, _r, st in sorted((f for f in found if f[0] is not None),
                                                         key=lambda f: (f[0], f[1]))]
        # the answered set and the heap of receive times against their definitions over every train
        assert zc._all_located(located) == (len(located) == len(zc.trains)
                                            and all(st.boots.answered for st in located))
        for st in zc.trains.values():
            assert zc.ages.other_stale(st, _now_s, zc.params.max_leader_age_s) == any(
                other is not st and (other.report_recv_s is None
                                     or _now_s - other.report_recv_s > zc.params.max_leader_age_s)
                for other in zc.trains.values())
        checked.append(len(located))

    sim.scheduler.call_every(0.05, check, start_s=0.0107)
    summary = sim.run().summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    assert len(checked) > 700 and max(checked) == 5 and min(checked) < 5   # located afresh at times
