"""Track layouts: YAML files of segments or LEGO pieces, with stations, RFID tags, fixed blocks and the IPS frame.

`load_layout(path_or_name)` validates everything and raises LayoutError naming the file, the key and the fix.
The format is described in docs/layouts.md and in the header of track_layouts/itb_square.yaml.
"""

import math
import os
from dataclasses import dataclass
from importlib import resources

import numpy as np
import yaml

from .errors import LayoutError
from .geometry import Path

STUD_M = 0.008
# LEGO pieces: name -> segment. Straight 16 studs; R40 curve: 40 studs to the track centre, 22.5 degrees (16 a circle)
PIECES = {
    "straight": ("straight", 16 * STUD_M),
    "half_straight": ("straight", 8 * STUD_M),
    "quarter_straight": ("straight", 4 * STUD_M),
    "curve_r40": ("arc", 40 * STUD_M, 22.5),
}
CLOSE_TOLERANCE_M = 0.005
CLOSE_TOLERANCE_DEG = 0.5


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
    end_m: float     # on a loop the last block may end past the seam (end < start)


@dataclass(frozen=True)
class IpsFrame:
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
        self.stations = tuple(stations)
        self.tags = tuple(sorted(tags, key=lambda t: t.s_m))
        self.blocks = tuple(blocks)
        self.ips = ips
        self._tags_by_uid = {t.uid: t for t in self.tags}

    def wrap(self, s_m):
        return self.path.wrap(s_m)

    def ahead_m(self, s_from_m, s_to_m):
        """Distance travelling forward from `s_from_m` to `s_to_m` (in [0, length) on a loop)."""
        if self.closed:
            return (s_to_m - s_from_m) % self.length_m
        return s_to_m - s_from_m

    def pose(self, s_m):
        return self.path.pose(s_m)

    def xy(self, s_m):
        return self.path.xy(s_m)

    def project(self, x_m, y_m, s_hint_m=None):
        return self.path.project(x_m, y_m, s_hint_m)

    def station(self, name) -> Station:
        for st in self.stations:
            if st.name == name:
                return st
        raise LayoutError(f"{self.source}: no station {name!r}; stations are {[st.name for st in self.stations]}")

    def tag_by_uid(self, uid):
        return self._tags_by_uid.get(uid)

    def block_at(self, s_m):
        for block in self.blocks:
            if self.ahead_m(block.start_m, s_m) < self.ahead_m(block.start_m, block.end_m) or \
                    (block.end_m - block.start_m) >= self.length_m:
                return block
        return None


# --- loading -------------------------------------------------------------------------------------------------------

def layout_names():
    """Names of the layouts shipped with the package."""
    folder = resources.files("cbtc.track_layouts")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def _resolve(path_or_name):
    if os.path.exists(path_or_name):
        return str(path_or_name)
    name = os.path.basename(str(path_or_name))
    name = name[:-5] if name.endswith(".yaml") else name
    packaged = resources.files("cbtc.track_layouts") / f"{name}.yaml"
    if packaged.is_file() and os.sep not in str(path_or_name).rstrip(os.sep):
        return str(packaged)
    raise LayoutError(f"layout {path_or_name!r} not found: give a YAML file path or one of {layout_names()}")


