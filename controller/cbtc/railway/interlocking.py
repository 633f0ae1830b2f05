"""The interlocking of a track network, as pure code: routes locked over sections and switches, released behind trains.

A route is a chain of (section, forward) steps for one train. Setting it is refused, with a reason a user can read,
when a locked route holds one of its sections or switches (unless, under moving block, it runs them the same way:
the train follows the other one, and its authority ends at that train's tail), or when a switch it needs is not free:
a switch is free when no train's span (its estimated extent, already widened by its uncertainty: `spans` maps train ->
((section, lo_m, hi_m), ...)) reaches either of its legs, the whole switch piece counting as inside the fouling point
(a train ahead running the same way over the same leg aside). The other leg of each switch in a set route is its
flank: no route over it can be set while the switch is locked, and a train on it makes the switch not free. A route
releases step by step behind its train: a step is released once the train's span has reached a later step and no
longer touches it. A switch moves only when set_route or move_switch find it unlocked and unoccupied. A route may
begin on the last section of a route its train holds, extending it. Cancelling a route its train is on is refused;
cancelling one the train is approaching (the caller says so: it could not stop short of the route) releases after
`approach_release_s`. Time is passed in.
"""

from dataclasses import dataclass, field

from cbtc.railway.track_graph import LEGS, TrackGraph

APPROACH_RELEASE_S = 10.0   # a cancelled route in front of an approaching train stays locked this long


@dataclass(frozen=True)
class Outcome:
    """What a request did: ok, the reason when refused (or what is pending), switch moves commanded [(id, leg)]."""
    ok: bool
    reason: str = ""
    moves: tuple = ()


@dataclass
class LockedRoute:
    id: str
    train: str
    steps: tuple
    switch_legs: dict              # switch id -> leg the route needs
    released: int = 0              # steps released from the front of `steps`
    entered: bool = False          # the train's span has touched the route
    cancel_at_s: float = None      # a time release under way

    @property
    def held_steps(self):
        return self.steps[self.released:]

    def direction_on(self, section):
        """True (forwards) or False as the route runs over `section` while holding it, None when it does not."""
        return next((fwd for name, fwd in self.held_steps if name == section), None)

    @property
    def flank(self):
        """The legs this route's switches must keep free of other routes: each switch's other leg."""
        return tuple((w, next(leg for leg in LEGS if leg != need)) for w, need in self.switch_legs.items())


