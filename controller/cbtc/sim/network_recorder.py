"""The recorder of a simulated run on a track network: truth of trains and switches, and the figures made from it.

Truth decides. A collision starts when two trains' true spans overlap on a section or stand on one switch or crossing
(cbtc.sim.network_truth), whoever moved. An authority overrun is a train's own forward motion taking its head within
the safety margin of the true room ahead on its route (another train's span on it or fouling it, the end of the track).
A switch violation is a train on a switch whose blades do not lie in its leg (moving, or set the other way), or an
authority a board holds that reaches over a switch not detected in its route's leg for longer than GRACE_S.
`granted_beyond_m` is how far a board's authority reached past the true room ahead on its route (the nearest true span
of another train on it or fouling it). An overtake is a train passing a common point of the network twice with another
train not passing it between (on the passing loop: a train overtaken while it dwells at the loop's platform).
"""

from math import inf

from cbtc.railway.ahead import look_ahead
from cbtc.sim.network_truth import collisions
from cbtc.sim.recorder import board_granted_m

STRANDED_S = 20.0


def rounds(train):
    """The rounds a simulated train has made of its itinerary: laps of a closed one, of its legs on a line."""
    if train.legs:
        return train.turns // len(train.legs)
    return int(train.travelled_m // train.route.length_m) if train.route.closed else 0
GRACE_S = 0.5   # an authority over a switch whose detection is lost is a violation once the zone has had this long
#                 to withdraw it (a cycle and a command's way, with room to spare)


class NetworkRecorder:
    def __init__(self, sim):
        self.sim = sim
        self.network = sim.config.layout
        self.graph = self.network.graph
        n = len(sim.trains)
        self._margin_m = sim.config.params.margin_m
        self.collisions = [0] * n      # per train, the collisions it was in
        self.collision_count = 0
        self.switch_violations = [0] * n
        self.granted_beyond_m = [-inf] * n
        self._colliding = set()
        self._on_wrong = [False] * n
        self._over_since = [None] * n      # since when a board's authority covers a switch not detected in its leg
        self._over_counted = [False] * n
        self._overruns = [0] * n
        self._overrunning = [False] * n
        self._t_first_s = self._t_last_s = None
        self._moving_last_s = None
        self._window = [[] for _ in range(n)]
        # a common point: the start of a section every itinerary runs, the first such in the layout's order
        common = set.intersection(*[{s for s, _f in t.route.steps} for t in sim.trains])
        self.mark = next((s for s in self.graph.sections if s in common and not self.graph.sections[s].piece), None)
        if any(t.legs for t in sim.trains):
            self.mark = None   # trains that reverse run each section both ways: no overtake is counted
        self._mark_s = [None if self.mark is None else t.route.s_of(self.mark, 0.0 if dict(t.route.steps)[self.mark]
                                                                    else self.graph.sections[self.mark].length_m)
                        for t in sim.trains]
        self._passes = []          # train indices in the order they passed the mark
        self._last_travel = [t.travelled_m for t in sim.trains]

    def true_spans(self):
        """train id -> its true span on the network."""
        return {t.train_id: t.route.span(t.travelled_m + t.s0_m - t.length_m, t.travelled_m + t.s0_m)
                for t in self.sim.trains}

    def sample(self, now_s):
        sim = self.sim
        if self._t_first_s is None:
            self._t_first_s = now_s
        self._t_last_s = now_s
        spans = self.true_spans()
        pairs = {(a, b) for a, b, _sa, _sb in collisions(self.graph, spans)}
        index = {t.train_id: i for i, t in enumerate(sim.trains)}
        for a, b in pairs - self._colliding:   # a new collision: counted once, and for each of its two trains
            self.collision_count += 1
            self.collisions[index[a]] += 1
            self.collisions[index[b]] += 1
        self._colliding = pairs
        machines = sim.switches
        for i, train in enumerate(sim.trains):
            if train.v_mps > 0.0:
                self._moving_last_s = now_s
            window = self._window[i]
            window.append((now_s, train.travelled_m))
            while window and window[0][0] < now_s - STRANDED_S:
                window.pop(0)
            wrong = any(self.graph.sections[name].switch and machines[self.graph.sections[name].switch].physical(
                now_s) != self.graph.sections[name].leg for name, _lo, _hi in spans[train.train_id])
            if wrong and not self._on_wrong[i]:
                self.switch_violations[i] += 1
            self._on_wrong[i] = wrong
            head_s = train.s0_m + train.travelled_m
            granted_m = board_granted_m(train, now_s) or 0.0
            ahead = look_ahead(train.route, head_s, spans, train.train_id)
            room_m = min(ahead.trains[0][1] if ahead.trains else inf, ahead.end_m)
            if granted_m > 0.0 and room_m < inf:
                self.granted_beyond_m[i] = max(self.granted_beyond_m[i], granted_m - room_m)
            over = any(d < granted_m and machines[w].detected(now_s) != leg for w, d, leg in ahead.switches
                       if d > 0.0)
            since = self._over_since[i] = (self._over_since[i] or now_s) if over else None
            if over and now_s - since > GRACE_S and not self._over_counted[i]:
                self.switch_violations[i] += 1
            self._over_counted[i] = over and (self._over_counted[i] or now_s - since > GRACE_S)
            moved = train.travelled_m > self._last_travel[i]
            overrunning = moved and room_m < self._margin_m
            if overrunning and not self._overrunning[i]:
                self._overruns[i] += 1
            self._overrunning[i] = overrunning
            self._mark_pass(i, train)

    def _mark_pass(self, i, train):
        mark_s = self._mark_s[i]
        before, now = self._last_travel[i], train.travelled_m
        self._last_travel[i] = now
        if mark_s is None or now <= before:
            return
        length = train.route.length_m
        a, b = train.s0_m + before, train.s0_m + now
        k = (a - mark_s) // length + 1 if train.route.closed else 0
        if mark_s + k * length <= b and (train.route.closed or a < mark_s <= b):
            self._passes.append(i)

    def overtakes(self):
        """Per train, how often it passed the common point twice with some other train not passing it between."""
        counts = [0] * len(self.sim.trains)
        last = {}
        for k, i in enumerate(self._passes):
            if i in last:
                between = set(self._passes[last[i] + 1:k])
                counts[i] += sum(1 for j in range(len(self.sim.trains)) if j != i and j not in between
                                 and j in last and last[j] < last[i])
            last[i] = k
        return counts

    def _train_row(self, i, train, view, overtakes):
        """One train's row of the summary."""
        state = view.train(train.train_id)
        zstate = self.sim.zc.state_of(train.train_id)
        window = self._window[i]
        stranded = bool(window) and window[-1][1] - window[0][1] < 0.05 and \
            window[-1][0] - window[0][0] >= STRANDED_S - 0.1
        made = zstate.dwells
        plan = tuple(zstate.setup.stops)
        return {
            "train": train.train_id,
            "plan": list(plan),
            # made every stop of its plan and still running it: a train standing for good is deadlocked
            "plan_completed": made >= len(plan) and not stranded,
            "laps": rounds(train),
            "mean_lap_s": None,
            "mean_gap_m": None,
            "min_gap_m": None,
            "distance_m": round(train.travelled_m, 3),
            "station_stops": state.station_stops,
            "collisions": self.collisions[i],
            "authority_overruns": self._overruns[i],
            "switch_violations": self.switch_violations[i],
            "overtakes": overtakes[i],
            "granted_beyond_m": None if self.granted_beyond_m[i] == -inf else round(self.granted_beyond_m[i], 4),
            "stranded": stranded,
            "estimation_rmse_m": None,
            "commands_rejected_onboard": train.obu.rejected,
            "emergency_trips": train.obu.trips,
            "reports_rejected": state.reports_rejected,
        }

    def summary(self):
        sim = self.sim
        view = sim.zc.view(sim.scheduler.now_s())
        overtakes = self.overtakes()
        trains = [self._train_row(i, train, view, overtakes) for i, train in enumerate(sim.trains)]
        beyond = [b for b in self.granted_beyond_m if b > -inf]
        started = self._t_first_s is not None
        return {
            "layout": self.network.name,
            "policy": sim.policy.name,
            "estimator": sim.config.estimator,
            "seed": sim.config.seed,
            "simulated_s": round(self._t_last_s, 3) if started else 0.0,
            "trains": trains,
            "collisions": self.collision_count,
            "authority_overruns": sum(self._overruns),
            "switch_violations": sum(self.switch_violations),
            "overtakes": sum(overtakes),
            "plan_completed": all(t["plan_completed"] for t in trains),
            "rolled_onto": 0,
            "granted_beyond_m": round(max(beyond), 4) if beyond else None,
            "stranded": sum(t["stranded"] for t in trains),
            "emergency_trips": sum(t.obu.trips for t in sim.trains),
            "encoder_trips": sum(t.obu.enc_fails for t in sim.trains),
            "mean_following_gap_m": None,
            "min_gap_m": None,
            "mean_lap_s": None,
            "all_standing_at_end_s": round(self._t_last_s - (self._t_first_s if self._moving_last_s is None
                                                              else self._moving_last_s), 3) if started else 0.0,
            "gridlocked": False,
        }
