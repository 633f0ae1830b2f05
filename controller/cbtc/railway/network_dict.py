"""A track network from the dict of its YAML file (a layout with a top-level `track:` list), checked.

Sections are chains of pieces placed from a pose or from an end already placed; switches are LEGO's left and right
switches placed by their toe or a heel. Ends meet where their positions agree within CLOSE_TOLERANCE_M and their
outward headings are opposite within CLOSE_TOLERANCE_DEG; every other end must be listed under `buffers`. Every error
names the file, the line of the item, the key and the fix. The format is in docs/layouts.md.
"""

import math

import numpy as np

from cbtc.railway import layout_dict as ld
from cbtc.railway.geometry import Path
from cbtc.railway.network_layout import NetworkLayout, NetworkStation, NetworkTag
from cbtc.railway.track_graph import END, LEGS, START, Node, Section, Switch, TrackGraph

TOP_KEYS = ("name", "track", "joins", "buffers", "stations", "tags", "ips")
SECTION_KEYS = ("section", "start", "from", "segments")
SWITCH_KEYS = ("switch", "piece", "start", "at", "by")
STUD_M = ld.STUD_M
CLEARANCE_M = 8 * STUD_M     # LEGO track is 8 studs wide: centre lines closer than this put two pieces on one spot
NODE_ZONE_M = 0.10           # near a node its sections run close by construction: not an overlap
SAMPLE_M = 0.01
R40_M = 40 * STUD_M
# LEGO's switch (macfreek.nl, "Lego train tracks geometry"): the straight leg is 32 studs; the diverging leg leaves
# on an R40 arc of atan(3/4) = 36.87 deg and turns back 14.37 deg, ending 22.5 deg out at (32.69, 12.955) studs, so
# that an R40 curve (22.5 deg) turned back brings it parallel to the straight leg 16 studs to the side, 48 studs on
DIVERGE_OUT_DEG = math.degrees(math.atan2(3.0, 4.0))
DIVERGE_BACK_DEG = DIVERGE_OUT_DEG - 22.5
SWITCH_PIECES = {"switch_left": 1.0, "switch_right": -1.0}


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


def _line(container, key):
    """The line of `key` (an index or a key) in a tree that keeps lines, 0 otherwise."""
    lines = getattr(container, "lines", None)
    if isinstance(lines, dict):
        return lines.get(key, getattr(container, "line", 0))
    if isinstance(lines, list) and isinstance(key, int) and key < len(lines):
        return lines[key]
    return getattr(container, "line", 0)


def _turn_deg(a_rad, b_rad):
    """|a - b| in degrees, the short way round."""
    return abs((math.degrees(a_rad - b_rad) + 180.0) % 360.0 - 180.0)


def network_from_dict(data, source, name) -> NetworkLayout:
    """Validate a network layout given as its parsed YAML tree (a mapping with `track:`)."""
    r = ld.Reader(source)
    r.mapping(data, "top level", TOP_KEYS)
    items = r.sequence(data["track"], "track")
    if not items:
        r.fail("track", "is empty: list sections and switches")
    sections, switches, ends = _place(r, items)
    graph = _join(r, data, sections, switches, ends)
    _check_overlaps(r, graph, ends)
    r.line = 0
    stations = _stations(r, data.get("stations", []), graph)
    tags = _tags(r, data.get("tags", []), graph)
    r.line = _line(data, "ips")
    ips = ld.read_ips(r, data.get("ips", {}))
    return NetworkLayout(name, source, graph, stations, tags, ips)


def _pose(r, spec, where):
    spec = r.mapping(spec, where, ("x_m", "y_m", "heading_deg"))
    return (r.number(spec, "x_m", where, default=0.0), r.number(spec, "y_m", where, default=0.0),
            math.radians(r.number(spec, "heading_deg", where, default=0.0)))


