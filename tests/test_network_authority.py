"""Moving block on a track network, in pure code: the limit of authority along the route the interlocking holds
(trains ahead and converging, switches not detected in the route's leg, the route's end), and model trains run under
it and the interlocking over the shipped networks: converging on one switch with both moving (SUMO's merge case),
circulating round the passing loop, with truth checked every step (no two trains on one piece of track, no train on
track its routes do not hold)."""

import math
from functools import partial

import pytest

from cbtc.authority.network_limit import fixed_block_limit, network_limit
from cbtc.layout_files import load_track
from cbtc.railway.interlocking import Interlocking, find_routes
from cbtc.railway.network_layout import BLOCK_M, section_blocks
from cbtc.sim.switch_machines import SWITCH_FAULTS, SwitchMachine
from network_model import RunningTrain, collisions, truth_spans, world_now

DT_S, V_MAX_MPS, ACCEL_MPS2, BRAKE_MPS2, MARGIN_M, SIGMA_M = 0.05, 0.3, 0.5, 0.4, 0.05, 0.02


def test_the_limit_names_what_bounds_it():
    g = load_track("lego_passing_loop").graph
    route = g.route([("platform_loop", True), ("W2.diverging", False), ("main", True)])
    spans = {"B": (("W2.straight", 0.0, 0.1), ("main", 0.0, 0.2))}   # a train on the other leg of W2, leaving it
    limit = network_limit(route, 0.3, "A", spans, {"W2": "diverging"})
    assert limit.distance_m == pytest.approx(0.7633 - 0.3, abs=1e-4) and "train B" in limit.reason
    limit = network_limit(route, 0.3, "A", {}, {"W2": None})
    assert limit.distance_m == pytest.approx(0.7633 - 0.3, abs=1e-4) and "W2" in limit.reason and "lost" in limit.reason
    limit = network_limit(route, 0.3, "A", {}, {"W2": "straight"})
    assert "detected straight" in limit.reason
    limit = network_limit(route, 0.3, "A", {}, {"W2": "diverging"})
    assert limit.distance_m == pytest.approx(route.length_m - 0.3) and "end of the route" in limit.reason


def test_what_lies_between_the_rear_most_and_front_most_plausible_heads_bounds_the_limit_at_zero():
    g = load_track("lego_passing_loop").graph
    route = g.route([("platform_loop", True), ("W2.diverging", False), ("main", True)])
    head_s = route.starts_m[2] + 0.1   # the front-most head past W2, the rear-most 0.5 m behind it, short of W2
    limit = network_limit(route, head_s, "A", {}, {"W2": None}, reach_m=0.5)
    assert limit.distance_m == 0.0 and "W2" in limit.reason
    assert network_limit(route, head_s, "A", {}, {"W2": None}).distance_m > 0.0   # from the front-most head alone
    spans = {"B": (("W2.diverging", 0.05, 0.1),)}   # a train between the two heads
    limit = network_limit(route, head_s, "A", spans, {"W2": "diverging"}, reach_m=0.5)
    assert limit.distance_m == 0.0 and "train B" in limit.reason
    assert network_limit(route, head_s, "A", spans, {"W2": "diverging"}).distance_m > 0.0
    limit = network_limit(route, head_s, "A", {}, {"W2": "diverging"}, reach_m=0.5)
    assert limit.distance_m == pytest.approx(route.length_m - head_s)   # nothing between: the end, from the front


