"""Automatic routing on a track network: which route each train asks the interlocking for next, without deadlock.

A plan is a train's stops in order, each a tuple of stations it may use (the two platforms of a passing loop, the
tracks of a terminus), repeated round. Trains rest only at stations; a route runs from the station a train stands at
to one of its next stop's stations, forwards or, reversing at the station, backwards. The dispatcher reasons on the
abstract railway: which train stands at which station, where each is in its plan (a train on its way counts as at
its destination), and the moves between such states (a train to a free station of its next stop, over track no
standing train blocks). The states are finite, so it finds exactly those from which the railway can run for ever
with every train reaching its stops again and again (they reach a strongly connected set of states in which every
train moves), and offers a train only the moves that keep the railway in one of them: a move that could only end in
gridlock (a single line with both ends and the loop between full of trains facing each other) is never offered, and
from a good state some move always is.
"""

from dataclasses import dataclass

from cbtc.railway.interlocking import find_routes


@dataclass(frozen=True)
class Move:
    """A route a train may ask for: to `station`, over `steps`; `reverse` when it first reverses where it stands."""
    station: str
    steps: tuple
    reverse: bool


class Dispatcher:
    def __init__(self, graph, stations, plans, max_steps=12):
        """`stations`: name -> (section, offset_m); `plans`: train -> [tuple of station names, ...]."""
        self.graph = graph
        self.stations = dict(stations)
        self.plans = {t: [tuple(stop) for stop in plan] for t, plan in plans.items()}
        for t, plan in self.plans.items():
            for stop in plan:
                for name in stop:
                    if name not in self.stations:
                        raise ValueError(f"train {t}'s plan names station {name!r}, which the layout does not have")
        self.max_steps = max_steps
        self._between = {}
        self._trains = ()
        self._analysis = ({}, set())    # the reachable abstract states, and the good ones among them
        self._distance_key, self._distance = None, {}

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

    def _successors(self, state):
        """[(train index, next state)] of the abstract moves from `state` = (stations, plan positions mod length):
        a train to a free station of its next stop over track no standing train blocks (staying, if it is there)."""
        where, idx = state
        standing = set(where)
        out = []
        for i, t in enumerate(self._trains):
            plan = self.plans[t]
            for station in plan[idx[i]]:
                if station != where[i] and (station in standing or
                                            not self._open(where[i], station, standing - {where[i]})):
                    continue
                out.append((i, (where[:i] + (station,) + where[i + 1:],
                                idx[:i] + ((idx[i] + 1) % len(plan),) + idx[i + 1:])))
        return out

    def _good_states(self, start):
        """The states reachable from `start` from which the railway can run for ever with every train reaching its
        stops again and again: those that can reach a strongly connected set of states in which every train moves."""
        graph, order, seen = {}, [start], {start}
        for state in order:                      # every state reachable from the start
            graph[state] = self._successors(state)
            for _i, nxt in graph[state]:
                if nxt not in seen:
                    seen.add(nxt)
                    order.append(nxt)
        fair = set()
        for component in _components(graph):
            movers = {i for st in component for i, nxt in graph[st] if nxt in component}
            if len(movers) == len(self._trains):
                fair |= component
        good, back = set(fair), {}
        for state, nexts in graph.items():
            for _i, nxt in nexts:
                back.setdefault(nxt, []).append(state)
        frontier = list(fair)
        while frontier:
            for prev in back.get(frontier.pop(), ()):
                if prev not in good:
                    good.add(prev)
                    frontier.append(prev)
        return graph, good

    def _state(self, at, index):
        self._trains = tuple(sorted(at))
        return (tuple(at[t] for t in self._trains),
                tuple(index[t] % len(self.plans[t]) for t in self._trains))

    def live(self, at, index):
        """True when from trains at stations `at` (train -> station) with plan positions `index` (train -> index of
        the next stop) the railway can run on for ever, every train reaching its stops again and again."""
        state = self._state(at, index)
        if state not in self._analysis[1]:
            self._analysis = self._good_states(state)
        return state in self._analysis[1]

    def moves(self, train, at, index, forward, first=None):
        """The routes `train`, standing at station `at[train]` facing `forward`, may ask for now to its next stop,
        in order of preference (no reversal first, then the shortest), each keeping the railway live. `first` names
        the train that has waited longest: another train is offered only moves that bring the railway closer to a
        state where `first` has a move, or keep the move it has, so no train waits for ever."""
        self.live(at, index)                  # the states reachable from here, analysed
        graph, good = self._analysis
        now, me = self._state(at, index), self._trains.index(train)
        distance = waiting = None
        if first is not None and first != train and first in at:
            distance = self._distances(self._trains.index(first))
            waiting = distance.get(now)
        out = []
        for mover, after in graph[now]:
            if mover != me or after not in good:
                continue
            if waiting is not None:   # only a move that brings `first`'s turn nearer, or keeps the one it has
                then = distance.get(after)
                if then is None or (then >= waiting and then > 0):
                    continue
            station = after[0][me]
            for fwd, steps in self._routes(at[train], station):
                out.append(Move(station, steps, fwd != forward))
        out.sort(key=lambda m: (m.reverse, len(m.steps)))
        return out

    def _distances(self, i):
        """Over the good states: how many moves of the others stand between each and one where train `i` has a good
        move (0: it has one now)."""
        graph, good = self._analysis
        key = (id(graph), i)
        if self._distance_key != key:
            back = {}
            for state in good:
                for _j, nxt in graph[state]:
                    if nxt in good:
                        back.setdefault(nxt, []).append(state)
            distance = {st: 0 for st in good if any(j == i and nxt in good for j, nxt in graph[st])}
            frontier = list(distance)
            while frontier:
                nxt_frontier = []
                for state in frontier:
                    for prev in back.get(state, ()):
                        if prev not in distance:
                            distance[prev] = distance[state] + 1
                            nxt_frontier.append(prev)
                frontier = nxt_frontier
            self._distance_key, self._distance = key, distance
        return self._distance


def _components(graph):
    """The strongly connected components of `graph` (state -> [(label, next state)]), as sets (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(graph[root]))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, it = work[-1]
            advanced = False
            for _label, nxt in it:
                if nxt not in index:
                    index[nxt] = low[nxt] = counter[0]
                    counter[0] += 1
                    stack.append(nxt)
                    on_stack.add(nxt)
                    work.append((nxt, iter(graph[nxt])))
                    advanced = True
                    break
                if nxt in on_stack:
                    low[node] = min(low[node], index[nxt])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                found.append(component)
    return found
