"""A layout from the dict of its YAML file, checked: every error names the file, the key path
(e.g. `segments[3].arc.radius_m`) and the fix. The format is described in docs/layouts.md and in the header of
track_layouts/itb_square.yaml.
"""

import difflib
import math
import os

from cbtc.errors import LayoutError
from cbtc.protocol import wire_zc
from cbtc.railway.geometry import Path, forward_m
from cbtc.railway.layout import Block, IpsFrame, Layout, Station, Tag, span_on_loop_m

MAX_COUNT = 1000   # most repeats of a piece, or blocks, a layout may ask for: a table holds a few hundred pieces

STUD_M = 0.008
# LEGO pieces: name -> segment. A straight is 16 studs; a curve's radius is measured to the track centre line.
# curve_r40 is LEGO's own curve; curve_r56 and curve_r72 are the wide curves LEGO users buy from third-party makers,
# taken here as 22.5 degrees a piece (16 to a circle) like R40; anything else: {piece: curve, radius_studs, angle_deg}.
PIECES = {
    "straight": ("straight", 16 * STUD_M),
    "half_straight": ("straight", 8 * STUD_M),
    "quarter_straight": ("straight", 4 * STUD_M),
    "curve_r40": ("arc", 40 * STUD_M, 22.5),
    "curve_r56": ("arc", 56 * STUD_M, 22.5),
    "curve_r72": ("arc", 72 * STUD_M, 22.5),
}
CLOSE_TOLERANCE_M = 0.005
CLOSE_TOLERANCE_DEG = 0.5
BLOCK_JOIN_TOLERANCE_M = 0.001   # block ends closer than this to the next start are joined exactly
DEFAULT_WINDOW_M = 0.03
MIN_WINDOW_M = 0.01   # a board holds a train that braked onto its mark up to 3 mm short, and the estimate errs too

TOP_KEYS = ("name", "closed", "start", "segments", "stations", "tags", "blocks", "ips")