def _place(r, items):
    """Place every item: a pose or an end already placed. Returns sections, switches and the ends by name."""
    ends, sections, switches, names = {}, [], [], {}
    pending = []
    for i, item in enumerate(items):
        where = f"track[{i}]"
        r.line = _line(items, i)
        if not isinstance(item, dict):
            r.fail(where, f"must be a mapping such as {{section: main, segments: [...]}}, got {ld.kind_of(item)}")
        kinds = [k for k in ("section", "switch") if k in item]
        if len(kinds) != 1:
            r.fail(where, "needs exactly one of 'section' (a chain of pieces) or 'switch' (a LEGO switch)"
                   + (f", got {kinds}" if kinds else ""))
        kind = kinds[0]
        r.mapping(item, where, SECTION_KEYS if kind == "section" else SWITCH_KEYS)
        ident = item[kind]
        if not isinstance(ident, str) or not ident or "." in ident:
            r.fail(f"{where}.{kind}", f"must be a name without dots, got {ident!r}")
        if ident in names:
            r.fail(f"{where}.{kind}", f"{ident!r} is used twice (first at track[{names[ident]}]): give each its own")
        names[ident] = i
        anchors = [k for k in ("start", "from" if kind == "section" else "at") if k in item]
        if len(anchors) > 1:
            r.fail(where, f"give '{anchors[0]}' or '{anchors[1]}', not both")
        if kind == "section":
            if "segments" not in item:
                r.fail(f"{where}.segments", "missing: list the section's pieces")
            segs = ld.read_segments(r, item["segments"], f"{where}.segments")
        else:
            piece = item.get("piece")
            if piece not in SWITCH_PIECES:
                r.fail(f"{where}.piece", f"must be one of {', '.join(SWITCH_PIECES)}, got {piece!r}")
            by = item.get("by", "toe")
            if by not in ("toe",) + LEGS:
                r.fail(f"{where}.by", f"must be toe, straight or diverging (the switch end placed at 'at'), got {by!r}")
            if by != "toe" and "at" not in item:
                r.fail(f"{where}.by", "needs 'at': the end the switch's heel is placed on")
            segs = switch_legs(SWITCH_PIECES[piece])
        pending.append((i, r.line, kind, ident, item, segs))
    while pending:
        left = []
        for entry in pending:
            i, line, kind, ident, item, segs = entry
            anchor = item.get("from" if kind == "section" else "at")
            if anchor is not None and anchor not in ends:
                left.append(entry)
                continue
            r.line = line
            where = f"track[{i}]"
            label = (i, line, f"{kind} {ident}")
            if kind == "section":
                if anchor is None:
                    x, y, h = _pose(r, item.get("start", {}), f"{where}.start")
                else:
                    e = ends[anchor]
                    x, y, h = e.x_m, e.y_m, e.out_rad
                path = Path(segs, x, y, h)
                sections.append(Section(ident, path))
                ends[f"{ident}.start"] = _End(f"{ident}.start", (x, y, h + math.pi), ((ident, START),), label)
                ends[f"{ident}.end"] = _End(f"{ident}.end", path.end_pose, ((ident, END),), label)
            else:
                x, y, h = _switch_toe(r, item, segs, ends, where)
                hand = "left" if SWITCH_PIECES[item["piece"]] > 0 else "right"
                switches.append(Switch(ident, hand, (x, y)))
                for leg in LEGS:
                    path = Path(segs[leg], x, y, h)
                    sections.append(Section(f"{ident}.{leg}", path, ident, leg))
                    ends[f"{ident}.{leg}"] = _End(f"{ident}.{leg}", path.end_pose, ((f"{ident}.{leg}", END),),
                                                  label)
                ends[f"{ident}.toe"] = _End(f"{ident}.toe", (x, y, h + math.pi),
                                            tuple((f"{ident}.{leg}", START) for leg in LEGS), label)
        if len(left) == len(pending):
            i, line, kind, ident, item, _segs = left[0]
            key = "from" if kind == "section" else "at"
            r.line = _line(item, key) or line
            anchor = item[key]
            if not isinstance(anchor, str) or "." not in anchor:
                r.fail(f"track[{i}].{key}", f"must name an end such as main.end or W1.diverging, got {anchor!r}")
            base = anchor.split(".")[0]
            if base not in names:
                r.fail(f"track[{i}].{key}", f"{anchor!r}: there is no section or switch {base!r} in track; "
                                            "name an end of one that is, or add it")
            known = [n for n in _end_names(items[names[base]])]
            if anchor not in known:
                r.fail(f"track[{i}].{key}", f"{anchor!r} is not an end of {base}: its ends are {', '.join(known)}")
            r.fail(f"track[{i}].{key}", f"{anchor!r} cannot be placed: {base} is itself placed from this item's "
                                        "ends; give one of them a 'start' pose")
        pending = left
    return sections, switches, ends


