"""The zone's routes on a track network: the interlocking it keeps, the routes it sets ahead of each train along its
itinerary, and where each train's authority ends on the network.

Each train runs an itinerary (cbtc.railway.itinerary) and the zone sees it in that frame (a path Layout of the
itinerary's route, cbtc.railway.network_layout.route_layout). Each cycle the zone reads every located train's span on
the network (its estimate widened by k sigma, its sensors' disagreement and, ahead, the way it can have run since its
data: line speed for the data's age and a cycle, never past the end of the authority the zone last sent it, which its
board enforces), releases the routes behind each train, and asks the interlocking for
the next section of each train's itinerary while the end of what it holds lies within the train's horizon. What a
train holds counts from its rear-most plausible head: a section between it and the front-most one is never skipped. A
train's authority then ends at the first of: the end of what the interlocking holds for it, and the network limit
(cbtc.authority.network_limit: another train's tail on the route or fouling a switch or crossing of it, a switch not
detected in the route's position). The train ahead on the route, translated into the follower's frame, is the leader
the policy follows (Takagi following and departure control as on a loop).
"""

import logging
from math import inf

from cbtc.authority.network_limit import NetworkLimit, fixed_block_limit, network_limit
from cbtc.authority.values import TrainPicture
from cbtc.railway.ahead import look_ahead
from cbtc.railway.geometry import forward_m
from cbtc.railway.interlocking import Interlocking
from cbtc.railway.network_layout import section_blocks
from cbtc.zone.line_dispatch import LineDispatch
from cbtc.zone.turns import Turns

log = logging.getLogger("cbtc.zone")
DEPART_S = 2.0   # a dwelling train's route is set this long before its dwell ends: a switch moves in about a second