def load_layout(path_or_name) -> Layout:
    source = _resolve(str(path_or_name))
    try:
        with open(source, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as exc:
        raise LayoutError(f"{source}: not valid YAML: {exc}") from None
    except OSError as exc:
        raise LayoutError(f"{source}: cannot read: {exc.strerror}") from None
    return layout_from_dict(data, source)


class _Reader:
    """Typed access to the YAML tree that names the file and the key path in every error."""

    def __init__(self, source):
        self.source = source

    def fail(self, key, message):
        raise LayoutError(f"{self.source}: {key}: {message}")

    def number(self, mapping, key, where, positive=False, default=None):
        if key not in mapping:
            if default is not None:
                return default
            self.fail(f"{where}.{key}", "missing: add a number")
        value = mapping[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(f"{where}.{key}", f"must be a number, got {value!r}")
        if positive and value <= 0:
            self.fail(f"{where}.{key}", f"must be > 0, got {value}")
        return float(value)

    def mapping(self, value, where):
        if not isinstance(value, dict):
            self.fail(where, f"must be a mapping, got {type(value).__name__}")
        return value

    def sequence(self, value, where):
        if not isinstance(value, list):
            self.fail(where, f"must be a list, got {type(value).__name__}")
        return value


def _segments(r: _Reader, items):
    segments = []
    for i, item in enumerate(r.sequence(items, "segments")):
        where = f"segments[{i}]"
        item = r.mapping(item, where)
        if "straight" in item:
            body = r.mapping(item["straight"], f"{where}.straight")
            segments.append(("straight", r.number(body, "length_m", f"{where}.straight", positive=True)))
        elif "arc" in item:
            body = r.mapping(item["arc"], f"{where}.arc")
            radius = r.number(body, "radius_m", f"{where}.arc", positive=True)
            angle = r.number(body, "angle_deg", f"{where}.arc")
            if angle == 0 or abs(angle) > 360:
                r.fail(f"{where}.arc.angle_deg", f"must be non-zero and within +/-360 (positive turns left), got {angle}")
            segments.append(("arc", radius, math.radians(angle)))
        elif "piece" in item:
            segments.extend(_piece(r, item, where))
        else:
            r.fail(where, "needs one of 'straight', 'arc' or 'piece'")
    if not segments:
        r.fail("segments", "is empty: list at least one segment")
    return segments


def _piece(r, item, where):
    name = item["piece"]
    count = item.get("count", 1)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        r.fail(f"{where}.count", f"must be a whole number >= 1, got {count!r}")
    if name == "curve":  # a generic curve: {piece: curve, radius_studs: N, angle_deg: A, turn: left|right}
        radius = r.number(item, "radius_studs", where, positive=True) * STUD_M
        angle = r.number(item, "angle_deg", where, positive=True)
        spec = ("arc", radius, angle)
    elif name in PIECES:
        spec = PIECES[name]
    else:
        r.fail(f"{where}.piece", f"unknown piece {name!r}; known: {sorted(PIECES) + ['curve']}")
    if spec[0] == "straight":
        if "turn" in item:
            r.fail(f"{where}.turn", "a straight piece does not turn: remove 'turn'")
        return [spec] * count
    turn = item.get("turn", "left")
    if turn not in ("left", "right"):
        r.fail(f"{where}.turn", f"must be 'left' or 'right', got {turn!r}")
    angle = math.radians(spec[2]) * (1 if turn == "left" else -1)
    return [("arc", spec[1], angle)] * count


def layout_from_dict(data, source="<dict>") -> Layout:
    r = _Reader(source)
    data = r.mapping(data, "top level")
    name = data.get("name", os.path.basename(source)[:-5] if source.endswith(".yaml") else source)
    closed = data.get("closed")
    if not isinstance(closed, bool):
        r.fail("closed", f"must be true (a loop) or false (an open line), got {closed!r}")
    if "segments" not in data:
        r.fail("segments", "missing: list the track as straights and arcs, or LEGO pieces")
    start = r.mapping(data.get("start", {}), "start")
    path = Path(_segments(r, data["segments"]), r.number(start, "x_m", "start", default=0.0),
                r.number(start, "y_m", "start", default=0.0),
                math.radians(r.number(start, "heading_deg", "start", default=0.0)), closed=closed)
    if closed:
        x0, y0, h0 = path.start_pose
        x1, y1, h1 = path.end_pose
        gap_m = math.hypot(x1 - x0, y1 - y0)
        turn_deg = abs((math.degrees(h1 - h0) + 180.0) % 360.0 - 180.0)
        if gap_m > CLOSE_TOLERANCE_M or turn_deg > CLOSE_TOLERANCE_DEG:
            r.fail("segments", f"the loop does not close: its end is {gap_m * 1000:.1f} mm and {turn_deg:.2f} deg from its "
                               f"start (tolerance {CLOSE_TOLERANCE_M * 1000:.0f} mm, {CLOSE_TOLERANCE_DEG} deg); fix the "
                               "segment lengths or angles, or set closed: false")
    length = path.length_m

    def on_track(s, key):
        if not (0.0 <= s < length or (not closed and s == length)):
            r.fail(key, f"s_m = {s} is off the track: use 0 <= s_m < {length:.4f}")
        return s

    stations, seen = [], set()
    for i, item in enumerate(r.sequence(data.get("stations", []), "stations")):
        where = f"stations[{i}]"
        item = r.mapping(item, where)
        st_name = item.get("name")
        if not isinstance(st_name, str) or not st_name:
            r.fail(f"{where}.name", "missing: give the station a name")
        if st_name in seen:
            r.fail(f"{where}.name", f"duplicate station name {st_name!r}: names must be unique")
        seen.add(st_name)
        stations.append(Station(st_name, on_track(r.number(item, "s_m", where), f"{where}.s_m"),
                                r.number(item, "window_m", where, positive=True, default=0.03)))
    tags, uids = [], set()
    for i, item in enumerate(r.sequence(data.get("tags", []), "tags")):
        where = f"tags[{i}]"
        item = r.mapping(item, where)
        uid = item.get("uid")
        if isinstance(uid, int):
            uid = f"{uid:X}"
        if not isinstance(uid, str) or not uid or any(c not in "0123456789abcdefABCDEF" for c in uid):
            r.fail(f"{where}.uid", f"must be a hex string such as '04A1B2C3', got {item.get('uid')!r}")
        uid = uid.upper()
        if uid in uids:
            r.fail(f"{where}.uid", f"duplicate uid {uid}: each tag needs its own")
        uids.add(uid)
        tags.append(Tag(uid, on_track(r.number(item, "s_m", where), f"{where}.s_m")))
    blocks = _blocks(r, data.get("blocks", []), length, closed)
    ips_data = r.mapping(data.get("ips", {}), "ips")
    beacons = []
    for i, b in enumerate(r.sequence(ips_data.get("beacons", []), "ips.beacons")):
        if not isinstance(b, list) or len(b) != 3 or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in b):
            r.fail(f"ips.beacons[{i}]", f"must be [x, y, z] in metres, got {b!r}")
        beacons.append(tuple(float(v) for v in b))
    ips = IpsFrame(r.number(ips_data, "origin_x_m", "ips", default=0.0), r.number(ips_data, "origin_y_m", "ips", default=0.0),
                   r.number(ips_data, "rotation_deg", "ips", default=0.0), tuple(beacons))
    return Layout(str(name), source, path, stations, tags, blocks, ips)


def _blocks(r, spec, length, closed):
    if isinstance(spec, dict):
        count = spec.get("count")
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            r.fail("blocks.count", f"must be a whole number >= 1, got {count!r}")
        size = length / count
        return tuple(Block(f"B{i + 1}", i * size, (i + 1) * size) for i in range(count))
    blocks = []
    for i, item in enumerate(r.sequence(spec, "blocks")):
        where = f"blocks[{i}]"
        item = r.mapping(item, where)
        blocks.append(Block(str(item.get("name", f"B{i + 1}")), r.number(item, "start_m", where),
                            r.number(item, "end_m", where)))
    if not blocks:
        return ()
    ordered = sorted(blocks, key=lambda b: b.start_m)
    for i, b in enumerate(ordered):
        if not 0.0 <= b.start_m < length:
            r.fail(f"blocks ({b.name}).start_m", f"{b.start_m} is off the track (0 <= start_m < {length:.4f})")
        span = (b.end_m - b.start_m) % length if closed else b.end_m - b.start_m
        if span <= 0:
            r.fail(f"blocks ({b.name}).end_m", f"the block is empty or reversed ({b.start_m} -> {b.end_m})")
        nxt = ordered[(i + 1) % len(ordered)]
        end = b.end_m % length if closed else b.end_m
        if i + 1 < len(ordered) or closed:
            expected = nxt.start_m
            if not np.isclose(end, expected, atol=1e-6):
                problem = "overlaps" if span > (expected - b.start_m) % length else "leaves a gap before"
                r.fail(f"blocks ({b.name})", f"{problem} block {nxt.name}: end_m {b.end_m} should equal the next block's "
                                             f"start_m {expected}; blocks must tile the track")
    return tuple(ordered)
