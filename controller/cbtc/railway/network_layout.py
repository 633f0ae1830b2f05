"""A track network layout as values: its graph of sections and switches, stations and tags on sections, IPS frame.

Positions are (section, offset_m). The zone and the simulator run on single paths (cbtc.railway.layout.Layout); a
network is read, checked, listed and drawn, and its routes flatten into paths (cbtc.railway.track_graph.Route).
"""

from dataclasses import dataclass
from math import cos, sin

from cbtc.errors import LayoutError
from cbtc.railway.geometry import Path
from cbtc.railway.layout import Block, Layout, Station, Tag

BLOCK_M = 0.8   # the fixed-block baseline's longest block on plain track: about a platform (a train, its margin)


def section_blocks(section, block_m=BLOCK_M):
    """The fixed blocks (start, end offsets) `section` is signalled as: a switch's or crossing's leg is one block
    (signals at its toe and heels); plain track is cut into equal blocks of at most `block_m`, as lineside block
    signals would cut it."""
    count = 1 if section.piece else max(1, -int(-section.length_m // block_m))
    size = section.length_m / count
    return tuple((k * size, (k + 1) * size) for k in range(count))


def block_name(section_name, k, count):
    """The name of block `k` (from the section's start) of the `count` a section is cut into: the section's own name
    when it is one block, else `section.k+1`."""
    return section_name if count == 1 else f"{section_name}.{k + 1}"


@dataclass(frozen=True)
class NetworkStation:
    name: str
    section: str
    offset_m: float        # stop point of the head of a train running the section forwards, from its start
    window_m: float
    back_offset_m: float   # ... of one running it backwards (by default as far from the section's end)

    def stop_m(self, forward):
        """The head's stop point (offset from the section's start) for a train running the section this way."""
        return self.offset_m if forward else self.back_offset_m


@dataclass(frozen=True)
class NetworkTag:
    uid: str
    section: str
    offset_m: float


class NetworkLayout:
    """A validated track network."""

    is_network = True

    def __init__(self, name, source, graph, stations, tags, ips):
        self.name = name
        self.source = source
        self.graph = graph
        self.stations = tuple(stations)
        self.tags = tuple(sorted(tags, key=lambda t: (t.section, t.offset_m)))
        self.ips = ips
        self.length_m = graph.length_m

    def xy_m(self, section, offset_m):
        """(x_m, y_m) of (section, offset_m)."""
        return self.graph.sections[section].path.xy_m(offset_m)

    def station(self, name) -> NetworkStation:
        for st in self.stations:
            if st.name == name:
                return st
        raise LayoutError(f"{self.source}: no station {name!r}; stations are {[st.name for st in self.stations]}")


def route_layout(network, steps, name=None, stops=None) -> Layout:
    """The single-path Layout a train on the route `steps` runs on: the route flattened into one path (a loop when it
    comes round), the stations on its sections (those named in `stops`, when given) at their stop points for the way
    the route runs them and the tags at their route coordinates, the fixed blocks of section_blocks (signals at the
    switches' toes and heels), the network's IPS frame. Positions convert back with Route.locate."""
    route = network.graph.route(steps)
    path = route.path()
    direction = dict(route.steps)
    stations = [Station(st.name, route.s_of(st.section, st.stop_m(direction[st.section])), st.window_m)
                for st in network.stations if st.section in direction and (stops is None or st.name in stops)]
    tags = [Tag(t.uid, route.s_of(t.section, t.offset_m)) for t in network.tags
            if route.s_of(t.section, t.offset_m) is not None]
    if route.closed:
        stations = [Station(st.name, st.s_m % route.length_m, st.window_m) for st in stations]
        tags = [Tag(t.uid, t.s_m % route.length_m) for t in tags]
    blocks = []
    for (section, fwd), start in zip(route.steps, route.starts_m):
        cuts = section_blocks(network.graph.sections[section])
        order = range(len(cuts)) if fwd else range(len(cuts) - 1, -1, -1)   # in the way the route runs it
        for k in order:
            lo, hi = cuts[k]
            blocks.append(Block(block_name(section, k, len(cuts)), start, start + hi - lo))
            start += hi - lo
    label = name or f"{network.name}:{'+'.join(s for s, _f in route.steps)}"
    return Layout(label, network.source, path, stations, tags, blocks, network.ips)


def sensor_frame(frame, back_m) -> Layout:
    """Where the sensors of a train whose head is at `s_m` on `frame` read when they ride `back_m` behind its head
    (a train running the other end first: its IPS beacon and RFID reader trail): the same coordinates, the geometry
    and tags shifted forward by `back_m` (a straight of that length leads into the path's start)."""
    path = frame.path
    x, y, h = path.start_pose
    shifted = Path((("straight", back_m),) + tuple(path.segments), x - back_m * cos(h), y - back_m * sin(h), h)
    return Layout(f"{frame.name} (sensors {back_m:.3f} m behind the head)", frame.source, shifted,
                  [Station(st.name, st.s_m + back_m, st.window_m) for st in frame.stations],
                  [Tag(t.uid, t.s_m + back_m) for t in frame.tags],
                  [Block(b.name, b.start_m + back_m, b.end_m + back_m) for b in frame.blocks], frame.ips)


def refuse_network(layout, what):
    """`layout`, or LayoutError when it is a network: `what` (a command) takes single-path layouts."""
    if getattr(layout, "is_network", False):
        raise LayoutError(f"{layout.source}: layout {layout.name} is a track network (switches and sections): {what} "
                          "takes single-path layouts (segments:) for now; `cbtc layout show` reads and draws networks; "
                          "pick a loop or a line from `cbtc layout list`")
    return layout
