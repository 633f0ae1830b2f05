"""Open lines: the front train is limited by the end of the track, stops before it, and the trains behind follow;
stations past the last stop are not looked for behind the train."""

import pytest

from cbtc.layout_files import load_layout, path_layout_names
from cbtc.railway.layout_dict import layout_from_dict
from cbtc.sim.runs import sim_config
from cbtc.sim.simulation import Simulation


def _run(config):
    recorder = Simulation(config, keep_samples=True).run()
    return recorder, recorder.summary()


@pytest.mark.parametrize("policy,blocks", [("moving_block", None), ("fixed_block", 6)])
@pytest.mark.parametrize("n_trains", [2, 4, 6])
def test_trains_on_a_line_all_move_and_stop_before_its_end(policy, blocks, n_trains):
    layout = load_layout("straight_test")
    recorder, summary = _run(sim_config(layout, n_trains, seed=0, duration_s=20.0, policy=policy, blocks=blocks))
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0 and summary["stranded"] == 0
    assert summary["granted_beyond_m"] < 0.0   # no board held an end beyond the track's end or the train ahead
    # packed 0.15 m apart with two balises on the line, the rear ones gain what the bounds of their starts leave
    # (the declared start, 2 cm, and the wheel's reach since: a few cm)
    assert all(t["distance_m"] > 0.03 for t in summary["trains"])
    front_end_m = max(max(heads) for heads in recorder.head_s_m)
    assert front_end_m < layout.length_m - 0.05, "the front train stops its margin short of the end of the track"


def test_trains_on_a_line_stop_at_each_station_ahead_once():
    layout = layout_from_dict({"name": "branch", "closed": False, "segments": [{"straight": {"length_m": 4.0}}],
                               "stations": [{"name": "X", "s_m": 1.6}, {"name": "Y", "s_m": 3.2}],
                               "tags": [{"uid": f"0A0B0C{i:02d}", "s_m": 0.25 + 0.5 * i} for i in range(8)]})
    config = sim_config(layout, 2, seed=3, duration_s=40.0)
    sim = Simulation(config)
    sim.run()
    summary = sim.recorder.summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    front, rear = sim.zc.state_of("T2"), sim.zc.state_of("T1")
    assert front.dwells == 1 and rear.dwells == 2   # the front one starts past X; neither dwells at Y for ever
    assert front.stop_overruns == 0 and rear.stop_overruns == 0


@pytest.mark.parametrize("name", path_layout_names())
def test_every_shipped_layout_runs_two_and_six_trains_safely(name):
    for n_trains in (2, 6):
        _recorder, summary = _run(sim_config(name, n_trains, seed=1, duration_s=12.0))
        assert summary["collisions"] == 0 and summary["authority_overruns"] == 0, (name, n_trains)
        assert all(t["distance_m"] > 0.03 for t in summary["trains"]), (name, n_trains)
