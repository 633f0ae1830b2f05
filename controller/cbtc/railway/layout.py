"""A track layout as values: the path, its stations, RFID tags, fixed blocks and IPS frame.

Every position on the track is an arc length `s_m` in metres from the path's start. Layouts are read from YAML by
cbtc.layout_files and checked by cbtc.railway.layout_dict; the format is described in docs/layouts.md.
"""

from dataclasses import dataclass

from cbtc.errors import LayoutError
from cbtc.railway.geometry import Path, forward_m
from cbtc.railway.track_graph import single_section_graph


@dataclass(frozen=True)
class Station:
    name: str
    s_m: float       # stop point for the train's head
    window_m: float  # +/- tolerance of the stop


@dataclass(frozen=True)
class Tag:
    uid: str         # upper-case hex
    s_m: float


@dataclass(frozen=True)
class Block:
    name: str
    start_m: float
    end_m: float     # the block is [start, end) along s; on a loop it may wrap past the seam (end < start)


@dataclass(frozen=True)
class IpsFrame:
    """Where the IPS frame sits in the layout frame: track = origin + R(rotation) * ips; beacons (m) in IPS frame."""
    origin_x_m: float = 0.0
    origin_y_m: float = 0.0
    rotation_deg: float = 0.0
    beacons: tuple = ()


class Layout:
    """A validated layout: geometry plus the railway on it. All positions are arc lengths `s_m` along the path."""

    def __init__(self, name, source, path: Path, stations, tags, blocks, ips):
        self.name = name
        self.source = source
        self.path = path
        self.closed = path.closed
        self.length_m = path.length_m
        self.loop_length_m = path.length_m if path.closed else None   # for offsets the short way round; None: a line
        self.segment_count = len(path.segments)
        self.stations = tuple(stations)
        self.tags = tuple(sorted(tags, key=lambda t: t.s_m))
        self.blocks = tuple(blocks)
        self.ips = ips
        self.is_network = False
        self.graph = single_section_graph(path)   # the path as a track graph: one section, "main"
        self._tags_by_uid = {t.uid: t for t in self.tags}
        self._stations_by_name = {st.name: st for st in self.stations}
        # wrap(s_m): closed, `s_m` modulo the length; open, clipped to [0, length]; float or numpy array. The path's
        # own method, called directly: every report and every simulated tick wraps positions several times
        self.wrap = path.wrap

    def ahead_m(self, s_from_m, s_to_m):
        """Distance (m) going forward from `s_from_m` to `s_to_m`: in [0, length) on a loop, to - from on a line."""
        return forward_m(s_from_m, s_to_m, self.loop_length_m)

    def pose(self, s_m):
        """(x_m, y_m, heading_rad) at `s_m` (float or array; wraps on a loop)."""
        return self.path.pose(s_m)

    def xy(self, s_m):
        """Position (m) at `s_m`, shape `np.shape(s_m) + (2,)`."""
        return self.path.xy(s_m)

    def xy_m(self, s_m: float):
        """(x_m, y_m) floats at `s_m` (wraps on a loop)."""
        return self.path.xy_m(s_m)

    def project(self, x_m, y_m, s_hint_m=None, window_m=0.5):
        """`s_m` of the track point nearest to (x_m, y_m); with a hint, the nearest within `window_m` of it."""
        return self.path.project(x_m, y_m, s_hint_m, window_m)

    def station(self, name) -> Station:
        """The station called `name`; LayoutError listing the known names otherwise."""
        if name not in self._stations_by_name:
            raise LayoutError(f"{self.source}: no station {name!r}; stations are {[st.name for st in self.stations]}")
        return self._stations_by_name[name]

    def tag_by_uid(self, uid):
        """The tag with this uid (hex, any case), or None."""
        return self._tags_by_uid.get(uid.upper() if isinstance(uid, str) else uid)

    def digest(self) -> str:
        """16 hex digits of SHA-256 over the track (its shape every centimetre, to the millimetre), stations, tags,
        blocks and IPS frame: two files that describe the same railway give the same digest, whatever their names."""
        import hashlib

        def mm(value):
            return round(value, 3) + 0.0   # + 0.0: -0.0 is 0.0

        count = max(2, int(self.length_m * 100))
        shape = [tuple(map(mm, self.xy_m(self.length_m * i / count))) for i in range(count + 1)]
        parts = (self.closed, mm(self.length_m), shape,
                 [(st.name, mm(st.s_m), mm(st.window_m)) for st in self.stations],
                 [(t.uid, mm(t.s_m)) for t in self.tags],
                 [(b.name, mm(b.start_m), mm(b.end_m)) for b in self.blocks],
                 (mm(self.ips.origin_x_m), mm(self.ips.origin_y_m), mm(self.ips.rotation_deg),
                  [tuple(map(mm, beacon)) for beacon in self.ips.beacons]))
        return hashlib.sha256(repr(parts).encode()).hexdigest()[:16]

    def block_at(self, s_m):
        """The fixed block holding `s_m` ([start, end)), or None where no block is defined."""
        s = self.wrap(s_m)
        for block in self.blocks:
            if self.closed:
                span = span_on_loop_m(block.start_m, block.end_m, self.length_m)
                if self.ahead_m(block.start_m, s) < span:
                    return block
            elif block.start_m <= s < block.end_m or (s == block.end_m == self.length_m):
                return block
        return None


def span_on_loop_m(start_m, end_m, length_m):
    """Length (m) of the loop block [start, end): end <= start wraps past the seam; [0, length) is the whole loop."""
    span = forward_m(start_m, end_m, length_m)
    return length_m if span == 0.0 and end_m != start_m else span