def run(layout_name, placements, plans, seconds, faults=None, following=True, v_max=None, limit=network_limit):
    """Model trains under the interlocking and the network limit for `seconds`, switches thrown by simulated
    machines (`faults`: switch -> (fault, at_s)); returns the counts and each train's last state."""
    graph = load_track(layout_name).graph
    limit_of = limit
    ixl = Interlocking(graph, following=following)
    machines = {w: SwitchMachine(w) for w in graph.switches}
    for w, (fault, at_s) in (faults or {}).items():
        machines[w].fault, machines[w].fault_at_s = fault, at_s
    trains = {t: RunningTrain(graph, step, head_m, 0.25, SIGMA_M) for t, (step, head_m) in placements.items()}
    target = {t: 0 for t in trains}
    v = {t: 0.0 for t in trains}
    stats = {"collisions": [], "overruns": [], "arrivals": {t: 0 for t in trains}, "reasons": set(),
             "switch_violations": [], "trains": trains, "v": v}
    for t, tr in trains.items():          # each train placed holds the section it stands on
        assert ixl.set_route(f"{t}0", t, (tr.steps[-1],), {}, 0.0).ok
    count, waiting_since = 0, {}
    for tick in range(int(seconds / DT_S)):
        now_s = tick * DT_S
        detected, physical, spans = world_now(machines, trains, now_s)
        ixl.release_behind(spans)
        for t in sorted(trains, key=lambda t: waiting_since.setdefault(t, tick)):   # first come, first served
            tr = trains[t]
            goal = plans[t][target[t] % len(plans[t])]
            if tr.steps[-1][0] == goal:
                target[t] += 1
                stats["arrivals"][t] += 1
                goal = plans[t][target[t] % len(plans[t])]
            held = ixl.held_by(t)
            if not held or held[-1][0] != goal:
                start = held[-1] if held else tr.steps[-1]
                for steps in find_routes(graph, start, goal):
                    count += 1
                    out = ixl.set_route(f"R{count}", t, steps, spans, now_s)
                    if out.ok:
                        for w, leg in out.moves:
                            machines[w].command(leg, now_s)
                        waiting_since.pop(t)
                        break
        for t, tr in trains.items():
            held = list(ixl.held_by(t))
            if tr.steps[-1] not in held:
                stats["overruns"].append((tick, t, tr.steps[-1]))
                v[t] = 0.0
                continue
            k = held.index(tr.steps[-1])
            limit = limit_of(graph.route(held[k:]), tr.head_into_m() + SIGMA_M, t, spans, detected)
            stats["reasons"].add(limit.reason.split(":")[0].split(" of train")[0])
            allowed = math.sqrt(2.0 * BRAKE_MPS2 * max(limit.distance_m - MARGIN_M, 0.0))
            top = (v_max or {}).get(t, V_MAX_MPS)
            v[t] = max(min(v[t] + ACCEL_MPS2 * DT_S, top, allowed), v[t] - BRAKE_MPS2 * DT_S, 0.0)
            before = tr.steps[-1]
            tr.advance(v[t] * DT_S, physical)
            head = graph.sections[tr.steps[-1][0]]
            if tr.steps[-1] != before and head.switch and physical[head.switch] != head.leg:
                stats["switch_violations"].append((now_s, t, head.name, physical[head.switch]))
            if v[t] > 0 and not graph.next_steps(*tr.steps[-1], physical) and graph.next_steps(*tr.steps[-1]) and \
                    tr.head_into_m() >= graph.sections[tr.steps[-1][0]].length_m - 1e-9:
                stats["switch_violations"].append((now_s, t, "ran into a switch that is not set", tr.steps[-1]))
        stats["collisions"] += collisions(graph, truth_spans(trains, 0.0))
    return stats


def test_two_trains_converging_on_one_switch_both_moving():
    # SUMO's merge case: one train on the main platform and one in the loop, both running east for W2 and the
    # main line beyond it; the interlocking gives W2 to one, the other's authority ends at its heel until the first
    # has cleared the switch
    stats = run("lego_passing_loop", {"A": (("platform_main", True), 0.5), "B": (("platform_loop", True), 0.45)},
                {"A": ["main", "platform_main"], "B": ["main", "platform_loop"]}, 60.0)
    assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
    assert min(stats["arrivals"].values()) >= 2, stats["arrivals"]       # both went through W2, and came round
    # each waits at the end of its held route or for a switch still moving, and follows the other round the oval
    assert stats["reasons"] <= {"the end of the route the interlocking holds for it", "switch W1", "switch W2",
                                "the rear-most plausible tail"}


