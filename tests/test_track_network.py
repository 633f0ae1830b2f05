"""Track networks: LEGO switch geometry, the shipped networks, routes along the graph, and validation errors that
name file, line and fix."""

import json
import math

import numpy as np
import pytest

from cbtc.cli import main as cbtc_main
from cbtc.errors import LayoutError
from cbtc.layout_files import load_layout, load_track
from cbtc.railway.geometry import Path
from cbtc.railway.network_dict import STUD_M, switch_legs
from cbtc.railway.track_graph import reversed_path

PASSING = open(load_track("lego_passing_loop").source, encoding="utf-8").read()
BRANCH = open(load_track("lego_branch").source, encoding="utf-8").read()


@pytest.mark.parametrize("hand", [1.0, -1.0])
def test_lego_switch_geometry(hand):
    legs = switch_legs(hand)
    straight = Path(legs["straight"])
    assert straight.end_pose == pytest.approx((32 * STUD_M, 0.0, 0.0))
    x, y, h = Path(legs["diverging"]).end_pose
    assert math.degrees(h) == pytest.approx(22.5 * hand)
    # with an R40 curve turned back the diverging leg runs parallel to the straight one, 16 studs to the side,
    # 48 studs on: one straight piece beyond the straight leg's heel
    back = Path(legs["diverging"] + [("arc", 40 * STUD_M, -hand * math.radians(22.5))])
    assert back.end_pose == pytest.approx((48 * STUD_M, hand * 16 * STUD_M, 0.0), abs=1e-12)


def test_shipped_networks_graphs():
    loop = load_track("lego_passing_loop")
    assert loop.is_network and set(loop.graph.switches) == {"W1", "W2"}
    assert {s.name for s in loop.graph.sections.values() if not s.switch} == {"main", "platform_main",
                                                                             "platform_loop"}
    # every node is a joint or a toe: no end left open on an oval
    assert all(node.side_b for node in loop.graph.nodes)
    assert [n for n in loop.graph.nodes if n.switch] and {n.switch for n in loop.graph.nodes} == {"", "W1", "W2"}
    branch = load_track("lego_branch")
    assert set(branch.graph.switches) == {"WA", "W1", "W2", "WB"}
    buffers = sorted(e for n in branch.graph.nodes if not n.side_b for e in n.side_a)
    assert buffers == [("east_1", "end"), ("east_2", "end"), ("west_1", "end"), ("west_2", "end")]


def test_switch_position_chooses_the_leg_and_trailing_moves_need_it_set():
    g = load_track("lego_passing_loop").graph
    assert set(g.next_steps("main", True)) == {("W1.straight", True), ("W1.diverging", True)}
    assert g.next_steps("main", True, {"W1": "diverging"}) == (("W1.diverging", True),)
    assert g.next_steps("W1.straight", False, {"W1": "straight"}) == (("main", False),)
    assert g.next_steps("W1.straight", False, {"W1": "diverging"}) == ()      # a run-through: nowhere to go
    assert g.next_steps("platform_main", True) == (("W2.straight", False),)


@pytest.mark.parametrize("via", ["straight", "diverging"])
def test_routes_round_the_passing_loop_are_closed_paths(via):
    layout = load_track("lego_passing_loop")
    g = layout.graph
    middle = "platform_main" if via == "straight" else "platform_loop"
    route = g.route([("main", True), (f"W1.{via}", True), (middle, True), (f"W2.{via}", False)])
    assert route.closed
    assert route.length_m == pytest.approx(sum(g.sections[n].length_m for n, _ in route.steps))
    path = route.path()
    assert path.closed and path.length_m == pytest.approx(route.length_m)
    for s in [0.0, 0.3, 1.7, route.length_m - 0.2, route.length_m - 0.01]:
        section, offset = route.locate(s)
        assert route.s_of(section, offset) == pytest.approx(s)
        assert math.dist(path.xy_m(s), route.xy_m(s)) < 1e-6
        assert math.dist(route.xy_m(s), layout.xy_m(section, offset)) < 1e-9
    with pytest.raises(ValueError, match="does not follow"):
        g.route([("main", True), ("platform_main", True)])