def _end_names(item):
    if "section" in item:
        return [f"{item['section']}.start", f"{item['section']}.end"]
    return [f"{item['switch']}.{e}" for e in ("toe",) + LEGS]


def _switch_toe(r, item, segs, ends, where):
    """The toe pose (x, y, heading into the legs) of a switch placed by `start`, or by its toe or a heel `at` an end."""
    if "at" not in item:
        return _pose(r, item.get("start", {}), f"{where}.start")
    e = ends[item["at"]]
    by = item.get("by", "toe")
    if by == "toe":
        return e.x_m, e.y_m, e.out_rad
    hx, hy, hh = Path(segs[by], 0.0, 0.0, 0.0).end_pose
    h = e.out_rad + math.pi - hh
    return (e.x_m - (hx * math.cos(h) - hy * math.sin(h)), e.y_m - (hx * math.sin(h) + hy * math.cos(h)), h)


def _join(r, data, sections, switches, ends):
    """Nodes from the ends' poses; checks explicit joins and buffers and reports open or doubly joined ends."""
    buffers = {}
    spec = r.sequence(data.get("buffers", []), "buffers")
    for i, name in enumerate(spec):
        r.line = _line(spec, i)
        if name not in ends:
            r.fail(f"buffers[{i}]", f"{name!r} is not an end in track; ends are named like main.end or W1.straight")
        buffers[name] = i
    clusters = []
    for e in ends.values():
        for cluster in clusters:
            if math.hypot(cluster[0].x_m - e.x_m, cluster[0].y_m - e.y_m) <= ld.CLOSE_TOLERANCE_M:
                cluster.append(e)
                break
        else:
            clusters.append([e])
    nodes, side_of, open_ends = [], {}, []
    for cluster in clusters:
        first = cluster[0]
        side_a, side_b = [first], []
        for e in cluster[1:]:
            if _turn_deg(e.out_rad, first.out_rad) <= ld.CLOSE_TOLERANCE_DEG:
                side_a.append(e)
            elif _turn_deg(e.out_rad, first.out_rad + math.pi) <= ld.CLOSE_TOLERANCE_DEG:
                side_b.append(e)
            else:
                r.line = e.item[1]
                r.fail(f"track[{e.item[0]}]", f"{e.name} meets {first.name} at ({e.x_m:.3f}, {e.y_m:.3f}) m at "
                       f"{_turn_deg(e.out_rad, first.out_rad + math.pi):.1f} deg (tolerance {ld.CLOSE_TOLERANCE_DEG}): "
                       "ends that meet must run on in line; fix the pieces, or use a switch")
        for side, other in ((side_a, side_b), (side_b, side_a)):
            if len(side) > 1:
                late = max(side, key=lambda e: e.item[0])
                joined = f" to {other[0].name}" if other else ""
                r.line = late.item[1]
                r.fail(f"track[{late.item[0]}]", f"{late.name} is joined twice{joined}: "
                       f"{' and '.join(e.name for e in side)} lie on one spot ({late.x_m:.3f}, {late.y_m:.3f}) m "
                       "facing the same way; an end joins one other end only: remove or move one of them")
        if not side_b and first.name not in buffers:
            open_ends.append(first)
        elif side_b:
            for e in side_a + side_b:
                if e.name in buffers:
                    r.line = _line(spec, buffers[e.name])
                    r.fail(f"buffers[{buffers[e.name]}]", f"{e.name} is listed as a buffer stop but is joined to "
                           f"{(side_b if e in side_a else side_a)[0].name}: remove it from buffers")
        toe = next((e for e in side_a + side_b if e.name.endswith(".toe")), None)
        node = Node((first.x_m, first.y_m), tuple(g for e in side_a for g in e.graph_ends),
                    tuple(g for e in side_b for g in e.graph_ends), toe.name[:-4] if toe else "")
        nodes.append(node)
        for e in side_a:
            side_of[e.name] = (len(nodes) - 1, "a")
        for e in side_b:
            side_of[e.name] = (len(nodes) - 1, "b")
    if open_ends:   # the end of the item written last: the pieces that fall short are usually the last ones
        e = max(open_ends, key=lambda e: e.item[0])
        r.line = e.item[1]
        r.fail(f"track[{e.item[0]}]", f"{e.name} at ({e.x_m:.3f}, {e.y_m:.3f}) m is left open"
               f"{_nearest(e, clusters)}: fix the pieces so the ends meet within {ld.CLOSE_TOLERANCE_M * 1000:.0f}"
               f" mm and {ld.CLOSE_TOLERANCE_DEG} deg, or list {e.name} under buffers if it is a buffer stop")
    spec = r.sequence(data.get("joins", []), "joins")
    for i, pair in enumerate(spec):
        r.line = _line(spec, i)
        if not isinstance(pair, list) or len(pair) != 2:
            r.fail(f"joins[{i}]", f"must be a pair of ends such as [loop.end, W2.diverging], got {pair!r}")
        for name in pair:
            if name not in ends:
                r.fail(f"joins[{i}]", f"{name!r} is not an end in track; ends are named like main.end or W1.toe")
        a, b = (ends[n] for n in pair)
        na, nb = side_of[a.name], side_of[b.name]
        if na[0] != nb[0] or na[1] == nb[1]:
            gap = math.hypot(a.x_m - b.x_m, a.y_m - b.y_m)
            r.fail(f"joins[{i}]", f"{a.name} and {b.name} do not meet: they are {gap * 1000:.1f} mm apart and "
                   f"{_turn_deg(a.out_rad, b.out_rad + math.pi):.1f} deg off (tolerance "
                   f"{ld.CLOSE_TOLERANCE_M * 1000:.0f} mm, {ld.CLOSE_TOLERANCE_DEG} deg): fix the pieces between them")
    return TrackGraph(sections, switches, nodes)