class NetworkRoutes:
    def __init__(self, network, frames, k_sigma, margin_m, fixed_blocks=False):
        """`frames`: train id -> the Route of its itinerary (the zone's frame of that train); `fixed_blocks`: the
        fixed-block baseline (a signal at every block's entry, railway.network_layout.section_blocks) in place of
        moving block."""
        self.network = network
        self.fixed_blocks = fixed_blocks
        self.frames = dict(frames)
        self.k_sigma = k_sigma
        self.margin_m = margin_m
        self.interlocking = Interlocking(network.graph)
        # a switch lies where the zone has not yet commanded it: its first route commands it, whatever it is detected
        self.interlocking.switch_leg = {w: None for w in network.graph.switches}
        self.held = {t: {} for t in self.frames}      # train -> {route id: the itinerary step it holds}
        self.refused = {t: "" for t in self.frames}   # train -> why its next section was refused ("" when it was not)
        self._route_ids = 0
        self.detection = lambda now_s: {}   # now_s -> {switch: detected leg, None while moving or lost}: the shell's
        #                                     lineside (a simulation's switch machines)
        self.on_move = None                 # (switch, leg, now_s): the shell throws a switch the interlocking moved
        self.spans = {}          # train -> its widened span on the network, at the newest refresh
        self._rears = {}         # train -> its span from the rear-most tail to the estimated head (what releases)
        self._seen = {}          # train -> its span widened, without the way it may have run since its data
        self.heads = {}          # train -> (frame coordinate of its front-most plausible head, section, offset_m)
        self.reach = {}          # train -> how far behind its front-most plausible head its head may be (m)
        self.kept = {}           # train -> its span when it reversed, an obstacle until it is located again
        self.turns = None        # on a line trains reverse on: cbtc.zone.turns.Turns
        self.dispatch = None     # ... and cbtc.zone.line_dispatch.LineDispatch, which gates each run
        self._waits = frozenset(st.section for st in network.stations)   # where a train on a line may wait

    # --- each cycle -------------------------------------------------------------------------------------------------

    def refresh(self, states, now_s):
        """Read every located train's span, release what lies behind each, and set each train's next sections."""
        self.spans, self.heads, self.reach, self._rears, self._seen = {}, {}, {}, {}, {}
        for st in states:
            if self.turns is not None and self.turns.due(st, now_s):
                self.turns.turn(st, now_s)
            span = self._span(st, now_s)
            if span is not None:
                self.spans[st.train_id] = span
                self.kept.pop(st.train_id, None)
        for train, span in self.kept.items():   # a train that reversed and is not located again yet stands there
            self.spans.setdefault(train, span)
            self._seen.setdefault(train, span)
        # a route is released behind the rear-most tail; its head side counts only where the estimate itself is, so
        # a span whose widening reaches into a route ahead and draws back never releases that route as run off
        for route_id, _section in self.interlocking.release_behind(self._rears):
            train = route_id.split("/", 1)[0]
            self.held[train].pop(route_id, None)
        self.interlocking.advance(self.spans, now_s)
        if self.dispatch is not None and self.dispatch.at is None and all(t in self.heads for t in self.frames):
            self.dispatch.start({st.train_id: (st.leg, self.frames[st.train_id].step_at(self.heads[st.train_id][0]),
                                               self.heads[st.train_id][1]) for st in states})
        for st in states:
            if st.train_id in self.heads:   # located (a reversed train waiting to be located asks nothing)
                for switch, leg in self._request(st, now_s):
                    log.info("switch %s: moving to %s for train %s", switch, leg, st.train_id)
                    if self.on_move is not None:
                        self.on_move(switch, leg, now_s)

    def _span(self, st, now_s):
        if st.report is None or not st.estimator.localized:
            return None
        est = st.newest_estimate()
        pic = st.picture()
        widen = self.k_sigma * est.sigma_s_m
        age_s = max(0.0, now_s - st.report_t_s)
        run_m = st.setup.profile.v_max_mps * (age_s + 0.1) + self.margin_m
        head = est.s_m + est.ahead_m + widen
        frame = self.frames[st.train_id]
        front = head + run_m
        if st.limit_s is not None:   # nor beyond the end of the authority the zone last sent it (the board's bound)
            to_limit_m = forward_m(est.s_m, st.limit_s, frame.length_m) if frame.closed else st.limit_s - est.s_m
            if frame.closed and to_limit_m > frame.length_m - 1.0:
                to_limit_m = 0.0     # just behind: it holds no authority ahead
            front = min(front, max(head, est.s_m + max(0.0, to_limit_m) + widen))
        name, offset = frame.locate(head)
        self.heads[st.train_id] = (head, name, offset)
        self.reach[st.train_id] = head - (est.s_m - est.behind_m - widen)   # (not its tail's doubt)
        tail = est.s_m - st.setup.profile.length_m - pic.behind_m - widen
        self._rears[st.train_id] = frame.span(tail, est.s_m)
        self._seen[st.train_id] = frame.span(tail, head)
        return frame.span(tail, front)

    def _chain(self, train):
        """(the step the train's rear-most plausible head is on, how many steps from it on its routes hold in a row):
        wherever between its rear-most and front-most plausible heads the train is, the track ahead of it is held."""
        frame = self.frames[train]
        held = set(self.held[train].values())
        here = frame.step_at(self.heads[train][0] - self.reach[train])
        n, count = len(frame.steps), 0
        while count < n and (here + count if not frame.closed else (here + count) % n) in held:
            count += 1
        return here, count

    def _need_m(self, st, now_s):
        """How far ahead of its head `st`'s train needs track held: its horizon; only to its next stop (and the
        margin its authority keeps short of what it holds) while it is bound to stop there or dwells, until DEPART_S
        before its dwell ends (a route set early for a train that stands holds the switches other trains need: the
        overtaken train would hold its exit while it dwells)."""
        need_m = st.horizon_m + 0.3
        frame = st.frame
        name = st.next_stop
        if not name or name == st.leaving or name not in {s.name for s in frame.stations}:
            return need_m
        if st.dwell_until_s is not None and st.dwell_until_s - now_s <= DEPART_S:
            return need_m
        est = st.newest_estimate()
        to_stop_m = forward_m(est.s_m, frame.station(name).s_m, frame.length_m if frame.closed else None)
        if frame.closed and to_stop_m > frame.length_m - 1.0:
            to_stop_m = 0.0          # at its stop, a little past the mark
        return min(need_m, max(0.0, to_stop_m) + self.margin_m + 0.05)   # its authority ends the margin short

    def _request(self, st, now_s):
        """Ask for the itinerary's next sections while what the train holds ends within its horizon (first, the
        sections its span stands on), never for one beyond another train on the way to it (that train goes first:
        a route taken over its head could hold the track it needs); the switch moves the routes set need."""
        train, frame = st.train_id, self.frames[st.train_id]
        n, moves = len(frame.steps), []
        if not self.held[train]:
            touched = {s for s, _lo, _hi in self._seen[train]}   # where it is, not where it may run to
            for i, (name, _fwd) in enumerate(frame.steps):
                if name in touched and not self._set(train, i, moves):
                    return moves
        head_s = self.heads[train][0]
        ahead = look_ahead(frame, head_s, self.spans, train)
        first_m = ahead.trains[0][1] if ahead.trains else inf   # to the nearest other train on the way
        need_m = self._need_m(st, now_s)
        while self._held_end_m(st) < need_m:
            here, count = self._chain(train)
            if count >= n or (not frame.closed and here + count >= n):
                break
            step = (here + count) % n
            if count and self._to_step_m(train, step) > first_m:
                break
            if count and self.fixed_blocks and not self._can_clear(st, step, head_s, first_m):
                break
            if not (self._set_run(train, step, moves, head_s, first_m) if st.setup.legs else
                    self._set(train, step, moves)):
                break
        return moves

    def _set_run(self, train, step, moves, head_s, first_m):
        """On a line trains reverse on, set the steps from `step` to the next place a train can wait (a section with
        a station, or its leg's end) all together or none, and only while no other train stands on that place or
        holds a route into it, nor beyond another train on the way (`first_m` from its head at `head_s`): a train
        never holds single track it may not leave, and never runs into a terminus track another train will come out
        of, so no two trains meet head on between passing places."""
        frame = self.frames[train]
        end = step
        while end < len(frame.steps) - 1 and frame.steps[end][0] not in self._waits:
            end += 1
        place = frame.steps[end][0]
        unseen = [t for t in self.frames if t not in self.spans]
        if unseen:
            self.refused[train] = f"train {unseen[0]} is not located: it may stand on the way"
            return False
        why = "" if self.dispatch is None else self.dispatch.refusal(train, place)
        if why:
            self.refused[train] = why
            return False
        if frame.starts_m[end] - head_s > first_m:
            self.refused[train] = f"another train is on the way to section {place}, where it would wait"
            return False
        taken = [t for t, span in self.spans.items() if t != train and any(s == place for s, _lo, _hi in span)] + \
            [r.train for r in self.interlocking.routes_of_section(place) if r.train != train]
        if taken:
            self.refused[train] = f"section {place}, where it would wait, is taken by train {taken[0]}"
            return False
        legs_before, set_ids, run_moves = dict(self.interlocking.switch_leg), [], []
        for i in range(step, end + 1):
            route_id = self._set(train, i, run_moves)
            if route_id is None:
                for route_id in set_ids:   # refused: the run's routes go, its switches are commanded nowhere
                    self.interlocking.routes.pop(route_id, None)
                    self.held[train].pop(route_id, None)
                self.interlocking.switch_leg.update(legs_before)
                return False
            set_ids.append(route_id)
        moves.extend(run_moves)
        if self.dispatch is not None:
            self.dispatch.moved(train, place)
        return True

    def _can_clear(self, st, step, head_s, first_m):
        """Under fixed blocks, whether `st`'s train, given step `step` of its itinerary, could get clear beyond it:
        a switch or crossing is taken only with the block past it clear and room there for the train and its margin
        before the nearest train on the way, so no train holds a junction it cannot leave while the trains it waits
        for need that junction (a ring of holds locked up). Moving block needs no such rule: its trains close up
        behind each other, and a junction held early lets its switch move before the train is near."""
        frame, sections = self.frames[st.train_id], self.network.graph.sections
        n = len(frame.steps)
        end, k = step, 0
        while k < n and sections[frame.steps[end][0]].piece:
            end, k = (end + 1) % n, k + 1
            if not frame.closed and end == 0:
                return True      # the line ends in the junction: its buffer stop is the train's place to wait
        if k == 0:
            return True          # plain track: the train waits on it
        room_m = st.setup.profile.length_m + self.margin_m
        if self.fixed_blocks:
            name, fwd = frame.steps[end]
            cuts = section_blocks(sections[name])
            lo, hi = cuts[0] if fwd else cuts[-1]
            room_m = max(room_m, hi - lo)
        return self._to_step_m(st.train_id, end) + room_m <= first_m

    def _to_step_m(self, train, step):
        """From the train's front-most plausible head to the start of `step` of its itinerary, along it (negative
        where the step starts behind that head, within its reach)."""
        frame = self.frames[train]
        head_s, reach_m = self.heads[train][0], self.reach[train]
        if not frame.closed:
            return frame.starts_m[step] - head_s
        return forward_m(head_s - reach_m, frame.starts_m[step], frame.length_m) - reach_m

    def _set(self, train, i, moves):
        """Ask the interlocking for step `i` of `train`'s itinerary; the route's id when set (its switch moves added
        to `moves`), None when refused."""
        route_id = f"{train}/{self._route_ids + 1}"
        outcome = self.interlocking.set_route(route_id, train, (self.frames[train].steps[i],), self.spans)
        if not outcome.ok:
            self.refused[train] = outcome.reason
            return None
        self._route_ids += 1
        self.refused[train] = ""
        moves.extend(outcome.moves)
        self.held[train][route_id] = i
        return route_id

    def _held_end_m(self, st):
        """Distance from the train's front-most plausible head to the end of the sections held for it in a row
        from its rear-most plausible head, along its itinerary: 0 when that row does not reach its front-most head."""
        train, frame = st.train_id, self.frames[st.train_id]
        if not self.held[train]:
            return 0.0
        here, count = self._chain(train)
        if count == 0:
            return 0.0
        if count >= len(frame.steps):
            return frame.length_m
        head_s = self.heads[train][0]
        back_s = head_s - self.reach[train]
        start = frame.starts_m[here]
        into = self.reach[train] + (forward_m(start, back_s, frame.length_m) if frame.closed else back_s - start)
        ahead = sum(self.network.graph.sections[frame.steps[(here + k) % len(frame.steps)][0]].length_m
                    for k in range(count))
        return max(0.0, ahead - into)

    def turn(self, st, route, now_s):
        """`st`'s train reverses onto `route`: the routes it holds are released (nothing held the old way survives);
        its span (read now, from its estimate before the turn) stays an obstacle until it is located again."""
        train = st.train_id
        span = self._span(st, now_s)
        for read in (self.heads, self.reach, self._rears, self._seen):
            read.pop(train, None)
        self.kept[train] = span or self.kept.get(train, ())
        for route_id in [r.id for r in self.interlocking.routes.values() if r.train == train]:
            del self.interlocking.routes[route_id]
        self.held[train] = {}
        self.frames[train] = route

    # --- per train --------------------------------------------------------------------------------------------------

    def clear_of(self, st, auth, now_s, leader=None):
        """`auth` cut to where `st`'s authority ends on the network, its margin off; `leader` (the train the policy
        followed) counts here only where it stands on a switch or crossing or off `st`'s itinerary: on the
        itinerary's plain track the policy has bounded it already, with the leader's motion (departure control)."""
        commanded = self.interlocking.switch_leg   # a detection is believed only where it shows what was commanded
        detected = {w: leg if leg == commanded.get(w) else None for w, leg in self.detection(now_s).items()}
        limit = self.limit(st, detected, None if leader is None else leader.train_id)
        if limit.distance_m - self.margin_m < auth.distance_m:
            return auth.cut_to(max(0.0, limit.distance_m - self.margin_m), limit.reason)
        return auth

    def limit(self, st, detected_legs, leader=None) -> NetworkLimit:
        """Where `st`'s authority ends on the network, from its front-most plausible head (the span of train
        `leader` taken only where it is on a switch or crossing or off `st`'s itinerary)."""
        train = st.train_id
        if train not in self.heads:
            return NetworkLimit(0.0, "not located on the network")
        head_s = self.heads[train][0]
        frame = self.frames[train]
        held_m = self._held_end_m(st)
        why = self.refused[train]
        best = NetworkLimit(held_m, f"the end of the route it holds ({why})" if why else
                            "the end of the route the interlocking holds for it")
        spans = self.spans
        reach_m = self.reach[train]
        if self.fixed_blocks:   # no train is followed by its motion: the first occupied section's signal bounds it
            net = fixed_block_limit(frame, head_s, train, spans, detected_legs, reach_m=reach_m)
            return net if net.distance_m < best.distance_m else best
        if leader in spans:
            sections, on_route = self.network.graph.sections, {name for name, _f in frame.steps}
            spans = dict(spans)
            spans[leader] = tuple(iv for iv in spans[leader] if sections[iv[0]].piece or iv[0] not in on_route)
        net = network_limit(frame, head_s, train, spans, detected_legs, reach_m)
        return net if net.distance_m < best.distance_m else best

    def frame_spans(self, st):
        """(train_id, head_s, tail_s) in `st`'s frame of every other train's span on a section of its itinerary, one
        per section (what the fixed-block policy reads as track circuits there: where the train is, widened by its
        uncertainty, not where it may have run since its data, which is a bound for the network limit)."""
        frame = self.frames[st.train_id]
        out = []
        for train, intervals in self._seen.items():
            if train == st.train_id:
                continue
            for name, lo, hi in intervals:
                a, b = frame.s_of(name, lo), frame.s_of(name, hi)
                if a is not None and b is not None:
                    out.append((train, max(a, b), min(a, b)))
        return tuple(out)

    def leader(self, st, states):
        """The train ahead of `st` on its itinerary whose head lies on it (the one its policy follows), or None."""
        frame = self.frames[st.train_id]
        if st.train_id not in self.heads:
            return None
        head_s = self.heads[st.train_id][0]
        best, best_d = None, None
        for other in states:
            if other is st or other.train_id not in self.heads:
                continue
            _s, name, offset = self.heads[other.train_id]
            s = frame.s_of(name, offset)
            if s is None or dict(frame.steps)[name] != dict(self.frames[other.train_id].steps)[name]:
                continue
            d = forward_m(head_s, s, frame.length_m if frame.closed else None)
            if not frame.closed and s < head_s:
                continue
            if best_d is None or d < best_d:
                best, best_d = other, d
        return best

    def picture_for(self, leader, follower):
        """`leader`'s picture moved into `follower`'s frame: its head where the follower's itinerary has it."""
        pic = leader.picture()
        frame = self.frames[follower.train_id]
        name, offset = self.frames[leader.train_id].locate(pic.s_m)
        s = frame.s_of(name, offset)
        return pic if s is None else TrainPicture(pic.train_id, s, pic.sigma_s_m, pic.v_mps, pic.data_t_s,
                                                  pic.profile, pic.ahead_m, pic.behind_m)

    def followers(self, st, states):
        """The trains whose leader is `st`."""
        return [other for other in states if other is not st and self.leader(other, states) is st]


def network_routes(layout, trains, params, policy, estimators):
    """The NetworkRoutes of a track network's zone (`trains`: id -> TrainState, each setup with its itinerary; a
    `policy` that signals blocks gets a signal at every section's entry; `estimators` make the fresh estimator of a
    train that reverses), or None on a single path."""
    if not getattr(layout, "is_network", False):
        return None
    routes = NetworkRoutes(layout, {st.train_id: st.setup.itinerary for st in trains.values()}, params.k_sigma,
                           params.margin_m, fixed_blocks=policy.uses_blocks)
    if any(st.setup.legs for st in trains.values()):
        routes.turns = Turns(routes, estimators, params.k_sigma)
        estimators.facing = routes.turns
        routes.dispatch = LineDispatch(layout.graph, {t: st.setup.legs for t, st in trains.items()}, routes._waits)
    return routes
