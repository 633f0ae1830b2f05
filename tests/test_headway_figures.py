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