def _nearest(e, clusters):
    best = None
    for cluster in clusters:
        if len(cluster) == 1 and cluster[0] is not e:
            o = cluster[0]
            d = math.hypot(o.x_m - e.x_m, o.y_m - e.y_m)
            if best is None or d < best[0]:
                best = (d, o)
    if best is None:
        return ""
    d, o = best
    off_deg = _turn_deg(e.out_rad, o.out_rad + math.pi)
    return f"; the nearest open end is {o.name}, {d * 1000:.1f} mm away and {off_deg:.1f} deg off line"


def _samples(section):
    count = max(2, int(math.ceil(section.length_m / SAMPLE_M)) + 1)
    s = np.linspace(0.0, section.length_m, count)
    return s, section.path.xy(s)


def _check_overlaps(r, graph, ends):
    """Centre lines of different pieces closer than the track's width, away from the nodes they share: an error."""
    label = {}
    for e in ends.values():
        for section, _which in e.graph_ends:
            label[section] = e.item
    names = list(graph.sections)
    sampled = {n: _samples(graph.sections[n]) for n in names}
    node_xy = {n: [np.asarray(graph.node_at((n, w)).xy_m) for w in (START, END)] for n in names}
    for ia, a in enumerate(names):
        sa, pa = sampled[a]
        for b in names[ia:]:
            sec_a, sec_b = graph.sections[a], graph.sections[b]
            if a != b and sec_a.switch and sec_a.switch == sec_b.switch:
                continue
            sb, pb = sampled[b]
            d = np.linalg.norm(pa[:, None, :] - pb[None, :, :], axis=-1)
            close = d < CLEARANCE_M
            if a == b:
                close &= np.abs(sa[:, None] - sb[None, :]) > 2.0 * NODE_ZONE_M
            for na in node_xy[a]:
                for nb in node_xy[b]:
                    if np.hypot(*(na - nb)) <= ld.CLOSE_TOLERANCE_M:
                        near_a = np.linalg.norm(pa - na, axis=-1) <= NODE_ZONE_M
                        near_b = np.linalg.norm(pb - na, axis=-1) <= NODE_ZONE_M
                        close &= ~(near_a[:, None] & near_b[None, :])
            if close.any():
                i, j = np.unravel_index(np.argmin(np.where(close, d, np.inf)), d.shape)
                item_a, item_b = label[a], label[b]
                later = max(item_a, item_b)
                r.line = later[1]
                x, y = pa[i]
                what = f"{item_a[2]} runs over itself" if a == b else \
                    f"{item_a[2]} (track[{item_a[0]}]) and {item_b[2]} (track[{item_b[0]}]) overlap"
                r.fail(f"track[{later[0]}]", f"{what}: at ({x:.3f}, {y:.3f}) m the centre lines are "
                       f"{d[i, j] * 1000:.0f} mm apart ({a} at {sa[i]:.3f} m, {b} at {sb[j]:.3f} m), closer than "
                       f"the track's width ({CLEARANCE_M * 1000:.0f} mm, 8 studs): move the pieces apart, or join "
                       "them at a switch")