def test_reversed_path_runs_the_same_track_backwards():
    p = Path([("straight", 0.3), ("arc", 0.32, 0.5), ("arc", 0.32, -0.2)], 0.1, 0.2, 0.3)
    r = reversed_path(p)
    assert r.length_m == pytest.approx(p.length_m)
    for s in (0.0, 0.2, 0.41, p.length_m):
        assert r.xy_m(s) == pytest.approx(p.xy_m(p.length_m - s), abs=1e-12)


def test_a_path_layout_is_a_graph_of_one_section():
    oval = load_layout("lego_oval")
    assert not oval.is_network and list(oval.graph.sections) == ["main"]
    assert oval.graph.route([("main", True)]).closed
    line = load_layout("straight_test")
    assert not line.graph.route([("main", True)]).closed
    assert line.graph.next_steps("main", True) == ()
    assert oval.digest() == load_layout("lego_oval").digest()


def _error(tmp_path, text, name="net.yaml"):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(LayoutError) as info:
        load_track(str(path))
    return str(info.value), str(path)


def _line_of(text, fragment, nth=0):
    lines = [i + 1 for i, line in enumerate(text.splitlines()) if fragment in line]
    return lines[nth]


SPUR = ("  - section: spur\n    start: {x_m: 0.5, y_m: -0.3, heading_deg: 90}\n    segments:\n"
        "      - {piece: straight, count: 4}\nbuffers: [spur.start, spur.end]")
CASES = [
    # an end that should be joined: the loop one straight short of switch W2
    ("open end", lambda t: t.replace("      - {piece: straight, count: 4}\n      - {piece: curve_r40, turn: right}\n"
                                     "  - section: main",
                                     "      - {piece: straight, count: 3}\n      - {piece: curve_r40, turn: right}\n"
                                     "  - section: main"),
     "section: platform_loop", ["platform_loop.end", "left open", "nearest open end is W2.diverging",
                               "128.0 mm", "list platform_loop.end under buffers"]),
    ("overlap", lambda t: t.replace("stations:", SPUR + "\nstations:"),
     "section: spur", ["overlap", "centre lines", "64 mm", "move the pieces apart"]),
    ("joined twice", lambda t: t.replace("stations:", "  - section: extra\n    from: W1.straight\n    segments:\n"
                                         "      - {piece: straight, count: 2}\nbuffers: [extra.end]\nstations:"),
     "section: extra", ["joined twice", "W1.straight", "platform_main.start", "remove or move one"]),
    ("station section", lambda t: t.replace("{name: north, section: main,", "{name: north, section: mian,"),
     "name: north", ["stations[2].section", "'mian' is off the graph", "sections are"]),
    ("station offset", lambda t: t.replace("{name: north, section: main, offset_m: 2.15}",
                                           "{name: north, section: main, offset_m: 9.5}"),
     "name: north", ["stations[2].offset_m", "9.5 is off the graph", "runs from 0 to 3.8026 m"]),
    ("station back", lambda t: t.replace("{name: north, section: main, offset_m: 2.15}",
                                         "{name: north, section: main, offset_m: 2.15, back_offset_m: -1}"),
     "name: north", ["stations[2].back_offset_m", "-1.0 is off the graph"]),
    ("tag off", lambda t: t.replace('"04560003", section: platform_loop, offset_m: 0.2',
                                    '"04560003", section: platform_loop, offset_m: -0.2'),
     '"04560003"', ["tags[2].offset_m", "off the graph"]),
    ("buffer joined", lambda t: t.replace("stations:", "buffers: [main.end]\nstations:"),
     "buffers:", ["buffers[0]", "main.end is listed as a buffer stop but is joined to W1.toe", "remove it"]),
    ("buffer twice", lambda t: t.replace("stations:", "buffers: [main.end, main.end]\nstations:"),
     "buffers:", ["buffers[1]", "main.end is listed twice (first at buffers[0])"]),
    ("join apart", lambda t: t.replace("stations:", "joins:\n  - [platform_main.start, W2.toe]\nstations:"),
     "[platform_main.start, W2.toe]", ["joins[0]", "do not meet", "mm apart"]),
    ("unknown anchor", lambda t: t.replace("from: W1.diverging", "from: W9.diverging"),
     "from: W9.diverging", ["track[3].from", "no section, switch or crossing 'W9'"]),
    ("unknown end", lambda t: t.replace("from: W1.diverging", "from: W1.curved"),
     "from: W1.curved", ["'W1.curved' is not an end of W1", "W1.toe, W1.straight, W1.diverging"]),
    ("bad piece", lambda t: t.replace("piece: switch_right", "piece: switch_wye"),
     "piece: switch_wye", ["track[2].piece", "switch_left, switch_right"]),
    ("segment", lambda t: t.replace("{piece: straight, count: 6}", "{piece: straight, count: 0}"),
     "section: platform_main", ["track[1].segments[0].count", "whole number"]),
    ("mixed", lambda t: t.replace("track:", "closed: true\ntrack:"),
     "closed: true", ["closed: belongs to a single-path layout", "sections under track"]),
]


