"""The zone and the simulator on a track network: virtual trains running the board's own loop over their
itineraries, the zone's interlocking setting routes ahead of them and releasing behind, switch machines moving."""

import json

import pytest

from cbtc.authority.network_limit import network_limit
from cbtc.errors import ConfigError
from cbtc.layout_files import load_track
from cbtc.railway.itinerary import default_plans, itinerary
from cbtc.sim.recorder import violations
from cbtc.sim.runs import sim_config
from cbtc.sim.simulation import Simulation


def test_itineraries_of_the_passing_loop_use_both_platforms_and_come_round():
    network = load_track("lego_passing_loop")
    plans = default_plans(network, ("main", True), 2)
    assert plans == [("south_main", "north"), ("south_loop", "north")]
    loop = itinerary(network, ("main", True), plans[1])
    assert loop == (("main", True), ("W1.diverging", True), ("platform_loop", True), ("W2.diverging", False))
    assert network.graph.route(loop).closed


def test_a_plan_that_cannot_be_made_in_one_round_is_refused_naming_the_station():
    network = load_track("lego_passing_loop")
    with pytest.raises(ConfigError, match="station south_loop"):
        itinerary(network, ("main", True), ("south_main", "south_loop"))


def test_on_a_loop_the_nearest_switch_not_in_the_routes_leg_bounds_the_authority():
    network = load_track("lego_passing_loop")
    route = network.graph.route(itinerary(network, ("main", True), ("south_loop",)))
    head_s = route.starts_m[2] + 0.3    # on platform_loop: W2 is next, W1 (behind) comes round last
    limit = network_limit(route, head_s, "T1", {}, {"W1": "straight", "W2": None})
    assert "switch W2" in limit.reason
    assert limit.distance_m == pytest.approx(route.starts_m[3] - head_s)


def test_four_trains_run_the_passing_loop_safely_making_their_plans():
    sim = Simulation(sim_config("lego_passing_loop", 4, 0, 150.0))
    summary = sim.run().summary()
    assert summary["collisions"] == 0
    assert summary["authority_overruns"] == 0
    assert summary["switch_violations"] == 0
    assert summary["plan_completed"]
    assert all(t["station_stops"] >= 10 for t in summary["trains"])


@pytest.mark.parametrize("fault", ["switch_stall", "switch_detection_lost", "switch_wrong_leg"])
def test_a_switch_that_fails_as_trains_approach_ends_their_authority_before_it(fault):
    # W1 splits the main line into the two platforms: from 3 s on every move of it fails for 20 s
    config = sim_config("lego_passing_loop", 3, 1, 40.0, fault_texts=[f"{fault}:switch=W1,at_s=3,duration_s=20"])
    sim = Simulation(config)
    held_at_w1 = set()
    for t_s in range(1, 41):
        sim.scheduler.run_until(float(t_s))
        for train in sim.trains:
            why = sim.zc.state_of(train.train_id).limited_by or ""
            if "switch W1" in why:
                held_at_w1.add(train.train_id)
    summary = sim.recorder.summary()
    assert held_at_w1, "no train was ever limited by the failed switch"
    assert (summary["collisions"], summary["authority_overruns"], summary["switch_violations"]) == (0, 0, 0)
    assert summary["granted_beyond_m"] < 0.0


def test_a_detection_that_shows_a_leg_never_commanded_is_not_believed():
    sim = Simulation(sim_config("lego_passing_loop", 2, 0, 5.0))
    routes, train = sim.zc.network, sim.zc.state_of("T2")   # T2's itinerary runs W1 diverging
    w1_s = routes.frames["T2"].starts_m[1]
    t_s = 0.5
    while not (train.authority and routes.interlocking.switch_leg["W1"] == "diverging"):
        t_s += 0.1
        sim.scheduler.run_until(t_s)
    to_w1_m = w1_s - sim.trains[1].head_s
    assert 0.1 < to_w1_m < 2.0                                    # on its way to W1
    far = train.authority.cut_to(10.0, "a long authority")
    routes.detection = lambda now_s: {"W1": "diverging", "W2": "straight"}
    assert routes.clear_of(train, far, t_s).distance_m > 1.0     # commanded and detected diverging: through W1
    routes.interlocking.switch_leg["W1"] = "straight"              # as if the zone had commanded straight
    cut = routes.clear_of(train, far, t_s)
    assert cut.distance_m < to_w1_m and "switch W1" in cut.reason and "correspondence" in cut.reason


