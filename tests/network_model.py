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


class RunningTrain(NetworkPosition):
    """A model train that may come round again (the simulator's true position on a network), with the uncertainty
    its span is widened by."""

    def __init__(self, graph, step, head_m, length_m, sigma_m):
        super().__init__(graph, step, head_m, length_m)
        self.sigma_m = sigma_m

    def span(self, widen_m=None):
        return super().span(self.sigma_m if widen_m is None else widen_m)


class Train(RunningTrain):
    """A model train for the interlocking's properties: it keeps every step it has run and never runs one twice (a
    buffer stop, a switch set against it or track it has run already stops it)."""

    def advance(self, d_m, switch_legs):
        self.head_m += d_m
        while True:
            route = self.graph.route(self.steps)
            if self.head_m <= route.length_m:
                return
            nxt = self.graph.next_steps(*self.steps[-1], switch_legs)
            nxt = [s for s in nxt if s[0] not in {n for n, _f in self.steps}]
            if not nxt:
                self.head_m = route.length_m
                return
            self.steps.append(nxt[0])
            self._route = None


def world_now(machines, trains, now_s):
    """The switches moved on to `now_s`: (detected legs, the legs the blades lie in, every train's widened span)."""
    for m in machines.values():
        m.step(now_s)
    return ({w: m.detected(now_s) for w, m in machines.items()}, {w: m.physical(now_s) for w, m in machines.items()},
            {t: tr.span() for t, tr in trains.items()})


def truth_spans(trains, sigma_m):
    """Every train's span widened by `sigma_m` (0: its true extent)."""
    out = {}
    for t, train in trains.items():
        keep = train.sigma_m
        train.sigma_m = sigma_m
        out[t] = train.span()
        train.sigma_m = keep
    return out
