"""Model railways for the network tests: random LEGO lines built from pieces, and a model train that runs over a
track graph (its true position; its span, widened by an uncertainty)."""

from hypothesis import strategies as st

from cbtc.railway.layout_dict import layout_from_dict
from cbtc.sim.network_position import NetworkPosition
from cbtc.sim.network_truth import collisions  # noqa: F401  (the tests' truth is the simulator's)


def network(elements):
    """A line of LEGO pieces from `elements`: ("run", n straights), ("loop", n: a passing loop on the left),
    ("siding", a stub on the right ending at a buffer stop), ("cross", a crossing whose other track runs a straight
    to a buffer stop each side); buffer stops at both ends of the line."""
    track = [{"section": "s0", "start": {"x_m": 0.0, "y_m": 0.0, "heading_deg": 0},
              "segments": [{"piece": "straight", "count": 2}]}]
    buffers, here = ["s0.start"], "s0.end"
    for i, (kind, n) in enumerate(elements):
        if kind == "run":
            track.append({"section": f"r{i}", "from": here, "segments": [{"piece": "straight", "count": n}]})
            here = f"r{i}.end"
        elif kind == "loop":
            track += [{"switch": f"A{i}", "piece": "switch_left", "at": here},
                      {"section": f"m{i}", "from": f"A{i}.straight",
                       "segments": [{"piece": "straight", "count": n + 2}]},
                      {"switch": f"B{i}", "piece": "switch_right", "at": f"m{i}.end", "by": "straight"},
                      {"section": f"l{i}", "from": f"A{i}.diverging",
                       "segments": [{"piece": "curve_r40", "turn": "right"}, {"piece": "straight", "count": n},
                                    {"piece": "curve_r40", "turn": "right"}]}]
            here = f"B{i}.toe"
        elif kind == "cross":
            track += [{"crossing": f"X{i}", "at": here},
                      {"section": f"n{i}", "from": f"X{i}.b.end", "segments": [{"piece": "straight"}]},
                      {"section": f"o{i}", "from": f"X{i}.b.start", "segments": [{"piece": "straight"}]},
                      {"section": f"c{i}", "from": f"X{i}.a.end", "segments": [{"piece": "straight"}]}]
            buffers += [f"n{i}.end", f"o{i}.end"]
            here = f"c{i}.end"
        else:
            track += [{"switch": f"S{i}", "piece": "switch_right", "at": here},
                      {"section": f"d{i}", "from": f"S{i}.diverging",
                       "segments": [{"piece": "curve_r40", "turn": "left"}, {"piece": "straight"}]},
                      {"section": f"t{i}", "from": f"S{i}.straight", "segments": [{"piece": "straight", "count": 4}]}]
            buffers.append(f"d{i}.end")
            here = f"t{i}.end"
    track.append({"section": "end", "from": here, "segments": [{"piece": "straight", "count": 2}]})
    buffers.append("end.end")
    return layout_from_dict({"name": "random", "track": track, "buffers": buffers}, "random.yaml").graph


ELEMENTS = st.lists(st.one_of(st.tuples(st.just("run"), st.integers(1, 3)),
                              st.tuples(st.just("loop"), st.integers(1, 4)),
                              st.tuples(st.just("siding"), st.just(0)), st.tuples(st.just("cross"), st.just(0))),
                    min_size=1, max_size=5)


class Train:
    """A model train: the steps it has run (a route on the graph), its head's coordinate along them, its length and
    its uncertainty (its span is widened by it both ways)."""

    def __init__(self, graph, step, head_m, length_m, sigma_m):
        self.graph, self.steps, self.head_m = graph, [step], head_m
        self.length_m, self.sigma_m = length_m, sigma_m

    def advance(self, d_m, switch_legs):
        self.head_m += d_m
        while True:
            route = self.graph.route(self.steps)
            if self.head_m <= route.length_m:
                return
            nxt = self.graph.next_steps(*self.steps[-1], switch_legs)
            nxt = [s for s in nxt if s[0] not in {n for n, _f in self.steps}]
            if not nxt:                      # a buffer stop or a switch set against it: it stops there
                self.head_m = route.length_m
                return
            self.steps.append(nxt[0])

    def span(self):
        route = self.graph.route(self.steps)
        lo, hi = max(0.0, self.head_m - self.length_m - self.sigma_m), self.head_m + self.sigma_m
        out = []
        for (name, forward), start in zip(route.steps, route.starts_m):
            length = self.graph.sections[name].length_m
            a, b = max(lo, start), min(hi, start + length)
            if a <= b:
                out.append((name, a - start, b - start) if forward else (name, start + length - b,
                                                                          start + length - a))
        excess = hi - route.length_m
        if excess > 0:                      # ahead of the head: every way it could go, whatever the switches
            for name, forward in self.graph.next_steps(*route.steps[-1]):
                length = self.graph.sections[name].length_m
                out.append((name, 0.0, min(excess, length)) if forward else (name, max(0.0, length - excess), length))
        return tuple(out)


class RunningTrain(NetworkPosition):
    """A model train that may come round again (the simulator's true position on a network), with the uncertainty
    its span is widened by."""

    def __init__(self, graph, step, head_m, length_m, sigma_m):
        super().__init__(graph, step, head_m, length_m)
        self.sigma_m = sigma_m

    def span(self, widen_m=None):
        return super().span(self.sigma_m if widen_m is None else widen_m)


def truth_spans(trains, sigma_m):
    """Every train's span widened by `sigma_m` (0: its true extent)."""
    out = {}
    for t, train in trains.items():
        keep = train.sigma_m
        train.sigma_m = sigma_m
        out[t] = train.span()
        train.sigma_m = keep
    return out
