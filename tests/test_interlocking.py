"""The interlocking: routes over switches, refusals with reasons, release behind the train, time release; and
property-based runs on random LEGO networks (random route requests, cancellations, switch throws and train moves):
no two locked routes conflict, no switch moves while locked or occupied, every released section lies wholly behind
its train's tail.

Bounded in the normal suite (derandomized); `pytest -m fuzz` runs the long profile with fresh examples.
"""

import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, initialize, invariant, rule

from cbtc.layout_files import load_track
from cbtc.railway.interlocking import Interlocking, find_routes
from cbtc.railway.track_graph import LEGS
from network_model import ELEMENTS, Train, network

BOUNDED = settings(max_examples=150, stateful_step_count=50, deadline=None, derandomize=True, database=None,
                   suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
LONG = settings(max_examples=2000, stateful_step_count=80, deadline=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])


def _span(section, lo=0.0, hi=None, graph=None):
    return (section, lo, hi if hi is not None else graph.sections[section].length_m)


@pytest.fixture
def branch():
    return Interlocking(load_track("lego_branch").graph)


WEST_TO_LOOP = (("west_1", False), ("WA.straight", False), ("west_line", True), ("W1.diverging", True),
                ("middle_loop", True))
EAST_TO_MAIN = (("east_1", False), ("WB.straight", False), ("east_line", False), ("W2.straight", True),
                ("middle_main", False))


def test_a_route_sets_its_switches_and_conflicts_are_refused_with_reasons(branch):
    g = branch.graph
    spans = {"T1": (_span("west_1", 0.1, 0.35),), "T2": (_span("east_1", 0.1, 0.35),)}
    out = branch.set_route("R1", "T1", WEST_TO_LOOP, spans)
    assert out.ok and out.moves == (("W1", "diverging"),)
    assert branch.switch_leg["W1"] == "diverging" and branch.routes["R1"].flank == (("WA", "diverging"),
                                                                                    ("W1", "straight"))
    # the other train's route into the main platform shares no section or switch: it is set too
    assert branch.set_route("R2", "T2", EAST_TO_MAIN, spans).ok
    # a third route over west_line conflicts, naming who holds it
    out = branch.set_route("R3", "T2", (("W1.straight", False), ("west_line", False)), spans)
    assert not out.ok and "conflicts with route R1 (train T1)" in out.reason
    # a switch that is locked cannot be thrown by hand
    out = branch.move_switch("W1", "straight", spans)
    assert not out.ok and "locked by route R1" in out.reason and branch.switch_leg["W1"] == "diverging"
    assert not branch.move_switch("W9", "straight", spans).ok
    assert g.switches["WA"]


def test_a_switch_never_moves_under_a_train_and_must_be_free(branch):
    g = branch.graph
    on_w1 = {"T1": (_span("west_line", 0.9, 1.024), _span("W1.straight", 0.0, 0.05))}
    out = branch.set_route("R1", "T1", (("west_line", True), ("W1.diverging", True), ("middle_loop", True)), on_w1)
    assert not out.ok and "cannot move to diverging" in out.reason and "train T1 on its straight leg" in out.reason
    assert branch.switch_leg["W1"] == "straight"
    out = branch.move_switch("W1", "diverging", on_w1)
    assert not out.ok and "never moves under a train" in out.reason
    # a train of another route standing on the flank leg: the switch is not free even in position
    flank = {"T1": (_span("west_line", 0.2, 0.5),), "T2": (_span("W1.diverging", 0.0, 0.1, g),)}
    out = branch.set_route("R1", "T1", (("west_line", True), ("W1.straight", True), ("middle_main", True)), flank)
    assert not out.ok and "not free" in out.reason and "train T2 is on its diverging leg" in out.reason


