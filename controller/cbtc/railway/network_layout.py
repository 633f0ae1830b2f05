"""A track network layout as values: its graph of sections and switches, stations and tags on sections, IPS frame.

Positions are (section, offset_m). The zone and the simulator run on single paths (cbtc.railway.layout.Layout); a
network is read, checked, listed and drawn, and its routes flatten into paths (cbtc.railway.track_graph.Route).
"""

from dataclasses import dataclass

from cbtc.errors import LayoutError


@dataclass(frozen=True)
class NetworkStation:
    name: str
    section: str
    offset_m: float    # stop point for the train's head, from the section's start
    window_m: float


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


def refuse_network(layout, what):
    """`layout`, or LayoutError when it is a network: `what` (a command) takes single-path layouts."""
    if getattr(layout, "is_network", False):
        raise LayoutError(f"{layout.source}: layout {layout.name} is a track network (switches and sections): {what} "
                          "takes single-path layouts (segments:) for now; `cbtc layout show` reads and draws networks; "
                          "pick a loop or a line from `cbtc layout list`")
    return layout