def test_faults_that_place_things_along_one_path_are_refused_on_a_network_and_switch_faults_on_a_path(capsys):
    from cbtc.cli import main
    assert main(["sim", "--layout", "lego_passing_loop", "--trains", "2", "--duration", "5",
                 "--fault", "unknown_board"]) == 2
    assert "not on the track network lego_passing_loop" in capsys.readouterr().err
    assert main(["sim", "--layout", "lego_oval", "--trains", "2", "--duration", "5", "--fault", "switch_stall"]) == 2
    assert "needs a track network" in capsys.readouterr().err


def test_a_campaign_runs_each_fault_class_on_the_layouts_it_runs_on():
    from cbtc.experiments import campaign
    specs = campaign.plan(60, list(campaign.CLASSES), campaign.LAYOUTS, campaign.FLEET_SIZES, 30.0, 0)
    for spec in specs:
        network = campaign.is_network(spec.layout)
        assert campaign.runs_on(spec.fault_class, spec.layout)
        assert not network or spec.trains <= campaign.NETWORK_FLEET
        names = {text.partition(":")[0] for text in spec.faults}
        assert not (names & set(campaign.faults.PATH_ONLY) if network else names & set(campaign.faults.SWITCH_FAULTS))
    switch_runs = [s for s in specs if s.fault_class.startswith("switch_")]
    assert switch_runs and all(campaign.is_network(s.layout) for s in switch_runs)
    with pytest.raises(ConfigError, match="switch_stall"):
        campaign.plan(3, ["switch_stall"], ("lego_oval",), (2,), 30.0, 0)


def test_a_fast_train_overtakes_a_slow_one_dwelling_in_the_passing_loop():
    from cbtc.sim.runs import scenario_config
    summary = Simulation(scenario_config("lego_passing_overtake", duration_s=120.0)).run().summary()
    fast, slow = summary["trains"]
    assert summary["overtakes"] >= 2 and fast["overtakes"] >= 2 and fast["distance_m"] > 1.5 * slow["distance_m"]
    assert (summary["collisions"], summary["authority_overruns"], summary["switch_violations"]) == (0, 0, 0)


def test_two_trains_converging_on_one_switch_take_turns_whichever_comes_first():
    from cbtc.sim.runs import scenario_config
    first = set()
    for seed in range(3):
        summary = Simulation(scenario_config("lego_merge_converging", seed=seed, duration_s=30.0)).run().summary()
        assert (summary["collisions"], summary["authority_overruns"], summary["switch_violations"]) == (0, 0, 0)
        a, b = summary["trains"]
        assert min(a["distance_m"], b["distance_m"]) > 1.0     # the second follows the first down the line
        first.add("A" if a["distance_m"] > b["distance_m"] else "B")
    assert first == {"A", "B"}


@pytest.mark.parametrize("train, message", [
    ({"id": "A", "start": "main"}, "a mapping of section, offset_m, forward"),
    ({"id": "A", "start": {"section": "mian", "offset_m": 1.0}}, "no section 'mian'"),
    ({"id": "A", "start": {"section": "main", "offset_m": 9.0}}, "past the end of section main"),
    ({"id": "A", "start": {"section": "main", "offset_m": 1.0}, "stops": ["south_main", "south_loop"]},
     "station south_loop"),
])
def test_a_network_scenario_names_a_bad_start_or_plan(train, message):
    from cbtc.scenario_files import scenario_from_dict
    with pytest.raises(ConfigError, match=message):
        scenario_from_dict({"layout": "lego_passing_loop", "trains": [train]}, "my.yaml")