def test_release_behind_the_tail_and_cancel_rules(branch):
    steps = (("west_line", True), ("W1.straight", True), ("middle_main", True), ("W2.straight", False),
             ("east_line", True))
    assert branch.set_route("R1", "T1", steps, {"T1": (_span("west_line", 0.1, 0.4),)}).ok
    # not yet entered: cancelling in front of an approaching train is time-released
    out = branch.cancel("R1", {"T1": ()}, approaching=True, now_s=5.0)
    assert not out.ok and "released at t = 15.0 s" in out.reason
    assert branch.advance({"T1": ()}, 10.0) == [] and "R1" in branch.routes
    # the train enters before the timer runs out: the cancel is dropped and the route releases behind the train
    on = {"T1": (_span("west_line", 0.8, 1.024), _span("W1.straight", 0.0, 0.1))}
    assert branch.release_behind(on) == []
    assert branch.advance(on, 16.0) == [] and branch.routes["R1"].cancel_at_s is None
    assert not branch.cancel("R1", on, approaching=False, now_s=16.0).ok
    # the tail (widened) leaves west_line: it is released, W1 stays locked while the train is on its leg
    assert branch.release_behind({"T1": (_span("W1.straight", 0.05, 0.256), _span("middle_main", 0.0, 0.1))}) == \
        [("R1", "west_line")]
    assert branch.switch_lock("W1").id == "R1"
    assert branch.release_behind({"T1": (_span("middle_main", 0.3, 0.6),)}) == [("R1", "W1.straight")]
    assert branch.switch_lock("W1") is None and branch.move_switch("W1", "diverging", {}).ok
    # a train with no estimate releases nothing; off the far end the rest is released
    assert branch.release_behind({}) == []
    assert [s for _r, s in branch.release_behind({"T1": (_span("east_1", 0.1, 0.3),)})] == \
        ["middle_main", "W2.straight", "east_line"]
    assert branch.routes == {}


def test_cancel_without_a_train_near_is_immediate_and_bad_routes_are_refused(branch):
    assert branch.set_route("R1", "T1", (("west_line", True), ("W1.straight", True)), {}).ok
    assert not branch.set_route("R1", "T2", (("east_line", True),), {}).ok
    assert branch.cancel("R1", {}, approaching=False, now_s=0.0).ok and branch.routes == {}
    out = branch.set_route("R2", "T1", (("west_line", True), ("middle_main", True)), {})
    assert not out.ok and "not a route on this layout" in out.reason
    assert not branch.cancel("R9", {}, False, 0.0).ok


def test_find_routes_through_the_passing_loop():
    g = load_track("lego_branch").graph
    routes = find_routes(g, ("west_1", False), "east_2")
    assert len(routes) == 2     # by the main platform or the loop
    assert all(r[-1][0] == "east_2" for r in routes)
    assert {r[4][0] for r in routes} == {"middle_main", "middle_loop"}


