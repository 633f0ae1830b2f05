"""A track network from the dict of its YAML file (a layout with a top-level `track:` list), checked.

Sections are chains of pieces placed from a pose or from an end already placed; switches are LEGO's left and right
switches placed by their toe or a heel. Ends meet where their positions agree within CLOSE_TOLERANCE_M and their
outward headings are opposite within CLOSE_TOLERANCE_DEG; every other end must be listed under `buffers`. Every error
names the file, the line of the item, the key and the fix. The format is in docs/layouts.md.
"""

import math

from cbtc.railway import layout_dict as ld
from cbtc.railway.geometry import Path
from cbtc.railway.network_joins import check_overlaps, join, line_of
from cbtc.railway.network_layout import NetworkLayout, NetworkStation, NetworkTag
from cbtc.railway.track_graph import END, LEGS, START, Section, Switch

TOP_KEYS = ("name", "track", "joins", "buffers", "stations", "tags", "ips")
SECTION_KEYS = ("section", "start", "from", "segments")
SWITCH_KEYS = ("switch", "piece", "start", "at", "by")
STUD_M = ld.STUD_M
R40_M = 40 * STUD_M
# LEGO's switch (macfreek.nl, "Lego train tracks geometry"): the straight leg is 32 studs; the diverging leg leaves
# on an R40 arc of atan(3/4) = 36.87 deg and turns back 14.37 deg, ending 22.5 deg out at (32.69, 12.955) studs, so
# that an R40 curve (22.5 deg) turned back brings it parallel to the straight leg 16 studs to the side, 48 studs on
DIVERGE_OUT_DEG = math.degrees(math.atan2(3.0, 4.0))
DIVERGE_BACK_DEG = DIVERGE_OUT_DEG - 22.5
SWITCH_PIECES = {"switch_left": 1.0, "switch_right": -1.0}
CROSSING_KEYS = ("crossing", "start", "at", "by")
CROSSING_HALF_M = 8 * STUD_M   # LEGO's crossing: two 16-stud straights crossing at their middles at 90 degrees
KINDS = ("section", "switch", "crossing")


def switch_legs(hand_sign):
    """{"straight": segments, "diverging": segments} of a LEGO switch, left (+1) or right (-1)."""
    return {"straight": [("straight", 32 * STUD_M)],
            "diverging": [("arc", R40_M, hand_sign * math.radians(DIVERGE_OUT_DEG)),
                          ("arc", R40_M, -hand_sign * math.radians(DIVERGE_BACK_DEG))]}


class _End:
    """A place where track ends, as the file names it (`loop.end`, `W1.toe`): its pose and the graph ends it holds."""

    def __init__(self, name, pose, graph_ends, item):
        self.name = name
        self.x_m, self.y_m, self.out_rad = pose
        self.graph_ends = graph_ends     # (section, "start"|"end") ends; a toe holds both legs' starts
        self.item = item                 # (index, line, label) of the track item that made it


def network_from_dict(data, source, name) -> NetworkLayout:
    """Validate a network layout given as its parsed YAML tree (a mapping with `track:`)."""
    r = ld.Reader(source)
    r.mapping(data, "top level", TOP_KEYS)
    items = r.sequence(data["track"], "track")
    if not items:
        r.fail("track", "is empty: list sections and switches")
    sections, switches, ends = _place(r, items)
    graph = join(r, data, sections, switches, ends)
    check_overlaps(r, graph, ends)
    r.line = 0
    stations = _stations(r, data.get("stations", []), graph)
    tags = _tags(r, data.get("tags", []), graph)
    r.line = line_of(data, "ips")
    ips = ld.read_ips(r, data.get("ips", {}))
    return NetworkLayout(name, source, graph, stations, tags, ips)


def _pose(r, spec, where):
    spec = r.mapping(spec, where, ("x_m", "y_m", "heading_deg"))
    return (r.number(spec, "x_m", where, default=0.0), r.number(spec, "y_m", where, default=0.0),
            math.radians(r.number(spec, "heading_deg", where, default=0.0)))


def _anchor_key(kind):
    """The key naming the end an item is placed at: a section starts `from` one, a switch or crossing lies `at` one."""
    return "from" if kind == "section" else "at"