@dataclass
class Interlocking:
    """The switches' set positions and the locked routes of one track graph."""
    graph: TrackGraph
    following: bool = True     # a route may follow another train the same way over what its route holds (moving
    #                            block); False: sections are exclusive, blocks behind signals (the fixed-block baseline)
    approach_release_s: float = APPROACH_RELEASE_S
    switch_leg: dict = field(default_factory=dict)    # switch id -> last commanded leg
    routes: dict = field(default_factory=dict)        # route id -> LockedRoute

    def __post_init__(self):
        for w in self.graph.switches:
            self.switch_leg.setdefault(w, "straight")

    # --- what is held ------------------------------------------------------------------------------------------

    def held_by(self, train):
        """The steps the routes of `train` hold, in the order they were set, a route that extends another joined to
        it on their shared section."""
        steps = []
        for route in self.routes.values():
            if route.train == train:
                held = route.held_steps
                steps.extend(held[1:] if steps and held and held[0] == steps[-1] else held)
        return tuple(steps)

    def routes_of_section(self, section):
        """The routes holding `section` (more than one only where trains follow each other the same way)."""
        return [r for r in self.routes.values() if any(name == section for name, _fwd in r.held_steps)]

    def switch_locks(self, switch):
        """The routes holding a leg of `switch`: a switch is locked while any of its legs is held."""
        return [r for r in self.routes.values()
                if any(self.graph.sections[name].switch == switch for name, _fwd in r.held_steps)]

    def switch_lock(self, switch):
        """The first route holding a leg of `switch`, or None."""
        held = self.switch_locks(switch)
        return held[0] if held else None

    def trains_on_switch(self, switch, spans):
        """{train: leg} of the trains whose span reaches a leg of `switch`."""
        legs = {f"{switch}.{leg}": leg for leg in LEGS}
        out = {}
        for train, intervals in spans.items():
            for section, _lo, _hi in intervals:
                if section in legs:
                    out.setdefault(train, legs[section])
        return out

    # --- requests ----------------------------------------------------------------------------------------------

    def set_route(self, route_id, train, steps, spans, now_s=0.0) -> Outcome:
        """Lock the route `steps` for `train` and command its switches, or refuse with the reason."""
        steps = tuple((str(s), bool(f)) for s, f in steps)
        if route_id in self.routes:
            return Outcome(False, f"route {route_id} is already set (for train {self.routes[route_id].train})")
        try:
            self.graph.route(steps)
        except (ValueError, KeyError) as exc:
            return Outcome(False, f"route {route_id} is not a route on this layout: {exc}")
        names = [s for s, _f in steps]
        if len(set(names)) != len(names):
            return Outcome(False, f"route {route_id} runs over a section twice: split it into two routes")
        needs = {}
        for name in names:
            sec = self.graph.sections[name]
            if sec.switch:
                if needs.get(sec.switch, sec.leg) != sec.leg:
                    return Outcome(False, f"route {route_id} runs over both legs of switch {sec.switch}")
                needs[sec.switch] = sec.leg
        for i, (name, forward) in enumerate(steps):
            for other in self.routes_of_section(name):
                if i == 0 and other.train == train and other.held_steps[-1][0] == name:
                    continue     # a route may begin on the last section of one its train holds: it extends it
                if self.following and other.train != train and other.direction_on(name) == forward:
                    continue     # it follows the other train the same way: the authority ends at that one's tail
                return Outcome(False, f"route {route_id} conflicts with route {other.id} (train {other.train}), "
                                      f"which holds section {name}"
                                      + (" the other way" if other.direction_on(name) != forward else ""))
        direction = dict(steps)
        for switch, leg in needs.items():
            leg_section = f"{switch}.{leg}"
            for other in self.switch_locks(switch):
                same = other.direction_on(leg_section) == direction[leg_section]
                if other.train == train and same and names[0] == leg_section:
                    continue
                if self.following and other.train != train and same:
                    continue
                return Outcome(False, f"route {route_id} conflicts with route {other.id} (train {other.train}), "
                                      f"which holds switch {switch} {other.switch_legs.get(switch, '')}")
            on = self.trains_on_switch(switch, spans)
            if self.switch_leg[switch] != leg and on:
                who = ", ".join(f"train {t} on its {lg} leg" for t, lg in sorted(on.items()))
                return Outcome(False, f"switch {switch} cannot move to {leg} for route {route_id}: {who} (spans "
                                      "widened by their uncertainty); a switch never moves under a train")
            for other_train, on_leg in sorted(on.items()):
                if on_leg == leg and (other_train == train or (self.following and any(
                        r.train == other_train and r.direction_on(leg_section) == direction[leg_section]
                        for r in self.switch_locks(switch)))):
                    continue     # itself, or a train ahead running the same way over the same leg
                return Outcome(False, f"switch {switch} is not free for route {route_id}: train {other_train} "
                                      f"is on its {on_leg} leg, inside the fouling point")
        crossing = self._crossing_conflict(route_id, train, steps, spans)
        if crossing is not None:
            return crossing
        moves = tuple((w, leg) for w, leg in needs.items() if self.switch_leg[w] != leg)
        for w, leg in moves:
            self.switch_leg[w] = leg
        self.routes[route_id] = LockedRoute(route_id, train, steps, needs)
        return Outcome(True, "", moves)

    def _crossing_conflict(self, route_id, train, steps, spans):
        """A refusal when a crossing on the route has its other track held by another train's route or occupied by
        another train (the two tracks cross: one train on either fouls both), else None."""
        for name, _fwd in steps:
            crossing = self.graph.sections[name].crossing
            for mate in self.graph.piece_mates(name) if crossing else ():
                for other in self.routes_of_section(mate):
                    if other.train != train:
                        return Outcome(False, f"route {route_id} conflicts with route {other.id} (train "
                                              f"{other.train}), which holds {mate}, the track crossing {name}")
                for other_train, intervals in sorted(spans.items()):
                    if other_train != train and any(s == mate for s, _lo, _hi in intervals):
                        return Outcome(False, f"crossing {crossing} is not free for route {route_id}: train "
                                              f"{other_train} is on {mate}")
        return None

    def move_switch(self, switch, leg, spans) -> Outcome:
        """Throw `switch` to `leg` by hand, or refuse: locked by a route, or a train on it."""
        if switch not in self.graph.switches:
            return Outcome(False, f"no switch {switch!r}; switches are {', '.join(self.graph.switches)}")
        if leg not in LEGS:
            return Outcome(False, f"switch {switch}: no leg {leg!r}; legs are straight and diverging")
        if self.switch_leg[switch] == leg:
            return Outcome(True)
        route = self.switch_lock(switch)
        if route is not None:
            return Outcome(False, f"switch {switch} is locked by route {route.id} (train {route.train}): cancel the "
                                  "route first")
        on = self.trains_on_switch(switch, spans)
        if on:
            who = ", ".join(f"train {t} on its {lg} leg" for t, lg in sorted(on.items()))
            return Outcome(False, f"switch {switch} cannot move: {who}; a switch never moves under a train")
        self.switch_leg[switch] = leg
        return Outcome(True, "", ((switch, leg),))

    def release_behind(self, spans):
        """Release each route's steps wholly behind its train; returns [(route id, section)] released. A train
        without a span (no estimate) releases nothing; a route its train has left entirely is released whole."""
        released = []
        for route in list(self.routes.values()):
            intervals = spans.get(route.train)
            if intervals is None:
                continue
            touched = {s for s, _lo, _hi in intervals}
            held = route.held_steps
            first = next((i for i, (name, _f) in enumerate(held) if name in touched), None)
            if first is None:
                if not route.entered:
                    continue
                first = len(held)      # the train has run off the route's far end
            else:
                route.entered = True
            for name, _fwd in held[:first]:
                released.append((route.id, name))
            route.released += first
            if route.released == len(route.steps):
                del self.routes[route.id]
        return released

    def cancel(self, route_id, spans, approaching, now_s) -> Outcome:
        """Cancel a route: refused while its train is on it; time-released when the train is approaching."""
        route = self.routes.get(route_id)
        if route is None:
            return Outcome(False, f"no route {route_id} is set")
        touched = {s for s, _lo, _hi in spans.get(route.train, ())}
        on = [name for name, _f in route.held_steps if name in touched]
        if on or route.entered:
            return Outcome(False, f"route {route_id} cannot be cancelled: train {route.train} is on it (section "
                                  f"{(on or [route.held_steps[0][0]])[0]}); it releases behind the train")
        if approaching:
            if route.cancel_at_s is None:
                route.cancel_at_s = now_s + self.approach_release_s
            return Outcome(False, f"route {route_id}: train {route.train} is approaching; the route is released at "
                                  f"t = {route.cancel_at_s:.1f} s if the train has not entered it by then")
        del self.routes[route_id]
        return Outcome(True)

    def advance(self, spans, now_s):
        """Complete the time releases due by `now_s` whose train has not entered; returns the route ids released."""
        done = []
        for route in list(self.routes.values()):
            if route.cancel_at_s is not None and now_s >= route.cancel_at_s:
                touched = {s for s, _lo, _hi in spans.get(route.train, ())}
                if route.entered or any(name in touched for name, _f in route.held_steps):
                    route.cancel_at_s = None     # the train entered: the route releases behind it instead
                    continue
                del self.routes[route.id]
                done.append(route.id)
        return done


def find_routes(graph: TrackGraph, start, end_section, max_steps=12):
    """Every route from step `start` (section, forward) to a step on `end_section`, shortest first, over at most
    `max_steps` sections and never over a section twice."""
    found, frontier = [], [(start,)]
    while frontier:
        nxt = []
        for steps in frontier:
            if steps[-1][0] == end_section:
                found.append(steps)
                continue
            if len(steps) >= max_steps:
                continue
            seen = {s for s, _f in steps}
            for step in graph.next_steps(*steps[-1]):
                if step[0] not in seen:
                    nxt.append(steps + (step,))
        frontier = nxt
    return found
