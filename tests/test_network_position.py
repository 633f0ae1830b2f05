"""A simulated train's true place on a track network: running on through switches as their blades lie, stopped by a
buffer stop, derailed by a switch moving or set against it, rolling back over the track behind, reversing."""

import pytest

from cbtc.layout_files import load_track
from cbtc.sim.network_position import NetworkPosition

STRAIGHT = {"W1": "straight", "W2": "straight"}


def _loop():
    return load_track("lego_passing_loop").graph


def test_runs_on_through_switches_as_their_blades_lie():
    g = _loop()
    train = NetworkPosition(g, ("main", True), 3.5, 0.25)
    assert train.advance(0.5, {"W1": "diverging", "W2": "straight"}) == pytest.approx(0.5)
    assert train.head == ("W1.diverging", pytest.approx(0.1974, abs=1e-4), True)
    span = train.span()
    assert span[0][0] == "main" and span[-1][0] == "W1.diverging"
    assert sum(hi - lo for _s, lo, hi in span) == pytest.approx(0.25)
    train.advance(2.0, {"W1": "diverging", "W2": "diverging"})     # round the loop and out onto main again
    loop_m = sum(g.sections[s].length_m for s in ("W1.diverging", "platform_loop", "W2.diverging"))
    assert train.head == ("main", pytest.approx(2.0 - (loop_m - 0.1974), abs=1e-4), True) and not train.derailed
    assert train.steps == [("main", True)]      # the history behind the tail's keep is let go


def test_a_moving_switch_or_one_set_against_a_trailing_move_derails_it():
    g = _loop()
    train = NetworkPosition(g, ("main", True), 3.5, 0.25)
    moved = train.advance(0.5, {"W1": None})
    assert moved == pytest.approx(g.sections["main"].length_m - 3.5)
    assert train.derailed == "ran into switch W1 not set for it" and train.advance(0.1, STRAIGHT) == 0.0
    trailing = NetworkPosition(g, ("platform_loop", True), 0.6, 0.25)
    trailing.advance(0.5, {"W2": "straight"})
    assert "switch W2" in trailing.derailed


def test_a_buffer_stop_stops_it_and_it_rolls_back_over_the_track_behind():
    g = load_track("lego_branch").graph
    train = NetworkPosition(g, ("east_line", True), 0.9, 0.25)
    train.advance(1.2, {"WB": "straight"})
    assert train.head == ("east_1", pytest.approx(0.640), True) and not train.derailed   # against the buffer
    train.advance(-1.5, {"WB": "straight", "W2": "straight"})
    assert train.head == ("east_line", pytest.approx(1.024 - (1.5 - 0.640 - 0.256)), True) and not train.derailed
    assert ("east_line", pytest.approx(1.024 - (1.5 - 0.640 - 0.256) - 0.25), pytest.approx(0.420)) in train.span()
    back = NetworkPosition(g, ("west_line", True), 0.3, 0.25)
    back.advance(-0.2, {"WA": "diverging"})
    assert back.steps[0] == ("WA.diverging", False) and not back.derailed
    # rolling back off a buffer stop's end: the tail stays at the stop
    stub = NetworkPosition(g, ("west_1", False), 0.3, 0.25)       # facing away from the buffer, 5 cm from it
    stub.advance(-0.2, {})
    assert stub.head_into_m() == pytest.approx(0.25) and not stub.derailed
    toward_wa = NetworkPosition(g, ("west_1", True), 0.4, 0.25)    # facing the buffer, rolling back to WA
    toward_wa.advance(-0.3, {})
    assert toward_wa.head == ("west_1", pytest.approx(0.1), True) and toward_wa.steps[0] == ("WA.straight", True)


def test_reversing_makes_the_tail_the_head():
    g = load_track("lego_branch").graph
    train = NetworkPosition(g, ("west_1", True), 0.4, 0.25)      # standing at the west terminus, facing the buffer
    train.reverse()
    assert train.head == ("west_1", pytest.approx(0.15), False)
    train.advance(0.4, {"WA": "straight"})
    assert train.steps[-1] == ("WA.straight", False) and train.head[1] == pytest.approx(0.256 - (0.4 - 0.15))


def test_truth_counts_a_collision_on_a_section_or_one_piece():
    from cbtc.sim.network_truth import collisions

    g = _loop()
    assert collisions(g, {"A": (("main", 0.5, 0.75),), "B": (("main", 0.76, 1.0),)}) == []
    assert collisions(g, {"A": (("main", 0.5, 0.75),), "B": (("main", 0.7, 1.0),)}) == [("A", "B", "main", "main")]
    # on the two legs of one switch: the piece is one, whoever moved
    assert collisions(g, {"A": (("W1.straight", 0.2, 0.256),), "B": (("W1.diverging", 0.25, 0.28),)}) == \
        [("A", "B", "W1.straight", "W1.diverging")]
    f8 = load_track("lego_figure_eight").graph
    assert collisions(f8, {"A": (("X.a", 0.0, 0.01),), "B": (("X.b", 0.12, 0.128),)}) == [("A", "B", "X.a", "X.b")]