class Reader:
    """Typed access to the YAML tree that names the file and the key path in every error."""

    def __init__(self, source):
        self.source = source
        self.line = 0     # the line of the item being read, where the tree keeps lines (0: name no line)

    def fail(self, key, message):
        where = f"{self.source}:{self.line}" if self.line else self.source
        raise LayoutError(f"{where}: {key}: {message}")

    def mapping(self, value, where, allowed):
        if not isinstance(value, dict):
            self.fail(where, f"must be a mapping of {', '.join(allowed)}, got {kind_of(value)}")
        for key in value:
            if key not in allowed:
                near = difflib.get_close_matches(str(key), allowed, n=1)
                hint = f"did you mean {near[0]!r}?" if near else f"known keys: {', '.join(allowed)}"
                self.fail(f"{where}.{key}" if where != "top level" else str(key), f"unknown key; {hint}")
        return value

    def sequence(self, value, where):
        if not isinstance(value, list):
            self.fail(where, f"must be a list, got {kind_of(value)}")
        return value

    def number(self, mapping, key, where, positive=False, default=None):
        path = f"{where}.{key}"
        if key not in mapping:
            if default is not None:
                return default
            self.fail(path, "missing: add a number")
        value = mapping[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(path, f"must be a number, got {value!r}")
        if positive and value <= 0:
            self.fail(path, f"must be > 0, got {value}")
        return float(value)

    def count(self, mapping, where):
        value = mapping.get("count", 1)
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_COUNT:
            self.fail(f"{where}.count", f"must be a whole number from 1 to {MAX_COUNT}, got {value!r}")
        return value


def kind_of(value):
    return "nothing" if value is None else type(value).__name__


def read_segments(r: Reader, items, key="segments"):
    segments = []
    for i, item in enumerate(r.sequence(items, key)):
        where = f"{key}[{i}]"
        if not isinstance(item, dict):
            r.fail(where, f"must be a mapping such as {{straight: {{length_m: 1.2}}}}, got {kind_of(item)}")
        kinds = [k for k in ("straight", "arc", "piece") if k in item]
        if len(kinds) != 1:
            r.fail(where, "needs exactly one of 'straight', 'arc' or 'piece'" + (f", got {kinds}" if kinds else ""))
        if kinds[0] == "straight":
            r.mapping(item, where, ("straight",))
            body = r.mapping(item["straight"], f"{where}.straight", ("length_m",))
            segments.append(("straight", r.number(body, "length_m", f"{where}.straight", positive=True)))
        elif kinds[0] == "arc":
            r.mapping(item, where, ("arc",))
            body = r.mapping(item["arc"], f"{where}.arc", ("radius_m", "angle_deg"))
            radius = r.number(body, "radius_m", f"{where}.arc", positive=True)
            angle = r.number(body, "angle_deg", f"{where}.arc")
            if angle == 0 or abs(angle) > 360:
                r.fail(f"{where}.arc.angle_deg", f"must be non-zero, within +/-360 (> 0 turns left), got {angle}")
            segments.append(("arc", radius, math.radians(angle)))
        else:
            segments.extend(_piece(r, item, where))
    if not segments:
        r.fail(key, "is empty: list at least one segment")
    return segments


def _piece(r, item, where):
    name = item["piece"]
    if name == "curve":  # any other curve: {piece: curve, radius_studs: N, angle_deg: A, turn: left|right, count: N}
        r.mapping(item, where, ("piece", "radius_studs", "angle_deg", "turn", "count"))
        angle = r.number(item, "angle_deg", where, positive=True)
        if angle > 360:
            r.fail(f"{where}.angle_deg", f"must be at most 360 (the piece's sweep; 'turn' gives the side), got {angle}")
        spec = ("arc", r.number(item, "radius_studs", where, positive=True) * STUD_M, angle)
    elif isinstance(name, str) and name in PIECES:
        spec = PIECES[name]
        r.mapping(item, where, ("piece", "count") if spec[0] == "straight" else ("piece", "turn", "count"))
    else:
        r.fail(f"{where}.piece", f"unknown piece {name!r}; known: {', '.join(list(PIECES) + ['curve'])}")
    count = r.count(item, where)
    if spec[0] == "straight":
        return [spec] * count
    turn = item.get("turn", "left")
    if turn not in ("left", "right"):
        r.fail(f"{where}.turn", f"must be 'left' or 'right', got {turn!r}")
    angle_rad = math.radians(spec[2]) * (1 if turn == "left" else -1)
    return [("arc", spec[1], angle_rad)] * count


def layout_from_dict(data, source="<dict>"):
    """Validate a layout given as the parsed YAML tree; `source` names it in error messages. A Layout (one path), or
    a NetworkLayout where the file has `track:` (sections and switches)."""
    r = Reader(source)
    if data is None:
        r.fail("top level", "the file is empty: write a layout (see docs/layouts.md)")
    if isinstance(data, dict) and "track" in data:
        return _network(r, data, source)
    data = r.mapping(data, "top level", TOP_KEYS)
    name = _name(r, data, source)
    if "closed" not in data:
        r.fail("closed", "missing: write closed: true for a loop or closed: false for an open line")
    closed = data["closed"]
    if not isinstance(closed, bool):
        r.fail("closed", f"must be true (a loop) or false (an open line), got {closed!r}")
    if "segments" not in data:
        r.fail("segments", "missing: list the track as straights and arcs, or LEGO pieces")
    segments = read_segments(r, data["segments"])
    start = r.mapping(data.get("start", {}), "start", ("x_m", "y_m", "heading_deg"))
    path = Path(segments, r.number(start, "x_m", "start", default=0.0), r.number(start, "y_m", "start", default=0.0),
                math.radians(r.number(start, "heading_deg", "start", default=0.0)), closed=closed)
    if closed:
        _check_closes(r, path)
    length = path.length_m
    stations = _stations(r, data.get("stations", []), length, closed)
    tags = _tags(r, data.get("tags", []), length, closed)
    blocks = _blocks(r, data.get("blocks", []), length, closed)
    ips = read_ips(r, data.get("ips", {}))
    return Layout(name, source, path, stations, tags, blocks, ips)


def _name(r, data, source):
    default_name = os.path.basename(source)[:-5] if source.endswith(".yaml") else source
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name:
        r.fail("name", f"must be a non-empty string, got {name!r}")
    return name


def _network(r, data, source):
    """A track network (switches, several sections): `track:` instead of `segments:`."""
    from cbtc.railway.network_dict import network_from_dict

    both = [k for k in ("segments", "closed", "start", "blocks") if k in data]
    if both:
        r.line = getattr(data, "lines", None) and data.lines.get(both[0], 0)
        r.fail(both[0], "belongs to a single-path layout, not a track network (`track:`): give the pieces as "
                        "sections under track (see docs/layouts.md), or drop track and keep segments")
    return network_from_dict(data, source, _name(r, data, source))


def _check_closes(r, path):
    x0, y0, h0 = path.start_pose
    x1, y1, h1 = path.end_pose
    gap_m = math.hypot(x1 - x0, y1 - y0)
    turn_deg = abs((math.degrees(h1 - h0) + 180.0) % 360.0 - 180.0)
    if gap_m > CLOSE_TOLERANCE_M or turn_deg > CLOSE_TOLERANCE_DEG:
        r.fail("segments", f"the loop does not close: its end is {gap_m * 1000:.1f} mm and {turn_deg:.2f} deg from its "
                           f"start (tolerance {CLOSE_TOLERANCE_M * 1000:.0f} mm, {CLOSE_TOLERANCE_DEG} deg); fix the "
                           "segment lengths or angles, or set closed: false")


def _on_track(r, s, key, length, closed):
    if not (0.0 <= s < length or (not closed and s == length)):
        op = "<" if closed else "<="
        r.fail(key, f"s_m = {s} is off the track: use 0 <= s_m {op} {length:.4f} (the track length)")
    return s


def _stations(r, items, length, closed):
    stations, seen = [], set()
    for i, item in enumerate(r.sequence(items, "stations")):
        where = f"stations[{i}]"
        item = r.mapping(item, where, ("name", "s_m", "window_m"))
        name = read_station_name(r, item, where, seen)
        s_m = _on_track(r, r.number(item, "s_m", where), f"{where}.s_m", length, closed)
        stations.append(Station(name, s_m, read_window(r, item, where)))
    return stations


def read_station_name(r, item, where, seen):
    """The station's name, checked to be a string no station in `seen` has; added to `seen`."""
    name = item.get("name")
    if not isinstance(name, str) or not name:
        r.fail(f"{where}.name", f"missing or not a string ({name!r}): give the station a name")
    if name in seen:
        r.fail(f"{where}.name", f"duplicate station name {name!r}: names must be unique")
    seen.add(name)
    return name


def read_window(r, item, where):
    """The station's stop window (m), at least MIN_WINDOW_M."""
    window_m = r.number(item, "window_m", where, positive=True, default=DEFAULT_WINDOW_M)
    if window_m < MIN_WINDOW_M:
        r.fail(f"{where}.window_m", f"{window_m} m is finer than a train stops (a board holds a train braked onto "
               f"its mark up to 3 mm short): give at least {MIN_WINDOW_M}")
    return window_m


def _tags(r, items, length, closed):
    tags, uids = [], set()
    for i, item in enumerate(r.sequence(items, "tags")):
        where = f"tags[{i}]"
        item = r.mapping(item, where, ("uid", "s_m"))
        uid = read_tag_uid(r, item, where)
        if uid in uids:
            r.fail(f"{where}.uid", f"duplicate uid {uid}: each tag needs its own")
        uids.add(uid)
        tags.append(Tag(uid, _on_track(r, r.number(item, "s_m", where), f"{where}.s_m", length, closed)))
    return tags


def read_tag_uid(r, item, where):
    """The tag's uid, upper-case hex, checked."""
    if "uid" not in item:
        r.fail(f"{where}.uid", "missing: add the tag's uid as a quoted hex string, e.g. '04A1B2C3'")
    uid = item["uid"]
    if not isinstance(uid, str):
        r.fail(f"{where}.uid", f"must be a quoted hex string such as '04A1B2C3', got {uid!r} (unquoted, YAML "
                               "reads hex digits as a number)")
    if len(uid) not in wire_zc.UID_HEX_LENGTHS or any(c not in "0123456789abcdefABCDEF" for c in uid):
        r.fail(f"{where}.uid", f"must be a 4, 7 or 10-byte uid in hex (8, 14 or 20 digits) such as '04A1B2C3', "
                               f"as the reader prints it; got {uid!r}")
    return uid.upper()


def _blocks(r, spec, length, closed):
    if isinstance(spec, dict):
        r.mapping(spec, "blocks", ("count",))
        if "count" not in spec:
            r.fail("blocks.count", "missing: write blocks: {count: N} or a list of {name, start_m, end_m}")
        count = r.count(spec, "blocks")
        size = length / count
        return tuple(Block(f"B{i + 1}", i * size, (i + 1) * size) for i in range(count))
    blocks = []
    for i, item in enumerate(r.sequence(spec, "blocks")):
        where = f"blocks[{i}]"
        item = r.mapping(item, where, ("name", "start_m", "end_m"))
        name = item.get("name", f"B{i + 1}")
        if not isinstance(name, str) or not name:
            r.fail(f"{where}.name", f"must be a non-empty string, got {name!r}")
        if any(b.name == name for _, b in blocks):
            r.fail(f"{where}.name", f"duplicate block name {name!r}: names must be unique")
        start = r.number(item, "start_m", where)
        end = r.number(item, "end_m", where)
        if not 0.0 <= start < length:
            r.fail(f"{where}.start_m", f"{start} is off the track: use 0 <= start_m < {length:.4f}")
        if not 0.0 <= end <= length:
            r.fail(f"{where}.end_m", f"{end} is off the track: use 0 <= end_m <= {length:.4f}")
        if not closed and end <= start:
            r.fail(f"{where}.end_m", f"must be beyond start_m ({start}) on an open line, got {end}")
        if closed and end == start:
            r.fail(f"{where}.end_m", f"equals start_m ({start}): the block is empty")
        blocks.append((i, Block(name, start, end)))
    if not blocks:
        return ()
    ordered = sorted(blocks, key=lambda ib: ib[1].start_m)
    joined = []
    for n, (i, b) in enumerate(ordered):
        last = n + 1 == len(ordered)
        if last and not closed:
            joined.append(b)
            break
        j, nxt = ordered[0] if last else ordered[n + 1]
        if closed:
            span_m = span_on_loop_m(b.start_m, b.end_m, length)
            room_m = forward_m(b.start_m, nxt.start_m, length) if j != i else length   # up to the next block's start
        else:
            span_m, room_m = b.end_m - b.start_m, nxt.start_m - b.start_m
        gap_m = room_m - span_m
        if gap_m < -BLOCK_JOIN_TOLERANCE_M:
            r.fail(f"blocks[{i}]", f"block {b.name} overlaps block {nxt.name} (blocks[{j}]) by {-gap_m:.4f} m: end it "
                                   f"at {nxt.start_m} where {nxt.name} starts")
        if closed and gap_m > BLOCK_JOIN_TOLERANCE_M:
            r.fail(f"blocks[{i}]", f"leaves {gap_m:.4f} m uncovered before block {nxt.name} (blocks[{j}]): on a loop "
                                   f"the blocks must cover the whole track; end {b.name} at {nxt.start_m}")
        end_m = b.end_m
        if abs(gap_m) <= BLOCK_JOIN_TOLERANCE_M:   # join exactly; a loop's last block ends at `length`, not 0
            end_m = length if last and nxt.start_m == 0.0 else nxt.start_m
        joined.append(Block(b.name, b.start_m, end_m))
    return tuple(joined)


def read_ips(r, spec):
    spec = r.mapping(spec, "ips", ("origin_x_m", "origin_y_m", "rotation_deg", "beacons"))
    beacons = []
    for i, b in enumerate(r.sequence(spec.get("beacons", []), "ips.beacons")):
        if not isinstance(b, list) or len(b) != 3 or \
                any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in b):
            r.fail(f"ips.beacons[{i}]", f"must be [x, y, z] in metres (IPS frame), got {b!r}")
        beacons.append(tuple(float(v) for v in b))
    return IpsFrame(r.number(spec, "origin_x_m", "ips", default=0.0), r.number(spec, "origin_y_m", "ips", default=0.0),
                    r.number(spec, "rotation_deg", "ips", default=0.0), tuple(beacons))
