"""Trains that reverse: a line's itinerary cut into legs from buffer stop to buffer stop (cbtc.railway.legs), the
zone turning a train at the end of each (cbtc.zone.turns) and its board turning standing, in simulation on
lego_branch, judged by truth."""

import json
from math import hypot

from cbtc.cli import main as cbtc_main
from cbtc.layout_files import load_track
from cbtc.railway.legs import legs, turned_head_s
from cbtc.railway.network_layout import sensor_frame
from cbtc.sim.simulation import Simulation
from cbtc.zone.line_dispatch import LineDispatch
from cbtc.zone.network_config import network_queue


def branch_legs(plan=("middle_main", "east_1"), length_m=0.25):
    return legs(load_track("lego_branch"), ("west_line", True), plan, length_m, "T1")


def test_a_line_is_run_in_legs_from_buffer_stop_to_buffer_stop_the_way_back_by_the_other_loop_track():
    net = load_track("lego_branch")
    found = branch_legs()
    assert len(found) == 2 and [leg.backwards for leg in found] == [False, True]
    for leg in found:
        last, first = leg.route.steps[-1], leg.route.steps[0]
        assert not net.graph.next_steps(*last)                       # it ends at a buffer stop
        assert not net.graph.next_steps(first[0], not first[1])     # and begins at one
    out, back = ({s for s, _f in leg.route.steps} for leg in found)
    assert "middle_main" in out and "middle_loop" in back and "middle_main" not in back
    assert found[0].stops == ("middle_main", "east_1") and found[1].stops == ()
    assert [st.name for st in found[0].frame.stations] == ["middle_main", "east_1"] and not found[1].frame.stations


def test_a_turn_puts_the_head_where_the_tail_was():
    out, back = branch_legs()
    head_s = out.route.length_m - 0.1       # 10 cm short of the east buffer stop
    new_s = turned_head_s(out, back, head_s, 0.25)
    assert abs(new_s - 0.35) < 1e-9          # its tail was 35 cm from the buffer stop: the new head is there
    assert back.route.locate(new_s)[0] == out.route.locate(head_s - 0.25)[0] == "east_1"


def test_the_sensors_of_a_train_running_backwards_read_a_train_length_behind_its_head():
    _out, back = branch_legs()
    frame, shifted = back.frame, back.sensors
    assert shifted is not frame and sensor_frame(frame, 0.25).length_m == frame.length_m + 0.25
    for s_m in (0.5, 1.7, 3.2, frame.length_m):
        (x, y), (xs, ys) = frame.xy_m(s_m - 0.25), shifted.xy_m(s_m)
        assert hypot(x - xs, y - ys) < 1e-9
    assert [t.s_m + 0.25 for t in frame.tags] == [t.s_m for t in shifted.tags]


def _run(seconds, seed=0):
    sim = Simulation(network_queue(load_track("lego_branch"), 1, seed=seed, duration_s=seconds))
    worst = [0.0, 0]

    def watch(now_s):
        train, st = sim.trains[0], sim.zc.state_of("T1")
        est = st.estimator.estimate(now_s) if st.estimator.localized else None   # at the time truth is read
        if est is not None and train.leg == st.leg:
            worst[0] = max(worst[0], abs(est.s_m - (train.s0_m + train.travelled_m)) - 3.0 * est.sigma_s_m)
            if train.v_mps > 0.0 and not (train.obu.way == train.cab == (-1 if st.travel_dir else 1)):
                worst[1] += 1
    return sim, watch, worst


def test_a_train_shuttles_on_a_line_reversing_at_each_end_and_truth_finds_nothing():
    sim, watch, worst = _run(150.0)
    t = 0.0
    while t < 150.0:
        t += 0.5
        sim.scheduler.run_until(t)
        watch(t)
    summary = sim.recorder.summary()
    train = sim.trains[0]
    assert train.turns >= 6 and sim.zc.network.turns.count == train.turns
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert summary["plan_completed"] and summary["trains"][0]["station_stops"] >= 10
    assert train.obu.rejected == 0 and train.obu.trips == 0       # every turn taken standing, none refused
    assert worst[1] == 0   # wherever the zone and truth run the same leg, the board runs the way both say
    assert worst[0] <= 0.02, worst[0]                             # truth within the estimate's 3 sigma (2 cm spare)