def _read_item(r, items, i, names):
    """Check track item `i` and return it as (index, line, kind, id, item, segments) to place."""
    item, where = items[i], f"track[{i}]"
    r.line = line_of(items, i)
    if not isinstance(item, dict):
        r.fail(where, f"must be a mapping such as {{section: main, segments: [...]}}, got {ld.kind_of(item)}")
    kinds = [k for k in KINDS if k in item]
    if len(kinds) != 1:
        r.fail(where, "needs exactly one of 'section' (a chain of pieces), 'switch' (a LEGO switch) or 'crossing' "
               "(a LEGO crossing)" + (f", got {kinds}" if kinds else ""))
    kind = kinds[0]
    r.mapping(item, where, {"section": SECTION_KEYS, "switch": SWITCH_KEYS, "crossing": CROSSING_KEYS}[kind])
    ident = item[kind]
    if not isinstance(ident, str) or not ident or "." in ident:
        r.fail(f"{where}.{kind}", f"must be a name without dots, got {ident!r}")
    if ident in names:
        r.fail(f"{where}.{kind}", f"{ident!r} is used twice (first at track[{names[ident]}]): give each its own")
    names[ident] = i
    anchor_key = _anchor_key(kind)
    anchors = [k for k in ("start", anchor_key) if k in item]
    if len(anchors) > 1:
        r.fail(where, f"give '{anchors[0]}' or '{anchors[1]}', not both")
    if anchor_key in item and not isinstance(item[anchor_key], str):
        r.fail(f"{where}.{anchor_key}", f"must name an end such as main.end or W1.diverging, got {item[anchor_key]!r}")
    if kind == "section":
        if "segments" not in item:
            r.fail(f"{where}.segments", "missing: list the section's pieces")
        return i, r.line, kind, ident, item, ld.read_segments(r, item["segments"], f"{where}.segments")
    if kind == "crossing":
        by = item.get("by", "a")
        if not isinstance(by, str) or by not in ("a", "b"):
            r.fail(f"{where}.by", f"must be a or b (the track whose start is placed at 'at'), got {by!r}")
        return i, r.line, kind, ident, item, None
    piece = item.get("piece")
    if not isinstance(piece, str) or piece not in SWITCH_PIECES:
        r.fail(f"{where}.piece", f"must be one of {', '.join(SWITCH_PIECES)}, got {piece!r}")
    by = item.get("by", "toe")
    if not isinstance(by, str) or by not in ("toe",) + LEGS:
        r.fail(f"{where}.by", f"must be toe, straight or diverging (the switch end placed at 'at'), got {by!r}")
    if by != "toe" and "at" not in item:
        r.fail(f"{where}.by", "needs 'at': the end the switch's heel is placed on")
    return i, r.line, kind, ident, item, switch_legs(SWITCH_PIECES[piece])


def _place(r, items):
    """Place every item: a pose or an end already placed. Returns sections, switches and the ends by name."""
    ends, sections, switches, names = {}, [], [], {}
    pending = [_read_item(r, items, i, names) for i in range(len(items))]
    while pending:
        left = []
        for entry in pending:
            anchor = entry[4].get(_anchor_key(entry[2]))
            if anchor is not None and anchor not in ends:
                left.append(entry)
            else:
                _place_item(r, entry, ends, sections, switches)
        if len(left) == len(pending):
            _unresolved(r, left[0], items, names)
        pending = left
    return sections, switches, ends


def _place_item(r, entry, ends, sections, switches):
    i, line, kind, ident, item, segs = entry
    r.line = line
    where = f"track[{i}]"
    label = (i, line, f"{kind} {ident}")
    if kind == "section":
        _add_section(Section(ident, Path(segs, *_anchor_pose(r, item, "from", ends, where))), sections, ends, label)
        return
    if kind == "crossing":
        _place_crossing(r, item, ident, ends, sections, where, label)
        return
    x, y, h = _switch_toe(r, item, segs, ends, where)
    switches.append(Switch(ident, "left" if SWITCH_PIECES[item["piece"]] > 0 else "right", (x, y)))
    for leg in LEGS:
        path = Path(segs[leg], x, y, h)
        sections.append(Section(f"{ident}.{leg}", path, ident, leg))
        ends[f"{ident}.{leg}"] = _End(f"{ident}.{leg}", path.end_pose, ((f"{ident}.{leg}", END),), label)
    ends[f"{ident}.toe"] = _End(f"{ident}.toe", (x, y, h + math.pi), tuple((f"{ident}.{leg}", START) for leg in LEGS),
                                label)


def _anchor_pose(r, item, key, ends, where):
    """(x, y, heading) an item starts from: its `start` pose, or the outward pose of the end its `key` names."""
    if key not in item:
        return _pose(r, item.get("start", {}), f"{where}.start")
    e = ends[item[key]]
    return e.x_m, e.y_m, e.out_rad


def _add_section(section, sections, ends, label):
    """Add a section and its two ends (`name.start`, `name.end`, facing out of it)."""
    sections.append(section)
    name, (x, y, h) = section.name, section.path.start_pose
    ends[f"{name}.start"] = _End(f"{name}.start", (x, y, h + math.pi), ((name, START),), label)
    ends[f"{name}.end"] = _End(f"{name}.end", section.path.end_pose, ((name, END),), label)