@pytest.mark.parametrize("case, change, at, words", CASES, ids=[c[0] for c in CASES])
def test_network_errors_name_file_line_and_fix(tmp_path, case, change, at, words):
    text = change(PASSING)
    assert text != PASSING, case
    message, path = _error(tmp_path, text)
    where = f"{path}:{_line_of(text, at)}: " if at else f"{path}: "
    assert message.startswith(where), (message, where)
    for word in words:
        assert word in message, (word, message)


def test_open_end_without_buffer_and_ends_at_an_angle(tmp_path):
    text = BRANCH.replace("buffers: [west_1.end, west_2.end, east_1.end, east_2.end]",
                          "buffers: [west_1.end, west_2.end, east_1.end]")
    message, path = _error(tmp_path, text)
    assert message.startswith(f"{path}:{_line_of(text, 'section: east_2')}: ")
    assert "east_2.end at (4.224, -0.128) m is left open" in message and "under buffers" in message
    # a curve ending at an angle against the next piece
    angled = ("track:\n  - section: a\n    segments:\n      - {piece: straight, count: 2}\n"
              "  - section: b\n    start: {x_m: 0.256, y_m: 0.0, heading_deg: 30}\n    segments:\n"
              "      - {piece: straight}\nbuffers: [a.start, b.end]\n")
    message, path = _error(tmp_path, angled, "angled.yaml")
    assert "meets" in message and "30.0 deg" in message and "use a switch" in message
    assert message.startswith(f"{path}:5: ")


def test_duplicate_keys_and_names_are_named(tmp_path):
    message, path = _error(tmp_path, PASSING.replace("name: lego_passing_loop", "name: a\nname: b"))
    assert message.startswith(f"{path}:") and "given twice" in message
    message, _ = _error(tmp_path, PASSING.replace("section: platform_loop", "section: platform_main"))
    assert "'platform_main' is used twice (first at track[1])" in message


