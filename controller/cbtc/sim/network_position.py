"""Where a simulated train truly is on a track network: the steps its body runs over and its head's coordinate along
them. It moves by distances (negative: rolling back), through switches as their blades truly lie, and reverses; what
it meets is told, not hidden: a buffer stop stops it, a switch whose blades are moving or set against a trailing move
derails it (it stays where it is, and `derailed` says where and why)."""

from cbtc.railway.track_graph import Route

KEEP_BEHIND_M = 0.5   # history kept behind the tail, beyond the train's length


class NetworkPosition:
    def __init__(self, graph, step, head_m, length_m):
        """A train of `length_m` with its head `head_m` into the step (section, forward)."""
        self.graph = graph
        self.steps = [tuple(step)]
        self.head_m = float(head_m)
        self.length_m = float(length_m)
        self.derailed = ""
        self._route = None

    def _chain(self):
        if self._route is None:
            self._route = Route(self.graph, self.steps)
        return self._route

    @property
    def head(self):
        """(section, offset_m from the section's start, forward) of the head."""
        route = self._chain()
        name, forward = self.steps[-1]
        into = self.head_m - route.starts_m[-1]
        length = self.graph.sections[name].length_m
        return name, (into if forward else length - into), forward

    def head_into_m(self):
        """How far the head is into its step, in its direction of travel."""
        return self.head_m - self._chain().starts_m[-1]

    def xy_m(self):
        name, offset, _fwd = self.head
        return self.graph.sections[name].path.xy_m(offset)

    def advance(self, d_m, physical_legs):
        """Move the head `d_m` along (negative: back); `physical_legs` maps switch -> the leg its blades lie in (None
        while moving). Returns the distance truly moved."""
        if self.derailed or d_m == 0.0:
            return 0.0
        start = self.head_m
        self.head_m += d_m
        if d_m > 0.0:
            self._run_on(physical_legs)
        else:
            self._roll_back(physical_legs)
        self._trim()
        return self.head_m - start

    def _run_on(self, legs):
        while self.head_m > self._chain().length_m:
            here = self.steps[-1]
            ways = self.graph.next_steps(*here, legs)
            if not ways:
                self.head_m = self._chain().length_m
                if self.graph.next_steps(*here):
                    self.derailed = f"ran into switch {self._switch_at(here)} not set for it"
                return
            self.steps.append(ways[0])
            self._route = None

    def _roll_back(self, legs):
        self._extend_behind(legs)
        while len(self.steps) > 1 and self.head_m < self._chain().starts_m[-1]:
            self.steps.pop()          # the head has rolled back into the step before
            self._route = None

    def _extend_behind(self, legs):
        while self.head_m - self.length_m < 0.0:
            first, forward = self.steps[0]
            ways = self.graph.next_steps(first, not forward, legs)
            if not ways:
                if self.graph.next_steps(first, not forward):
                    self.derailed = f"rolled back into switch {self._switch_at((first, not forward))} not set for it"
                self.head_m = self.length_m     # the tail against the buffer stop (or the switch)
                return
            name, fwd = ways[0]
            self.steps.insert(0, (name, not fwd))
            self.head_m += self.graph.sections[name].length_m
            self._route = None

    def _switch_at(self, step):
        node = self.graph.node_at((step[0], "end" if step[1] else "start"))
        return node.switch or "?"

    def _trim(self):
        while len(self.steps) > 1:
            first = self.graph.sections[self.steps[0][0]].length_m
            if self.head_m - self.length_m - KEEP_BEHIND_M < first:
                break
            self.steps.pop(0)
            self.head_m -= first
            self._route = None

    def reverse(self):
        """Run the other way: the tail becomes the head, every step is run backwards."""
        route = self._chain()
        self.steps = [(name, not fwd) for name, fwd in reversed(self.steps)]
        self.head_m = route.length_m - (self.head_m - self.length_m)
        self._route = None

    def span(self, widen_m=0.0):
        """((section, lo_m, hi_m), ...) the train covers, widened by `widen_m` both ways (ahead, onto every way the
        track could take it, whatever the switches)."""
        route = self._chain()
        lo, hi = max(0.0, self.head_m - self.length_m - widen_m), self.head_m + widen_m
        out = []
        for (name, forward), start in zip(route.steps, route.starts_m):
            length = self.graph.sections[name].length_m
            a, b = max(lo, start), min(hi, start + length)
            if a <= b:
                out.append((name, a - start, b - start) if forward else (name, start + length - b,
                                                                          start + length - a))
        excess = hi - route.length_m
        if excess > 0:
            for name, forward in self.graph.next_steps(*route.steps[-1]):
                length = self.graph.sections[name].length_m
                out.append((name, 0.0, min(excess, length)) if forward else (name, max(0.0, length - excess), length))
        return tuple(out)