def _place_crossing(r, item, ident, ends, sections, where, label):
    """A crossing's two tracks, `a` and `b` (a's heading + 90 degrees), from a start pose or from the end a's start
    (by: a) or b's start (by: b) is placed at."""
    x, y, h = _anchor_pose(r, item, "at", ends, where)
    if "at" in item and item.get("by", "a") == "b":     # from b's start to the middle, then back along a to a's start
        mx, my = x + CROSSING_HALF_M * math.cos(h), y + CROSSING_HALF_M * math.sin(h)
        h -= math.pi / 2
        x, y = mx - CROSSING_HALF_M * math.cos(h), my - CROSSING_HALF_M * math.sin(h)
    mx, my = x + CROSSING_HALF_M * math.cos(h), y + CROSSING_HALF_M * math.sin(h)
    hb = h + math.pi / 2
    starts = {"a": (x, y, h), "b": (mx - CROSSING_HALF_M * math.cos(hb), my - CROSSING_HALF_M * math.sin(hb), hb)}
    for track, pose in starts.items():
        path = Path([("straight", 2 * CROSSING_HALF_M)], *pose)
        _add_section(Section(f"{ident}.{track}", path, crossing=ident), sections, ends, label)


def _unresolved(r, entry, items, names):
    """Fail on an item whose anchor no placed end answers: a bad name, an unknown end, or a circle of anchors."""
    i, line, kind, _ident, item, _segs = entry
    key = _anchor_key(kind)
    r.line = line_of(item, key) or line
    anchor = item[key]
    if not isinstance(anchor, str) or "." not in anchor:
        r.fail(f"track[{i}].{key}", f"must name an end such as main.end or W1.diverging, got {anchor!r}")
    base = anchor.split(".")[0]
    if base not in names:
        r.fail(f"track[{i}].{key}", f"{anchor!r}: there is no section, switch or crossing {base!r} in track; name an "
                                    "end of one that is, or add it")
    known = _end_names(items[names[base]])
    if anchor not in known:
        r.fail(f"track[{i}].{key}", f"{anchor!r} is not an end of {base}: its ends are {', '.join(known)}")
    r.fail(f"track[{i}].{key}", f"{anchor!r} cannot be placed: {base} is itself placed from this item's ends; give "
                                "one of them a 'start' pose")


def _end_names(item):
    if "section" in item:
        return [f"{item['section']}.start", f"{item['section']}.end"]
    if "crossing" in item:
        return [f"{item['crossing']}.{t}.{e}" for t in ("a", "b") for e in ("start", "end")]
    return [f"{item['switch']}.{e}" for e in ("toe",) + LEGS]


def _switch_toe(r, item, segs, ends, where):
    """The toe pose (x, y, heading into the legs) of a switch placed by `start`, or by its toe or a heel `at` an end."""
    ex, ey, eh = _anchor_pose(r, item, "at", ends, where)
    by = item.get("by", "toe")    # a heel needs `at` (checked as the item was read)
    if by == "toe":
        return ex, ey, eh
    hx, hy, hh = Path(segs[by], 0.0, 0.0, 0.0).end_pose
    h = eh + math.pi - hh
    return ex - (hx * math.cos(h) - hy * math.sin(h)), ey - (hx * math.sin(h) + hy * math.cos(h)), h


def _on_graph(r, graph, item, where, key):
    section = item.get("section")
    if not isinstance(section, str) or section not in graph.sections:
        r.fail(f"{where}.section", f"{section!r} is off the graph: no such section; sections are "
               f"{', '.join(graph.sections)}")
    return section, _on_section(r, graph, section, r.number(item, key, where), f"{where}.{key}")


def _on_section(r, graph, section, offset, key):
    """`offset` (m), checked to lie on `section`."""
    length = graph.sections[section].length_m
    if not 0.0 <= offset <= length:
        r.fail(key, f"{offset} is off the graph: section {section} runs from 0 to {length:.4f} m")
    return offset


def _stations(r, items, graph):
    stations, seen = [], set()
    for i, item in enumerate(r.sequence(items, "stations")):
        where = f"stations[{i}]"
        r.line = line_of(items, i)
        item = r.mapping(item, where, ("name", "section", "offset_m", "back_offset_m", "window_m"))
        name = ld.read_station_name(r, item, where, seen)
        section, offset = _on_graph(r, graph, item, where, "offset_m")
        window_m = ld.read_window(r, item, where)
        length = graph.sections[section].length_m
        back = _on_section(r, graph, section, r.number(item, "back_offset_m", where, default=length - offset),
                           f"{where}.back_offset_m")
        stations.append(NetworkStation(name, section, offset, window_m, back))
    return stations


def _tags(r, items, graph):
    tags, uids = [], set()
    for i, item in enumerate(r.sequence(items, "tags")):
        where = f"tags[{i}]"
        r.line = line_of(items, i)
        item = r.mapping(item, where, ("uid", "section", "offset_m"))
        uid = ld.read_tag_uid(r, item, where)
        if uid in uids:
            r.fail(f"{where}.uid", f"duplicate uid {uid}: each tag needs its own")
        uids.add(uid)
        section, offset = _on_graph(r, graph, item, where, "offset_m")
        tags.append(NetworkTag(uid, section, offset))
    return tags