def test_layout_show_and_list_networks(tmp_path, capsys):
    png = tmp_path / "net.png"
    assert cbtc_main(["layout", "show", "lego_passing_loop", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "track network" in out and "W1" in out and "diverging leg joins" in out and png.stat().st_size > 20_000
    assert cbtc_main(["layout", "show", "lego_branch", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["kind"] == "network"
    wa = next(w for w in info["switches"] if w["id"] == "WA")
    assert (wa["toe_joins"], wa["straight_joins"], wa["diverging_joins"]) == \
        ("west_line.start", "west_1.start", "west_2.start")
    assert cbtc_main(["layout", "list"]) == 0
    out = capsys.readouterr().out
    assert any(line.split()[:2] == ["lego_branch", "network"] for line in out.splitlines())


@pytest.mark.parametrize("argv", [["fusion", "--layout", "lego_figure_eight"],
                                  ["setup", "--layout", "lego_branch", "--out", "OUT"]])
def test_commands_that_run_paths_refuse_a_network_cleanly(argv, tmp_path, capsys):
    out = tmp_path / "live"
    assert cbtc_main([str(out) if a == "OUT" else a for a in argv]) == 2
    err = capsys.readouterr().err
    assert "is a track network" in err and "cbtc layout list" in err and "Traceback" not in err
    assert not out.exists()      # nothing written before the refusal


def test_ips_fixes_project_onto_the_sections_the_train_can_be_on():
    layout = load_track("lego_passing_loop")
    g = layout.graph
    # between the two platforms, 64 mm from each: the nearest track decides only among the candidates given
    x, y = layout.xy_m("platform_main", 0.45)
    fix = (x, y + 0.06)
    assert g.project(*fix)[0] == "platform_main"
    name, offset, distance = g.project(*fix, sections=["platform_loop", "W1.diverging"])
    assert name == "platform_loop" and distance == pytest.approx(0.128 - 0.06, abs=1e-3)
    assert math.dist(layout.xy_m(name, offset), (x, 0.128)) < 1e-3


def test_what_lies_ahead_on_a_route():
    from cbtc.railway.ahead import look_ahead, trains_ahead

    assert trains_ahead([0.5, 2.0, 1.0], closed=True) == {0: 2, 2: 1, 1: 0}
    assert trains_ahead([0.5, 2.0, 1.0], closed=False) == {0: 2, 2: 1}
    g = load_track("lego_branch").graph
    route = g.route([("west_line", True), ("W1.straight", True), ("middle_main", True), ("W2.straight", False),
                     ("east_line", True)])
    spans = {"A": (("middle_main", 0.5, 0.7),), "B": (("middle_loop", 0.6, 0.7633), ("W2.diverging", 0.0, 0.2862)),
             "C": (("west_line", 0.0, 0.2),)}
    ahead = look_ahead(route, 0.5, spans, own="C")
    # B, converging on W2 from the loop, fouls the route where it enters W2; A is on the route itself
    assert ahead.trains == (("A", pytest.approx(1.024 - 0.5 + 0.256 + 0.5)), ("B", pytest.approx(2.048 - 0.5)))
    assert [(w, round(d, 4), leg) for w, d, leg in ahead.switches] == [("W1", 0.524, "straight"),
                                                                      ("W2", 1.548, "straight")]
    assert ahead.end_m == pytest.approx(route.length_m - 0.5)
    # a switch not detected in the route's leg ends the limit before any train past it
    from cbtc.authority.network_limit import network_limit

    assert network_limit(route, 0.5, "C", spans, {"W1": "diverging", "W2": "straight"}).distance_m == \
        pytest.approx(0.524)
    assert network_limit(route, 0.5, "C", spans, {"W1": "straight", "W2": "straight"}).distance_m == \
        pytest.approx(1.28)
    # past W1, on its leg: the switch is at distance 0; a train behind is not ahead
    on_w1 = look_ahead(route, 1.1, {"C": (("west_line", 0.0, 0.2),)})
    assert on_w1.switches[0] == ("W1", 0.0, "straight") and on_w1.trains == ()


def test_a_route_through_the_network_is_a_layout_the_zone_can_run():
    from cbtc.railway.network_layout import route_layout

    loop = load_track("lego_passing_loop")
    via_main = route_layout(loop, [("W1.straight", True), ("platform_main", True), ("W2.straight", False),
                                   ("main", True)])
    oval = load_layout("lego_oval")
    # through the straight legs the passing loop is the LEGO oval, piece for piece, from the same origin
    assert via_main.closed and via_main.length_m == pytest.approx(oval.length_m, abs=1e-9)
    for s in np.linspace(0.0, oval.length_m, 97):
        assert math.dist(via_main.xy_m(s), oval.xy_m(s)) < 1e-9
    assert [st.name for st in via_main.stations] == ["south_main", "north"]
    assert via_main.station("south_main").s_m == pytest.approx(0.256 + 0.5)
    assert len(via_main.tags) == 7 and [b.name for b in via_main.blocks] == \
        ["W1.straight", "platform_main", "W2.straight", "main.1", "main.2", "main.3", "main.4", "main.5"]
    assert via_main.block_at(0.3).name == "platform_main"
    via_loop = route_layout(loop, [("W1.diverging", True), ("platform_loop", True), ("W2.diverging", False),
                                   ("main", True)])
    assert via_loop.length_m > via_main.length_m and [st.name for st in via_loop.stations] == ["south_loop", "north"]
    line = route_layout(load_track("lego_branch"), [("west_1", False), ("WA.straight", False), ("west_line", True)])
    assert not line.closed and line.length_m == pytest.approx(0.640 + 0.256 + 1.024)
    # run backwards, west_1's stop point is as far from the section's end as its forward one is from its start
    assert line.station("west_1").s_m == pytest.approx(0.40)
    assert load_track("lego_branch").station("west_1").stop_m(False) == pytest.approx(0.640 - 0.40)


@pytest.mark.parametrize("policy", ["moving_block", "fixed_block"])
def test_the_simulator_runs_trains_on_one_route_through_the_network(policy):
    # every switch set for the route: the virtual trains, their boards and the zone run on the route's layout as on
    # any loop; both policies (fixed blocks: one per section, signals at the switches)
    from cbtc.railway.network_layout import route_layout
    from cbtc.sim.runs import sim_config
    from cbtc.sim.simulation import Simulation

    layout = route_layout(load_track("lego_passing_loop"), [("W1.diverging", True), ("platform_loop", True),
                                                           ("W2.diverging", False), ("main", True)])
    trains = 3 if policy == "moving_block" else 2      # fixed blocks: the 3.8 m main line is one block
    summary = Simulation(sim_config(layout, trains, seed=2, duration_s=30.0, policy=policy)).run().summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    assert all(t["distance_m"] > 0.5 for t in summary["trains"])


def test_a_figure_eight_crosses_on_a_crossing():
    from cbtc.railway.ahead import look_ahead
    from cbtc.railway.interlocking import Interlocking

    layout = load_track("lego_figure_eight")
    g = layout.graph
    assert g.sections["X.a"].crossing == "X" and g.piece_mates("X.a") == ["X.b"]
    # the two tracks cross at their middles at right angles; the figure eight is one closed route over both
    assert math.dist(g.sections["X.a"].path.xy_m(0.064), g.sections["X.b"].path.xy_m(0.064)) < 1e-12
    route = g.route([("X.a", True), ("east_loop", True), ("X.b", False), ("west_loop", True)])
    assert route.closed and route.length_m == pytest.approx(layout.length_m)
    # a train on the crossing's other track fouls the route where it enters the crossing
    ahead = look_ahead(route, 3.0, {"T": (("X.b", 0.0, 0.05),), "U": (("X.a", 0.0, 0.01),)}, own="U")
    assert ahead.trains == (("T", pytest.approx(route.length_m - 3.0)),)
    ixl = Interlocking(g)
    spans = {"T": (("west_loop", 1.5, 1.75),), "U": (("east_loop", 1.5, 1.75),)}
    assert ixl.set_route("R1", "T", [("west_loop", True), ("X.a", True), ("east_loop", True)], spans).ok
    out = ixl.set_route("R2", "U", [("east_loop", True), ("X.b", False), ("west_loop", True)], spans)
    assert not out.ok and "X.a, the track crossing X.b" in out.reason
    out = Interlocking(g).set_route("R2", "U", [("east_loop", True), ("X.b", False)],
                                    {"T": (("X.a", 0.05, 0.128), ("east_loop", 0.0, 0.1))})
    assert not out.ok and "crossing X is not free" in out.reason and "train T is on X.a" in out.reason


def test_crossing_errors_name_the_line_and_fix(tmp_path):
    text = open(load_track("lego_figure_eight").source, encoding="utf-8").read()
    message, path = _error(tmp_path, text.replace("from: X.b.start", "from: X.c.start"))
    assert f"{path}:{_line_of(text, 'from: X.b.start')}:" in message and "'X.c.start' is not an end of X" in message
    assert "X.a.start, X.a.end, X.b.start, X.b.end" in message
    message, _ = _error(tmp_path, text.replace("{crossing: X, start:", "{crossing: X, by: c, start:"))
    assert "track[0].by: must be a or b" in message


def _graph_is_consistent(graph):
    """Every section end on exactly one node side; a way on is a way back; routes flatten onto the sections."""
    seen = {}
    for node in graph.nodes:
        for end in node.side_a + node.side_b:
            assert end not in seen, end
            seen[end] = node
    assert set(seen) == {(n, w) for n in graph.sections for w in ("start", "end")}
    for name in graph.sections:
        for forward in (True, False):
            for nxt, fwd in graph.next_steps(name, forward):
                assert (name, not forward) in graph.next_steps(nxt, not fwd), (name, forward, nxt, fwd)
                route = graph.route([(name, forward), (nxt, fwd)])
                path = route.path()
                for s in (0.0, route.starts_m[1] - 1e-6, route.starts_m[1] + 1e-6, route.length_m):
                    assert math.dist(path.xy_m(s), route.xy_m(s)) < 0.006   # joints meet within 5 mm


def test_random_lines_of_pieces_load_as_consistent_graphs():
    from hypothesis import HealthCheck, given, settings

    from network_model import ELEMENTS, network

    @settings(max_examples=60, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow])
    @given(ELEMENTS)
    def check(elements):
        _graph_is_consistent(network(elements))

    check()
    for name in ("lego_passing_loop", "lego_branch", "lego_figure_eight"):
        _graph_is_consistent(load_track(name).graph)
