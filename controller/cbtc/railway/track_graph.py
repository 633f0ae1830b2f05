"""A track network as a graph: sections (open paths) whose ends meet at nodes, switches that choose a leg.

A position on the network is (section, offset_m) with the offset measured from the section's start. A node is where
section ends meet, in two sides facing each other: a train leaving through an end on one side enters any end on the
other. A plain joint has one end a side; a switch's toe node has its two legs' starts on one side, and the switch's
position says which of them a train passes; a buffer stop has an empty side. A route is a chain of sections, each run
forwards or backwards, and flattens into one Path along which a train's coordinate runs.
"""

from bisect import bisect_right
from dataclasses import dataclass
from math import hypot, pi

from cbtc.railway.geometry import Path

START, END = "start", "end"
LEGS = ("straight", "diverging")


@dataclass(frozen=True)
class Section:
    """An open stretch of track between two nodes; a switch's leg is a section starting at the switch's toe."""
    name: str
    path: Path
    switch: str = ""      # the switch this section is a leg of, "" for plain track
    leg: str = ""         # "straight" or "diverging" for a leg
    crossing: str = ""    # the crossing this section is a track of ("a" or "b", crossing the other at its middle)

    @property
    def piece(self):
        """The switch or crossing this section belongs to, "" for plain track: the sections of one piece foul each
        other, so one train on any of them occupies them all."""
        return self.switch or self.crossing

    @property
    def length_m(self):
        return self.path.length_m


@dataclass(frozen=True)
class Switch:
    """A switch: its toe, where its two legs (sections `id.straight` and `id.diverging`) start, and its hand."""
    id: str
    hand: str             # "left" or "right": the side the diverging leg turns to, seen from the toe
    toe_xy_m: tuple

    def leg_section(self, leg):
        return f"{self.id}.{leg}"


@dataclass(frozen=True)
class Node:
    """Ends meeting at one point, in two sides facing each other; `switch` names the switch whose toe this is."""
    xy_m: tuple
    side_a: tuple         # ends (section, "start"|"end"), all with one outward heading
    side_b: tuple         # the ends facing them; empty at a buffer stop
    switch: str = ""


def reversed_path(path: Path) -> Path:
    """The same track run from its end to its start."""
    segments = []
    for seg in reversed(path.segments):
        segments.append(seg if seg[0] == "straight" else ("arc", seg[1], -seg[2]))
    x, y, h = path.end_pose
    return Path(segments, x, y, h + pi)


class TrackGraph:
    """Sections, switches and the nodes joining them; pure values, built by cbtc.railway.network_dict."""

    def __init__(self, sections, switches, nodes):
        self.sections = {s.name: s for s in sections}
        self.switches = {w.id: w for w in switches}
        self.nodes = tuple(nodes)
        self._node_of = {}
        self._across = {}
        for node in self.nodes:
            for here, there in ((node.side_a, node.side_b), (node.side_b, node.side_a)):
                for end in here:
                    self._node_of[end] = node
                    self._across[end] = tuple(there)

    @property
    def length_m(self):
        return sum(s.length_m for s in self.sections.values())

    def piece_mates(self, section):
        """The other sections of the switch or crossing `section` belongs to (none for plain track)."""
        piece = self.sections[section].piece
        return [n for n, s in self.sections.items() if piece and s.piece == piece and n != section]

    def node_at(self, end):
        """The node the section end (section, "start"|"end") lies on."""
        return self._node_of[end]

    def across(self, end):
        """The ends a train leaving through `end` may enter, whatever the switches' positions."""
        return self._across.get(end, ())

    def next_steps(self, section, forward, switch_legs=None):
        """Where a train on `section` running `forward` (or backwards) goes next: a tuple of (section, forward).

        `switch_legs` maps switch id -> "straight"|"diverging": at a toe only the set leg is offered, and a train
        coming off a leg that is not set has nowhere to go. None: every leg is offered, set or not.
        """
        leaving = (section, END if forward else START)
        out = []
        node = self._node_of.get(leaving)
        for end in self.across(leaving):
            if node is not None and node.switch and switch_legs is not None:
                sw_section = self.sections[end[0]]
                if sw_section.switch == node.switch and sw_section.leg != switch_legs.get(node.switch):
                    continue
            out.append((end[0], end[1] == START))
        if node is not None and node.switch and switch_legs is not None:
            leg = self.sections[section]
            if leg.switch == node.switch and leg.leg != switch_legs.get(node.switch):
                return ()          # trailing through a switch set against the train: a run-through, not a move
        return tuple(out)

    def project(self, x_m, y_m, sections=None):
        """(section, offset_m, distance_m) of the track point nearest to (x_m, y_m) on `sections` (the ones the
        train can be on; None: every section): an IPS fix lands on the track the train may be on, not the nearest."""
        best = None
        for name in (self.sections if sections is None else sections):
            path = self.sections[name].path
            offset = path.project(float(x_m), float(y_m))
            px, py = path.xy_m(offset)
            d = hypot(px - x_m, py - y_m)
            if best is None or d < best[2]:
                best = (name, offset, d)
        return best

    def is_closed_cycle(self, steps):
        """True when the route `steps` returns to where it started, running on in the same direction."""
        section, forward = steps[-1]
        return steps[0] in self.next_steps(section, forward)

    def route(self, steps):
        """The Route along `steps`, a sequence of (section, forward) each entered from the one before."""
        return Route(self, steps)