def _on_graph(r, graph, item, where, key):
    section = item.get("section")
    if section not in graph.sections:
        r.fail(f"{where}.section", f"{section!r} is off the graph: no such section; sections are "
               f"{', '.join(graph.sections)}")
    length = graph.sections[section].length_m
    offset = r.number(item, key, where)
    if not 0.0 <= offset <= length:
        r.fail(f"{where}.{key}", f"{offset} is off the graph: section {section} runs from 0 to {length:.4f} m")
    return section, offset


def _stations(r, items, graph):
    stations, seen = [], set()
    for i, item in enumerate(r.sequence(items, "stations")):
        where = f"stations[{i}]"
        r.line = _line(items, i)
        item = r.mapping(item, where, ("name", "section", "offset_m", "window_m"))
        name = item.get("name")
        if not isinstance(name, str) or not name:
            r.fail(f"{where}.name", f"missing or not a string ({name!r}): give the station a name")
        if name in seen:
            r.fail(f"{where}.name", f"duplicate station name {name!r}: names must be unique")
        seen.add(name)
        section, offset = _on_graph(r, graph, item, where, "offset_m")
        window_m = r.number(item, "window_m", where, positive=True, default=ld.DEFAULT_WINDOW_M)
        if window_m < ld.MIN_WINDOW_M:
            r.fail(f"{where}.window_m", f"{window_m} m is finer than a train stops: give at least {ld.MIN_WINDOW_M}")
        stations.append(NetworkStation(name, section, offset, window_m))
    return stations


def _tags(r, items, graph):
    tags, uids = [], set()
    for i, item in enumerate(r.sequence(items, "tags")):
        where = f"tags[{i}]"
        r.line = _line(items, i)
        item = r.mapping(item, where, ("uid", "section", "offset_m"))
        uid = ld.read_tag_uid(r, item, where)
        if uid in uids:
            r.fail(f"{where}.uid", f"duplicate uid {uid}: each tag needs its own")
        uids.add(uid)
        section, offset = _on_graph(r, graph, item, where, "offset_m")
        tags.append(NetworkTag(uid, section, offset))
    return tags