def test_network_trains_that_overlap_at_the_start_are_refused():
    from cbtc.scenario_files import scenario_from_dict
    trains = [{"id": "A", "start": {"section": "main", "offset_m": 1.0}},
              {"id": "B", "start": {"section": "main", "offset_m": 1.2}}]
    with pytest.raises(ConfigError, match="trains A and B overlap at the start"):
        scenario_from_dict({"layout": "lego_passing_loop", "trains": trains}, "my.yaml")


def test_compare_on_the_passing_loop_runs_more_trains_under_moving_block_both_safe(capsys):
    from cbtc.cli import main
    assert main(["compare", "--layout", "lego_passing_loop", "--trains", "4", "--duration", "90", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    systems = result["systems"]
    for figures in systems.values():
        assert figures["collisions"] == figures["authority_overruns"] == figures["switch_violations"] == 0, figures
        assert figures["plan_completed"], figures
    assert systems["moving_block"]["trains_per_hour"] > 1.2 * systems["fixed_block"]["trains_per_hour"], systems
    assert result["trains_per_hour_gain_pct"] > 20.0


@pytest.mark.parametrize("argv, named", [
    (["compare", "--layout", "lego_passing_loop", "--laps", "2"], "--laps: not on a track network"),
    (["compare", "--layout", "lego_passing_loop", "--blocks", "3"], "--blocks: not on a track network"),
    (["compare", "--trains", "3"], "--trains: only for a track network"),
    (["compare", "--scenario", "lego_passing_overtake", "--trains", "3"], "--trains: the scenario"),
    (["sim", "--layout", "lego_passing_loop", "--policy", "fixed_block", "--blocks", "4"], "drop --start-gap and"),
    (["sim", "--layout", "lego_figure_eight", "--trains", "2", "--duration", "5", "--fault", "switch_stall"],
     "lego_figure_eight has no switch"),
])
def test_flags_that_do_not_apply_on_a_network_are_refused_in_one_line(capsys, argv, named):
    from cbtc.cli import main
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1 and "Traceback" not in err, err


def test_fixed_blocks_on_the_figure_eight_never_lock_a_ring_of_holds():
    # four trains on a ring of eight blocks that crosses itself: a train let onto the crossing with its exit block
    # taken would hold it against the trains it waits for; it waits at the crossing's signal instead
    summary = Simulation(sim_config("lego_figure_eight", 4, 0, 150.0, policy="fixed_block")).run().summary()
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert summary["plan_completed"] and summary["stranded"] == 0, summary["trains"]
    assert summary["emergency_trips"] <= 2


def test_a_broker_outage_on_a_network_is_ridden_out():
    config = sim_config("lego_passing_loop", 3, 4, 60.0, fault_texts=("broker_outage:at_s=20,duration_s=3",))
    summary = Simulation(config).run().summary()
    assert summary["collisions"] == summary["authority_overruns"] == summary["switch_violations"] == 0
    assert summary["plan_completed"]


@pytest.mark.parametrize("layout, seed, faults", [
    # a train's IPS 0.8 m off ahead puts its front-most head past a merge it has not reached
    ("lego_passing_loop", 660, ["ips_offset:at_s=19.5,duration_s=4.22,offset_m=0.795,train=T2"]),
    # a train whose odometer jumps back is located again with its head anywhere over nearly a metre
    ("lego_figure_eight", 703, ["odometer_jump:at_s=28.7,distance_m=-0.594,train=T1"]),
    ("lego_figure_eight", 573, ["link_duplicate:at_s=15.4,direction=both,duration_s=5.734,share=0.125,train=T3",
                                "controller_restart:at_s=20.7,duration_s=1.478"]),
])
def test_the_track_ahead_is_held_from_the_rear_most_plausible_head(layout, seed, faults):
    """Wherever between its rear-most and front-most plausible heads a train is, its authority covers only track
    held for it: a junction between the two is not skipped (campaign runs that collided when the held track was
    counted from the front-most head alone)."""
    summary = Simulation(sim_config(layout, 4, seed, 40.0, fault_texts=faults)).run().summary()
    assert violations(summary) == [] and summary["switch_violations"] == 0, summary