def test_nothing_held_the_old_way_survives_a_turn():
    sim, _watch, _worst = _run(60.0)
    st, net = sim.zc.state_of("T1"), sim.zc.network
    seen = []
    t = 0.0
    while t < 60.0 and not seen:
        t += 0.02
        turns = net.turns.count
        sim.scheduler.run_until(t)
        if net.turns.count > turns:
            seen.append((st.estimator.localized, st.command, st.limited_by, dict(net.held["T1"]),
                         [r for r in net.interlocking.routes.values() if r.train == "T1"], st.travel_dir))
    assert seen, "no turn in 60 s"
    localized, command, why, held, routes, travel_dir = seen[0]
    assert not localized and travel_dir == 1
    assert command.v_mmps == 0 and command.dir == 1 and why == "held: T1 not located"   # held, told to turn
    assert not held and not routes                                 # its routes released...
    assert net.spans["T1"]                                         # ...its span still an obstacle to others


def test_cbtc_sim_runs_a_train_on_lego_branch(capsys):
    assert cbtc_main(["sim", "--layout", "lego_branch", "--trains", "1", "--duration", "60", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["collisions"] == 0 and summary["trains"][0]["station_stops"] >= 3


def test_two_trains_share_a_line_meeting_at_its_passing_loop_without_deadlock():
    sim = Simulation(network_queue(load_track("lego_branch"), 2, seed=0, duration_s=150.0))
    summary = sim.run().summary()
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert summary["plan_completed"] and not summary["stranded"]
    assert all(t.turns >= 4 and t.obu.rejected == 0 for t in sim.trains)


def test_a_run_to_a_place_to_wait_is_set_whole_or_not_at_all():
    """A run refused part way leaves no route of it locked and no switch commanded for it."""
    sim = Simulation(network_queue(load_track("lego_branch"), 2, seed=0, duration_s=5.0))
    sim.run()
    net = sim.zc.network
    for held in net.held.values():
        steps = sorted(held.values())
        assert not steps or steps == list(range(steps[0], steps[0] + len(steps)))   # held in one piece
    assert set(net.interlocking.routes) == {r for held in net.held.values() for r in held}


def _branch_dispatch():
    net = load_track("lego_branch")
    config = network_queue(net, 4)
    waits = frozenset(st.section for st in net.stations)
    return config, LineDispatch(net.graph, {t.train_id: t.legs for t in config.trains}, waits)


def test_four_trains_stand_on_the_four_terminus_tracks_and_shuttle_across_keeping_to_one_loop_track_each_way():
    config, dispatch = _branch_dispatch()
    assert [t.legs[0].route.steps[0][0] for t in config.trains] == ["west_1", "west_2", "east_1", "east_2"]
    assert [name for _k, _i, name in dispatch.places["T1"]] == ["middle_main", "east_1", "middle_loop", "west_1"]
    assert [name for _k, _i, name in dispatch.places["T3"]] == ["middle_loop", "west_1", "middle_main", "east_1"]


def test_the_dispatcher_holds_a_run_that_could_only_end_in_trains_facing_each_other():
    _config, dispatch = _branch_dispatch()
    assert "not yet seen" in dispatch.refusal("T1", "middle_main")
    dispatch.start({"T1": (0, 0, "west_1"), "T2": (0, 0, "west_2"), "T3": (0, 0, "east_1"), "T4": (0, 0, "east_2")})
    assert dispatch.refusal("T1", "middle_main") == ""
    assert "next place is middle_main" in dispatch.refusal("T1", "east_1")
    dispatch.moved("T1", "middle_main")
    # T1 on the loop bound for east_1, where T3 stands: T4 into the loop's other track would leave T3 no way out
    # (west_1 is free but T4 would block it) and T1 none in
    assert "dispatcher holds it" in dispatch.refusal("T4", "middle_loop")
    assert dispatch.refusal("T3", "middle_loop") == ""


def test_a_train_read_at_start_inside_its_place_may_run_on_to_its_stop_there():
    """A zone restarted while a train ran into its loop track counts it there; the run on to its stop within that
    track is its own (it was refused as not its next place, and the train stood short of its stop for good)."""
    _config, dispatch = _branch_dispatch()
    at_loop = next((k, i) for k, i, name in dispatch.places["T1"] if name == "middle_loop")
    dispatch.start({"T1": (*at_loop, "middle_loop"), "T2": (0, 0, "west_2"), "T3": (0, 0, "east_1"),
                    "T4": (0, 0, "east_2")})
    assert dispatch.refusal("T1", "middle_loop") == ""
    dispatch.moved("T1", "middle_loop")
    assert dispatch.at["T1"] == "middle_loop" and dispatch.places["T1"][dispatch.index["T1"]][2] == "west_1"
    assert "next place is west_1" in dispatch.refusal("T1", "middle_loop")   # once: it is there now


def test_four_trains_share_a_line_with_two_termini_and_a_passing_loop_without_deadlock():
    sim = Simulation(network_queue(load_track("lego_branch"), 4, seed=1, duration_s=150.0))
    summary = sim.run().summary()
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert summary["plan_completed"] and not summary["stranded"]
    assert all(t["station_stops"] >= 8 for t in summary["trains"]), summary["trains"]
    assert all(t.obu.rejected == 0 for t in sim.trains)


def test_a_scenario_file_gives_trains_on_a_line_plans_they_run_reversing():
    from cbtc.sim.runs import scenario_config
    config = scenario_config("lego_branch_shuttle", duration_s=60.0)
    assert all(spec.legs and len(spec.legs) == 2 for spec in config.trains)
    summary = Simulation(config).run().summary()
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert all(t["station_stops"] >= 3 for t in summary["trains"]), summary["trains"]


def test_a_plan_a_line_cannot_run_even_reversing_is_refused_naming_its_station():
    from cbtc.errors import ConfigError
    from cbtc.scenario_files import scenario_from_dict
    train = {"id": "A", "start": {"section": "west_1", "offset_m": 0.24, "forward": False}, "stops": ["nowhere"]}
    try:
        scenario_from_dict({"layout": "lego_branch", "trains": [train]}, "my.yaml")
    except ConfigError as exc:
        assert "nowhere" in str(exc) and "my.yaml" in str(exc)
    else:
        raise AssertionError("a plan naming no station of the line was taken")


def _line_run(fault, seed=868):
    from cbtc.sim.runs import sim_config
    sim = Simulation(sim_config("lego_branch", 4, seed, 60.0, fault_texts=(fault,)))
    return sim, sim.run().summary()


def test_a_restarted_zone_takes_each_trains_way_from_its_board_and_turns_none():
    """Found by the campaign: a new zone put every train on its first leg and told the boards running backwards to
    turn, and a train standing on the passing loop's westbound track was turned onto a leg that does not run it."""
    sim, summary = _line_run("controller_restart:at_s=26.6,duration_s=1.555")
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    for train in sim.trains:   # the zone's leg runs the way the virtual train's does
        assert sim.zc.trains[train.train_id].setup.legs[sim.zc.trains[train.train_id].leg].backwards == \
            (train.encoder.way < 0)


def test_a_board_that_restarts_on_a_backwards_leg_does_not_turn_its_train_off_the_plan():
    """A restarted board drives forward from boot; the train turns only once it is driven the other way (the sim
    turned it at the reboot, onto a leg that does not run the westbound loop track, and raised)."""
    sim, summary = _line_run("reboot:at_s=28.2,train=T1")
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    t1 = next(t for t in sim.trains if t.train_id == "T1")
    assert t1.legs[t1.leg].backwards   # it stands on its westbound leg still