class Route:
    """A chain of (section, forward) steps; `s_m` runs from the first section's entry along the chain."""

    def __init__(self, graph: TrackGraph, steps):
        self.graph = graph
        self.steps = tuple((str(name), bool(fwd)) for name, fwd in steps)
        if not self.steps:
            raise ValueError("a route needs at least one section")
        for (a, fa), nxt in zip(self.steps, self.steps[1:]):
            if nxt not in graph.next_steps(a, fa):
                raise ValueError(f"section {nxt[0]} does not follow {a} ({'forwards' if fa else 'backwards'})")
        self.starts_m = []
        s = 0.0
        for name, _fwd in self.steps:
            self.starts_m.append(s)
            s += graph.sections[name].length_m
        self.length_m = s
        self.closed = graph.is_closed_cycle(self.steps)

    def locate(self, s_m):
        """(section, offset_m) of route coordinate `s_m` (clipped to the route; modulo its length when closed)."""
        s = s_m % self.length_m if self.closed else min(max(s_m, 0.0), self.length_m)
        i = len(self.starts_m) - 1
        while i > 0 and self.starts_m[i] > s:
            i -= 1
        name, forward = self.steps[i]
        into = s - self.starts_m[i]
        length = self.graph.sections[name].length_m
        return name, (into if forward else length - into)

    def s_of(self, section, offset_m):
        """Route coordinate of (section, offset_m), or None when the route does not run over that section."""
        for (name, forward), start in zip(self.steps, self.starts_m):
            if name == section:
                length = self.graph.sections[name].length_m
                return start + (offset_m if forward else length - offset_m)
        return None

    def step_at(self, s_m):
        """The index of the step route coordinate `s_m` lies on (clipped to the route; modulo its length if closed)."""
        s = s_m % self.length_m if self.closed else min(max(s_m, 0.0), self.length_m)
        return max(0, bisect_right(self.starts_m, s) - 1)

    def span(self, tail_s_m, head_s_m):
        """((section, lo_m, hi_m), ...) of the stretch from route coordinate `tail_s_m` forwards to `head_s_m`: on a
        closed route taken round (the whole round at most), on an open one clipped to the route."""
        extent = head_s_m - tail_s_m
        if extent <= 0.0:
            return ()
        if self.closed:
            if extent >= self.length_m:
                return tuple((name, 0.0, self.graph.sections[name].length_m) for name, _f in self.steps)
            lo = tail_s_m % self.length_m
            pieces = [(lo, min(lo + extent, self.length_m))]
            if lo + extent > self.length_m:
                pieces.append((0.0, lo + extent - self.length_m))
        else:
            pieces = [(max(tail_s_m, 0.0), min(head_s_m, self.length_m))]
        out = []
        for a, b in pieces:
            for (name, forward), start in zip(self.steps, self.starts_m):
                length = self.graph.sections[name].length_m
                x, y = max(a, start), min(b, start + length)
                if x < y or (x == y and a == b == x):
                    out.append((name, x - start, y - start) if forward else (name, start + length - y,
                                                                              start + length - x))
        return tuple(out)

    def path(self) -> Path:
        """The route as one Path from the first section's entry; closed when the route is a cycle."""
        segments = []
        for name, forward in self.steps:
            p = self.graph.sections[name].path
            segments.extend((p if forward else reversed_path(p)).segments)
        first, forward = self.steps[0]
        p = self.graph.sections[first].path
        x, y, h = (p if forward else reversed_path(p)).start_pose
        return Path(segments, x, y, h, closed=self.closed)

    def xy_m(self, s_m):
        """(x_m, y_m) at route coordinate `s_m`, read on the section itself (no drift through the joints)."""
        name, offset = self.locate(s_m)
        return self.graph.sections[name].path.xy_m(offset)


def single_section_graph(path: Path, name="main") -> TrackGraph:
    """The graph of a layout that is one path: one section, its ends joined to each other on a loop, buffers else."""
    section = Section(name, Path(path.segments, *path.start_pose))
    x0, y0, _ = path.start_pose
    x1, y1, _ = path.end_pose
    if path.closed:
        nodes = [Node((x0, y0), ((name, END),), ((name, START),))]
    else:
        nodes = [Node((x0, y0), ((name, START),), ()), Node((x1, y1), ((name, END),), ())]
    return TrackGraph([section], [], nodes)