def test_the_limit_alone_keeps_converging_trains_apart(monkeypatch):
    # defence in depth: with the interlocking's conflict checks taken out (every route set, switches thrown at will),
    # the limit still stops each train at the other's tail and before a switch not in its route's leg
    monkeypatch.setattr(Interlocking, "routes_of_section", lambda self, section: [])
    monkeypatch.setattr(Interlocking, "switch_locks", lambda self, switch: [])
    stats = run("lego_passing_loop", {"A": (("platform_main", True), 0.5), "B": (("platform_loop", True), 0.45)},
                {"A": ["main", "platform_main"], "B": ["main", "platform_loop"]}, 60.0)
    assert stats["collisions"] == [] and stats["overruns"] == []
    assert {"the rear-most plausible tail", "switch W2"} <= stats["reasons"]


def test_two_trains_circulate_the_passing_loop_on_their_own_platforms():
    stats = run("lego_passing_loop", {"A": (("main", True), 1.0), "B": (("platform_loop", True), 0.4)},
                {"A": ["platform_main", "main"], "B": ["platform_loop", "main"]}, 120.0)
    assert stats["collisions"] == [] and stats["overruns"] == []
    assert min(stats["arrivals"].values()) >= 4, stats["arrivals"]


@pytest.mark.parametrize("fault", SWITCH_FAULTS)
@pytest.mark.parametrize("leg", ["straight", "diverging"])
def test_a_switch_failing_as_a_train_approaches_stops_it_before_the_switch(fault, leg):
    # A runs along main for W1 and the platform on `leg`; W1 fails 2 s in, with A about 0.5 m short of it
    platform = "platform_main" if leg == "straight" else "platform_loop"
    stats = run("lego_passing_loop", {"A": (("main", True), 2.8)}, {"A": [platform, "main"]}, 20.0,
                faults={"W1": (fault, 2.0 if fault != "switch_stall" else 0.0)})
    train = stats["trains"]["A"]
    assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
    if fault == "switch_stall" and leg == "straight":
        assert stats["arrivals"]["A"] >= 1        # W1 lay straight already: no move, nothing to stall
        return
    assert train.steps[-1] == ("main", True) and stats["v"]["A"] == 0.0     # stopped on main, short of W1
    short_m = train.graph.sections["main"].length_m - train.head_into_m()
    assert SIGMA_M < short_m < 0.2, short_m
    assert any(r.startswith("switch W1") for r in stats["reasons"])


def test_a_switch_that_moves_in_time_lets_the_train_through():
    stats = run("lego_passing_loop", {"A": (("main", True), 2.8)}, {"A": ["platform_loop", "main"]}, 30.0)
    assert stats["switch_violations"] == [] and stats["arrivals"]["A"] >= 2


def test_following_on_shared_track_beats_exclusive_sections():
    # two trains round the oval, one through each platform: under moving block a route may follow the train ahead
    # over track its route holds; with sections exclusive (blocks behind signals) each waits for the whole 3.8 m
    # main section to clear
    laps = {}
    for following in (True, False):
        stats = run("lego_passing_loop", {"A": (("main", True), 1.0), "B": (("platform_loop", True), 0.4)},
                    {"A": ["platform_main", "main"], "B": ["platform_loop", "main"]}, 120.0, following=following)
        assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
        laps[following] = sum(stats["arrivals"].values())
    assert laps[True] >= 1.4 * laps[False], laps


def test_two_trains_round_the_figure_eight_take_turns_at_the_crossing():
    stats = run("lego_figure_eight", {"A": (("east_loop", True), 1.0), "B": (("west_loop", True), 1.0)},
                {"A": ["west_loop", "east_loop"], "B": ["east_loop", "west_loop"]}, 90.0)
    assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
    assert min(stats["arrivals"].values()) >= 6, stats["arrivals"]