class InterlockingMachine(RuleBasedStateMachine):
    @initialize(elements=ELEMENTS, data=st.data())
    def build(self, elements, data):
        self.graph = network(elements)
        self.ixl = Interlocking(self.graph, following=data.draw(st.booleans()))
        plain = sorted(n for n, s in self.graph.sections.items() if not s.switch)
        self.trains = {}
        for t in range(data.draw(st.integers(1, 3))):
            name = data.draw(st.sampled_from(plain))
            forward = data.draw(st.booleans())
            length = self.graph.sections[name].length_m
            self.trains[f"T{t}"] = Train(self.graph, (name, forward), data.draw(st.floats(0.0, length)),
                                         data.draw(st.floats(0.05, 0.3)), data.draw(st.floats(0.0, 0.05)))
        self.now_s, self.count = 0.0, 0

    def spans(self):
        return {t: train.span() for t, train in self.trains.items()}

    def _check_moves(self, moves, locks_before, on_before):
        for switch, _leg in moves:
            assert locks_before[switch] is None, f"switch {switch} moved while locked"
            assert not on_before[switch], f"switch {switch} moved under {on_before[switch]}"

    def _before(self, spans):
        return ({w: self.ixl.switch_lock(w) for w in self.graph.switches},
                {w: self.ixl.trains_on_switch(w, spans) for w in self.graph.switches})

    @rule(data=st.data())
    def request_route(self, data):
        train = data.draw(st.sampled_from(sorted(self.trains)))
        start = self.trains[train].steps[-1] if data.draw(st.booleans()) else \
            (data.draw(st.sampled_from(sorted(self.graph.sections))), data.draw(st.booleans()))
        steps = [start]                       # a random walk on from the start: always a route on the graph
        for _ in range(data.draw(st.integers(0, 6))):
            nxt = [s for s in self.graph.next_steps(*steps[-1]) if s[0] not in {n for n, _f in steps}]
            if not nxt:
                break
            steps.append(data.draw(st.sampled_from(nxt)))
        spans = self.spans()
        before = self._before(spans)
        self.count += 1
        out = self.ixl.set_route(f"R{self.count}", train, steps, spans, self.now_s)
        assert out.ok or out.reason
        self._check_moves(out.moves, *before)
        for name, _f in steps if out.ok else ():
            for mate in self.graph.piece_mates(name) if self.graph.sections[name].crossing else ():
                on = [t for t, iv in spans.items() if t != train and any(s == mate for s, _lo, _hi in iv)]
                assert not on, f"route over {name} set with train {on} on {mate}, the track crossing it"

    @rule(data=st.data())
    def throw_switch(self, data):
        if not self.graph.switches:
            return
        switch = data.draw(st.sampled_from(sorted(self.graph.switches)))
        spans = self.spans()
        before = self._before(spans)
        out = self.ixl.move_switch(switch, data.draw(st.sampled_from(LEGS)), spans)
        self._check_moves(out.moves, *before)

    @rule(data=st.data())
    def cancel(self, data):
        if not self.ixl.routes:
            return
        route = data.draw(st.sampled_from(sorted(self.ixl.routes)))
        out = self.ixl.cancel(route, self.spans(), data.draw(st.booleans()), self.now_s)
        assert out.ok or out.reason

    @rule(data=st.data(), d_m=st.floats(0.0, 0.4))
    def move_train(self, data, d_m):
        train = data.draw(st.sampled_from(sorted(self.trains)))
        self.trains[train].advance(d_m, self.ixl.switch_leg)
        self.now_s += 1.0
        spans = self.spans()
        held = {rid: (r.train, r.held_steps, r.entered) for rid, r in self.ixl.routes.items()}
        for rid, section in self.ixl.release_behind(spans):
            owner, steps, _entered = held[rid]
            touched = {s for s, _lo, _hi in spans[owner]}
            assert section not in touched, f"{section} released under train {owner}'s span"
            names = [s for s, _f in steps]
            later = names[names.index(section) + 1:]
            assert any(s in touched for s in later) or rid not in self.ixl.routes or \
                not any(s in touched for s in names), f"{section} released ahead of train {owner}"
        self.ixl.advance(spans, self.now_s)

    def _extends(self, a, b, name, i):
        ra, rb = self.ixl.routes[a], self.ixl.routes[b]
        return ra.train == rb.train and ((i == 0 and ra.held_steps[-1][0] == name) or
                                         (rb.held_steps[-1][0] == name and ra.held_steps[0][0] == name))

    def _follows(self, a, b, name, forward):
        ra = self.ixl.routes[a]
        return self.ixl.following and ra.train != self.ixl.routes[b].train and ra.direction_on(name) == forward

    @invariant()
    def no_two_trains_hold_the_tracks_of_one_crossing(self):
        if not hasattr(self, "ixl"):
            return
        held = {}
        for route in self.ixl.routes.values():
            for name, _f in route.held_steps:
                crossing = self.graph.sections[name].crossing
                if crossing:
                    for track, train in held.get(crossing, ()):
                        assert track == name or train == route.train, f"crossing {crossing} held by two trains"
                    held.setdefault(crossing, []).append((name, route.train))

    @invariant()
    def no_two_locked_routes_conflict(self):
        if not hasattr(self, "ixl"):
            return
        held_sections, held_switches = {}, {}
        for rid, route in self.ixl.routes.items():
            for i, (name, forward) in enumerate(route.held_steps):
                other = held_sections.get(name)
                # one train's route may extend another of its own, from that one's last section; under moving block
                # another train's route may follow it the same way
                assert other is None or self._extends(other, rid, name, i) or \
                    self._follows(other, rid, name, forward), f"{name} held by {other} and {rid}"
                held_sections[name] = rid
                switch = self.graph.sections[name].switch
                if switch:
                    other = held_switches.get(switch, rid)
                    assert other == rid or self.ixl.routes[other].train == route.train or \
                        self._follows(other, rid, name, forward), f"switch {switch} in two trains' routes"
                    held_switches[switch] = rid
                    assert self.ixl.switch_leg[switch] == route.switch_legs[switch], \
                        f"switch {switch} not in route {rid}'s position"


def test_interlocking_properties_bounded():
    InterlockingMachine.TestCase.settings = BOUNDED
    InterlockingMachine.TestCase().runTest()


@pytest.mark.fuzz
def test_interlocking_properties_long():
    InterlockingMachine.TestCase.settings = LONG
    InterlockingMachine.TestCase().runTest()
