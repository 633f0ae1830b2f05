"""A train's state as a value (cbtc.zone.handover): exported by one zone, taken over by another, which refuses the
replays the first refused, never extends the authority the board holds from stale data, and confirms the train's
position from the handed envelope instead of holding it at restricted speed until a balise."""

import json

import pytest

from cbtc.errors import ConfigError
from cbtc.sim.recorder import violations
from cbtc.sim.runs import sim_config
from cbtc.sim.simulation import Simulation
from cbtc.zone.handover import TrainRecord

HANDOVER_S = 12.0


def _run(hand_over):
    sim = Simulation(sim_config("lego_oval", 3, seed=4, duration_s=24.0))
    heard = []
    sim.broker.connect("spy").subscribe("cbtc/train/T1/report", lambda topic, payload: heard.append((topic, payload)))
    sim.scheduler.run_until(HANDOVER_S - 0.5)
    replay = heard[-1]   # a report of T1 the old zone took
    records = [sim.zc.export_train(t.train_id, sim.scheduler.now_s()) for t in sim.trains]
    sim.scheduler.run_until(HANDOVER_S)
    sim.restart_zone(hand_over=hand_over)
    sent = []
    sim.zc.commands.subscribe(sent.append)
    sim.scheduler.run_until(HANDOVER_S + 1.5)
    rejected = sim.zc.view(sim.scheduler.now_s()).train("T1").reports_rejected
    sim.zc.on_report(*replay)
    replay_refused = sim.zc.view(sim.scheduler.now_s()).train("T1").reports_rejected == rejected + 1
    recorder = sim.run()
    return sim, records, sent, replay_refused, recorder.summary()


def test_a_record_goes_through_json_and_back_unchanged_and_a_bad_one_is_named():
    sim = Simulation(sim_config("lego_oval", 2, seed=1, duration_s=6.0))
    sim.scheduler.run_until(5.0)
    record = sim.zc.export_train("T1", 5.0)
    assert record.s_m is not None and record.boot is not None and record.command is not None
    assert TrainRecord.from_dict(json.loads(json.dumps(record.as_dict()))) == record
    data = dict(record.as_dict(), speed=1)
    del data["boot"]
    with pytest.raises(ConfigError, match="missing: boot, unknown: speed"):
        TrainRecord.from_dict(data)
    with pytest.raises(ConfigError, match="train 'X' is not in this zone"):
        sim.zc.export_train("X", 5.0)


def test_the_zone_that_takes_the_trains_over_confirms_them_and_refuses_the_old_replays():
    sim, records, sent, replay_refused, summary = _run(hand_over=True)
    assert all(r.confirmed for r in records)
    assert replay_refused, "a report the old zone took is a replay to the new one"
    first = {}
    for command in sent:
        first.setdefault(command.train_id, command)
    assert set(first) == {"T1", "T2", "T3"} and all(c.confirmed for c in first.values()), first
    assert all(first[r.train_id].command.seq > r.cmd_seq for r in records)   # the sequence goes on
    assert violations(summary) == []


def test_without_the_records_a_new_zone_holds_the_trains_at_restricted_speed_until_a_balise():
    sim, _records, sent, _replay_refused, summary = _run(hand_over=False)
    first = {}
    for command in sent:
        first.setdefault(command.train_id, command)
    assert not any(c.confirmed for c in first.values())
    assert violations(summary) == []


def test_a_position_declared_while_the_train_runs_is_carried_on_by_its_odometer():
    """A handed-over train runs on between its first report to the new zone (where the declaration is made) and the
    balise read that places it: the declaration is carried by the odometer, its tolerance widened by the scale's
    doubt, or a read 5 cm on would disagree with it and the train would wait for a second reference."""
    from cbtc.estimation.estimate import declared_at
    assert declared_at((0.704, 0.047, 4.174), 4.234) == pytest.approx((0.764, 0.047 + 0.05 * 0.06))
    assert declared_at((0.704, 0.047, None), 9.0) == (0.704, 0.047)
