"""Track the zone cannot vouch for is occupied: at its start and after a restart, until it is cleared (an operator, a
simulation from its truth) or a located train has swept it."""

import logging
from dataclasses import replace

import pytest

from cbtc.layout_files import load_layout
from cbtc.sim import faults
from cbtc.sim.recorder import violations
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import queue_scenario
from cbtc.zone.swept import SweptTrack


@pytest.fixture(scope="module")
def loop():
    return load_layout("itb_square")


def test_cleared_stretches_merge_wrap_the_origin_and_say_how_far_ahead_is_vouched_for(loop):
    track = SweptTrack(loop)
    length_m = loop.length_m
    assert track.known_ahead_m(1.0) == 0.0 and not track.spans
    track.clear(length_m - 0.5, length_m + 1.0)            # over the origin
    assert track.spans == [(0.0, pytest.approx(1.0)), (pytest.approx(length_m - 0.5), length_m)]
    assert track.known_ahead_m(length_m - 0.2) == pytest.approx(1.2)
    assert track.known_ahead_m(0.5) == pytest.approx(0.5) and track.known_ahead_m(2.0) == 0.0
    track.clear(1.0, 3.0)                                   # touching: one stretch
    assert track.spans[0] == (0.0, pytest.approx(3.0)) and track.known_ahead_m(length_m - 0.5) == pytest.approx(3.5)
    track.clear(2.5, length_m - 0.5)
    assert track.complete and track.known_ahead_m(4.0) == float("inf")
    track = SweptTrack(loop)
    track.clear(2.0, 2.0 + length_m)                        # a loop's worth is all of it
    assert track.complete


def test_on_an_open_line_the_end_of_the_track_is_not_unknown():
    line = load_layout("straight_test")
    track = SweptTrack(line)
    track.clear(1.0, line.length_m + 5.0)
    assert track.spans == [(1.0, line.length_m)] and track.known_ahead_m(2.0) == float("inf")
    assert track.known_ahead_m(0.5) == 0.0 and not track.complete
    track.clear(-1.0, 1.0)
    assert track.complete


def _run(config, clear=None):
    sim = Simulation(config)
    if clear is not None:
        sim.zc.clear_track(clear(sim), by="the test")
    sim.run()
    return sim, sim.recorder.summary()


def test_with_nothing_cleared_no_train_moves_and_each_says_why(loop, caplog):
    with caplog.at_level(logging.WARNING, logger="cbtc"):
        sim, summary = _run(queue_scenario(loop, 3, seed=0, duration_s=8.0, clear_track="none"))
    said = caplog.records[0].getMessage()
    assert "the track is not cleared" in said and "--clear-track all" in said and len(said) < 200
    assert max(t.travelled_m for t in sim.trains) < 0.01 and not violations(summary)
    assert {st.limited_by for st in sim.zc.trains.values()} == {"track not swept or cleared ahead"}


def test_a_train_sweeps_the_track_its_body_passed_over_and_the_train_behind_may_then_run_there(loop):
    def all_but_under_t2(sim):   # 5 cm in the middle of T2's body: not cleared, only T2 can vouch for it
        t2 = sim.trains[1]
        middle_s = t2.head_s - 0.5 * t2.length_m
        return [(middle_s + 0.025, middle_s - 0.025 + loop.length_m)]
    sim, summary = _run(queue_scenario(loop, 3, seed=0, duration_s=30.0, clear_track="none"), all_but_under_t2)
    assert sim.zc.swept.complete and not violations(summary)
    assert min(t.travelled_m for t in sim.trains) > 2.0     # T1 ran on over the place T2 stood on


@pytest.mark.parametrize("fault", ["unseen_train:train=T2,at_s=10,distance_m=1.0",
                                   "unseen_train:train=T1,at_s=6,duration_s=1,distance_m=2.5"])
def test_a_train_put_down_while_the_zone_is_down_is_never_run_into(loop, fault):
    """The restarted zone is told the track is clear but where truth has a vehicle that is none of its trains: the
    unseen train's place stays unknown, so occupied. An operator who clears the whole track without looking has the
    trains run into it."""
    config = queue_scenario(loop, 3, seed=0, duration_s=40.0, faults=(faults.parse(fault),))
    sim, summary = _run(config)
    assert sim.strays and not violations(summary), summary
    careless = Simulation(config)
    careless._clear_track = lambda: careless.zc.clear_track(None, by="a careless operator")
    careless.run()
    assert careless.recorder.summary()["collisions"] > 0


def test_a_zone_restarted_after_a_car_came_off_keeps_the_car_s_place_occupied(loop):
    """No train line, no tail beacon: the car's place is known to truth alone, and a restarted zone is told it is
    not clear."""
    config = queue_scenario(loop, 3, seed=0, duration_s=40.0,
                            faults=(faults.parse("car_dropped:train=T2,at_s=5,length_m=0.12"),
                                    faults.parse("controller_restart:at_s=6,duration_s=1")))
    config = replace(config, trains=[replace(spec, profile=spec.profile.with_changes(tail_beacon=0, integrity_loop=0))
                                     for spec in config.trains])
    sim, summary = _run(config)
    car = sim.strays[0]
    assert sim.zc.swept.known_ahead_m(car.tail_s - 0.001) < 0.01 and not violations(summary), summary
