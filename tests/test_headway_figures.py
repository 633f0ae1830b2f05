"""The time headway `cbtc compare` reports: at points every 5 cm, the time between the train ahead's head and the
follower's head passing them, averaged; checked on motions whose headway is known in closed form."""

from types import SimpleNamespace

import numpy as np
import pytest

from cbtc.experiments.headway import mean_headway_s
from cbtc.layout_files import load_layout


def recorder(layout, starts_m, travels, t_s):
    trains = [SimpleNamespace(s0_m=s0) for s0 in starts_m]
    return SimpleNamespace(layout=layout, sim=SimpleNamespace(trains=trains), t_s=t_s, travelled_m=travels)


def test_trains_at_one_speed_are_their_head_to_head_distance_over_it_apart():
    layout = load_layout("sumo_square")
    t = np.arange(0.0, 30.0, 0.01)
    rec = recorder(layout, [1.0, 0.525], [0.5 * t, 0.5 * t], t)
    assert mean_headway_s(rec, 1) == pytest.approx(0.475 / 0.5, abs=0.011)
    # the train ahead of A is B, round the loop: 5.0 - 0.475 m ahead
    assert mean_headway_s(rec, 0) == pytest.approx((5.0 - 0.475) / 0.5, abs=0.011)


def test_a_stop_behind_counts_where_the_follower_passes_after_it():
    """B stands 2 s at 2.0 m of its travel: every point after that sees it 2 s later; the points before do not."""
    layout = load_layout("sumo_square")
    t = np.arange(0.0, 40.0, 0.01)
    b = np.where(t < 4.0, 0.5 * t, np.where(t < 6.0, 2.0, 0.5 * (t - 2.0)))
    rec = recorder(layout, [1.0, 0.525], [0.5 * t, b], t)
    end_m = min(b[-1], 0.5 * t[-1] + 0.475)
    points = np.arange(0.475 + 0.05, end_m, 0.05)
    expected = 0.95 + 2.0 * np.mean(points > 2.0 + 1e-9)
    assert mean_headway_s(rec, 1) == pytest.approx(expected, abs=0.02)


def test_no_headway_on_an_open_line_or_alone():
    t = np.arange(0.0, 5.0, 0.01)
    assert mean_headway_s(recorder(load_layout("straight_test"), [1.0, 0.5], [0.1 * t, 0.1 * t], t), 1) is None
    assert mean_headway_s(recorder(load_layout("sumo_square"), [1.0], [0.1 * t], t), 0) is None


def test_the_minimum_leg_accelerates_cruises_and_brakes_or_turns_at_its_peak():
    from cbtc.experiments.headway import minimum_leg_s
    from cbtc.railway.train_profile import TrainProfile
    p = TrainProfile(v_max_mps=0.5, accel_max_mps2=0.5, beta_s_mps2=1.0, beta_e_mps2=1.5)
    # 0.25 m to reach line speed, 0.125 m to stop from it: 1.0 s + 0.5 s, the rest at 0.5 m/s
    assert minimum_leg_s(1.375, p) == pytest.approx(1.0 + 0.5 + 1.0 / 0.5)
    # too short to reach line speed: a triangle whose ramps meet at the peak speed
    peak = (2 * 0.12 * 0.5 * 1.0 / 1.5) ** 0.5
    assert minimum_leg_s(0.12, p) == pytest.approx(peak / 0.5 + peak / 1.0)


def test_the_least_headway_is_sumos_on_its_case_and_ours_keeps_it_for_one_profile_and_fixed_dwells():
    """SUMO's moving block heads its trains 3.80 s apart on its case: the least the profile allows (2 s dwell, 1.3 s
    for the leader to run its 0.3 m and the 0.1 m margin from standing, 0.5 s for the follower to brake from
    0.5 m/s); `cbtc compare` prints it for scenarios of one profile and fixed dwells at every station."""
    from cbtc.commands.compare import _least_headway
    from cbtc.experiments.headway import least_headway_s
    from cbtc.railway.train_profile import TrainProfile
    from cbtc.scenario_files import load_scenario
    from cbtc.zone.config import paper_scenario
    sumo = TrainProfile(length_m=0.30, v_max_mps=0.5, accel_max_mps2=0.5, beta_s_mps2=1.0, beta_e_mps2=1.5)
    assert least_headway_s(sumo, 0.10, 2.0) == pytest.approx(3.80)
    # clearing within the ramp to line speed: sqrt(2 d / a)
    assert least_headway_s(sumo.with_changes(length_m=0.05), 0.10, 2.0) == pytest.approx(2.0 + 0.6 ** 0.5 + 0.5)
    assert _least_headway(load_scenario("sumo_case")) == pytest.approx(3.80)
    assert _least_headway(paper_scenario(load_layout("itb_square"))) is None   # dwells drawn from 1-3 s


@pytest.mark.parametrize("layout_name, profile", [
    ("itb_square", {}),
    ("sumo_square", {"v_max_mps": 0.5, "accel_max_mps2": 0.5, "beta_s_mps2": 1.0, "beta_e_mps2": 1.5}),
])
def test_a_train_alone_laps_within_3_percent_of_its_minimum_and_stops_on_the_mark(layout_name, profile):
    """Line speed reached in truth (the speed loop runs on the odometer at the wheel's learnt scale), stops braked
    onto the mark and held there through the dwell (no creeping up to it, no nudges when the estimate moves)."""
    from cbtc.experiments.headway import lone_lap
    from cbtc.railway.train_profile import TrainProfile
    alone = lone_lap(load_layout(layout_name), TrainProfile(**profile), dwell_s=2.0, seed=0, laps=3)
    assert alone["laps"] >= 2 and alone["collisions"] == 0 and alone["authority_overruns"] == 0
    assert 1.0 < alone["lap_over_minimum"] <= 1.03, alone
    line = alone["line_speed_mps"]
    assert 0.99 * line <= alone["top_speed_mps"] <= 1.002 * line, alone
    assert alone["stop_error_max_mm"] <= 10.0 and alone["stops_with_creep"] == 0, alone