@pytest.mark.parametrize("seed", range(20))
def test_sumo_merge_case_two_trains_converging_on_one_switch(seed):
    # lego_merge: trains on both branches run east for the line beyond switch M, starting where and as fast as the
    # seed says; one passes M first, the other waits at M's heel and then follows it down the line to the buffer
    import random

    rng = random.Random(seed)
    placements = {"A": (("branch_a", False), rng.uniform(0.5, 0.95)),
                  "B": (("branch_b", False), rng.uniform(0.5, 0.95))}
    speeds = {"A": rng.uniform(0.15, 0.3), "B": rng.uniform(0.15, 0.3)}
    stats = run("lego_merge", placements, {"A": ["line"], "B": ["line"]}, 40.0, v_max=speeds)
    assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
    trains = stats["trains"]
    assert all(tr.steps[-1][0] == "line" for tr in trains.values())            # both through M
    first, second = sorted(trains.values(), key=lambda tr: -tr.head_into_m())
    assert first.head_into_m() > 1.3 and second.head_into_m() < first.head_into_m() - 0.25   # one behind the other


def test_moving_block_runs_more_trains_round_the_loop_than_fixed_blocks():
    # two trains round the oval, one through each platform, routes following each other: under moving block each
    # runs up to the other's tail; under fixed blocks (a signal at every section's entry: at each switch's toe and
    # heels, none between: block_m longer than any section) it waits at the signal before any section the other is
    # in, on the 3.8 m main line too
    placements = {"A": (("main", True), 1.0), "B": (("platform_loop", True), 0.4)}
    plans = {"A": ["platform_main", "main"], "B": ["platform_loop", "main"]}
    laps = {}
    at_switches = partial(fixed_block_limit, block_m=4.0)
    for name, limit in (("moving", network_limit), ("fixed", at_switches)):
        stats = run("lego_passing_loop", placements, plans, 120.0, limit=limit)
        assert stats["collisions"] == [] and stats["overruns"] == [] and stats["switch_violations"] == []
        laps[name] = sum(stats["arrivals"].values())
        assert any(r.startswith("block") for r in stats["reasons"]) == (name == "fixed")
    assert laps["moving"] >= 1.4 * laps["fixed"], laps


def test_fixed_blocks_signal_plain_track_every_block_and_each_switch_leg_whole():
    graph = load_track("lego_passing_loop").graph
    main, leg = graph.sections["main"], graph.sections["W1.straight"]
    cuts = section_blocks(main)
    assert len(cuts) == 5 and cuts[0][0] == 0.0 and cuts[-1][1] == pytest.approx(main.length_m)
    assert all(hi - lo <= BLOCK_M for lo, hi in cuts) and section_blocks(leg) == ((0.0, leg.length_m),)
    route = graph.route([("main", True), ("W1.straight", True)])
    block_m = main.length_m / 5
    # B's tail in main's third block: A, in the first, waits at that block's signal (moving block: at B's tail)
    spans = {"B": (("main", 2.2 * block_m, 2.5 * block_m),)}
    fixed = fixed_block_limit(route, 0.3, "A", spans, {"W1": "straight"})
    assert fixed.distance_m == pytest.approx(2 * block_m - 0.3) and "block main.3" in fixed.reason
    moving = network_limit(route, 0.3, "A", spans, {"W1": "straight"})
    assert moving.distance_m == pytest.approx(2.2 * block_m - 0.3)
    # a train on the switch's other leg fouls the whole switch: A waits at the switch's toe
    spans = {"B": (("W1.diverging", 0.1, 0.2),)}
    fixed = fixed_block_limit(route, 0.3, "A", spans, {"W1": "straight"})
    assert fixed.distance_m == pytest.approx(main.length_m - 0.3)
