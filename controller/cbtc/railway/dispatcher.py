"""Automatic routing on a track network: which route each train asks the interlocking for next, without deadlock.

A plan is a train's stops in order, each a tuple of stations it may use (the two platforms of a passing loop, the
tracks of a terminus), repeated round. Trains rest only at stations; a route runs from the station a train stands at
to one of its next stop's stations, forwards or, reversing at the station, backwards. Before a train is given a route
the dispatcher asks whether the railway stays live: in the abstract state where that train already stands at its
destination (a train on its way counts as there), is there an order of moves, each to a free station over track no
standing train blocks, in which every train reaches its next stop `rounds` times? If not, the move could lead to
gridlock (a single line with both ends and the loop between full of trains facing each other) and it is not offered.
"""

from dataclasses import dataclass
from functools import lru_cache

from cbtc.railway.interlocking import find_routes


@dataclass(frozen=True)
class Move:
    """A route a train may ask for: to `station`, over `steps`; `reverse` when it first reverses where it stands."""
    station: str
    steps: tuple
    reverse: bool


class Dispatcher:
    def __init__(self, graph, stations, plans, rounds=2, max_steps=12):
        """`stations`: name -> (section, offset_m); `plans`: train -> [tuple of station names, ...]."""
        self.graph = graph
        self.stations = dict(stations)
        self.plans = {t: [tuple(stop) for stop in plan] for t, plan in plans.items()}
        for t, plan in self.plans.items():
            for stop in plan:
                for name in stop:
                    if name not in self.stations:
                        raise ValueError(f"train {t}'s plan names station {name!r}, which the layout does not have")
        self.rounds = rounds
        self.max_steps = max_steps
        self._between = {}

    def _routes(self, a, b):
        """[(forward at a, steps)] of routes from station a's section to station b's, in both directions."""
        key = (a, b)
        if key not in self._between:
            sa, sb = self.stations[a][0], self.stations[b][0]
            found = []
            for forward in (True, False):
                for steps in find_routes(self.graph, (sa, forward), sb, self.max_steps):
                    found.append((forward, steps))
            self._between[key] = found
        return self._between[key]

    def _open(self, a, b, standing):
        """Some route from a to b crosses no section a train stands on (a and b themselves aside)."""
        blocked = {self.stations[s][0] for s in standing}
        ends = {self.stations[a][0], self.stations[b][0]}
        return any(not ({s for s, _f in steps} - ends) & blocked for _fwd, steps in self._routes(a, b))

    def live(self, at, index):
        """True when from trains at stations `at` (train -> station) with plan positions `index` (train -> index of
        the next stop) every train can reach its next stop `rounds` times in some order of moves."""
        trains = tuple(sorted(at))
        need = self.rounds

        @lru_cache(maxsize=None)
        def search(where, idx, done):
            if all(d >= need for d in done):
                return True
            standing = set(where)
            for i, t in enumerate(trains):
                if done[i] >= need:
                    continue
                plan = self.plans[t]
                stop = plan[idx[i] % len(plan)]
                for station in stop:
                    if station in standing and station != where[i]:
                        continue
                    if station != where[i] and not self._open(where[i], station, standing - {where[i]}):
                        continue
                    nw = where[:i] + (station,) + where[i + 1:]
                    ni = idx[:i] + (idx[i] + 1,) + idx[i + 1:]
                    nd = done[:i] + (done[i] + 1,) + done[i + 1:]
                    if search(nw, ni, nd):
                        return True
            return False

        return search(tuple(at[t] for t in trains), tuple(index[t] for t in trains), (0,) * len(trains))

    def moves(self, train, at, index, forward):
        """The routes `train`, standing at station `at[train]` facing `forward`, may ask for now to its next stop,
        in order of preference (no reversal first, then the shortest), each keeping the railway live."""
        plan = self.plans[train]
        stop = plan[index[train] % len(plan)]
        here = at[train]
        others = {s for t, s in at.items() if t != train}
        out = []
        for station in stop:
            if station in others:
                continue
            after_at = dict(at, **{train: station})
            after_index = dict(index, **{train: index[train] + 1})
            if not self.live(after_at, after_index):
                continue
            for fwd, steps in self._routes(here, station):
                out.append(Move(station, steps, fwd != forward))
        out.sort(key=lambda m: (m.reverse, len(m.steps)))
        return out
