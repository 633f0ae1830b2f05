"""How the pieces of a track network meet: ends joined into nodes by their poses, buffers and explicit joins
checked, and pieces that overlap found. Every error names the file, the line of the item and the fix."""

import math

import numpy as np

from cbtc.railway import layout_dict as ld
from cbtc.railway.track_graph import END, START, Node, TrackGraph

CLEARANCE_M = 8 * ld.STUD_M  # LEGO track is 8 studs wide: centre lines closer than this put two pieces on one spot
NODE_ZONE_M = 0.10           # near a node its sections run close by construction: not an overlap
SAMPLE_M = 0.01


def line_of(container, key):
    """The line of `key` (an index or a key) in a tree that keeps lines, 0 otherwise."""
    lines = getattr(container, "lines", None)
    if isinstance(lines, dict):
        return lines.get(key, getattr(container, "line", 0))
    if isinstance(lines, list) and isinstance(key, int) and key < len(lines):
        return lines[key]
    return getattr(container, "line", 0)


def turn_deg(a_rad, b_rad):
    """|a - b| in degrees, the short way round."""
    return abs((math.degrees(a_rad - b_rad) + 180.0) % 360.0 - 180.0)


def join(r, data, sections, switches, ends):
    """The graph: nodes from the ends' poses, with the buffers and the explicit joins checked; open and doubly joined
    ends reported."""
    spec = r.sequence(data.get("buffers", []), "buffers")
    buffers = {}
    for i, name in enumerate(spec):
        r.line = line_of(spec, i)
        if not isinstance(name, str) or name not in ends:
            r.fail(f"buffers[{i}]", f"{name!r} is not an end in track; ends are named like main.end or W1.straight")
        if name in buffers:
            r.fail(f"buffers[{i}]", f"{name} is listed twice (first at buffers[{buffers[name]}]): keep one")
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
        side_a, side_b = _sides(r, cluster)
        if not side_b and side_a[0].name not in buffers:
            open_ends.append(side_a[0])
        for e in (side_a + side_b) if side_b else ():
            if e.name in buffers:
                r.line = line_of(spec, buffers[e.name])
                r.fail(f"buffers[{buffers[e.name]}]", f"{e.name} is listed as a buffer stop but is joined to "
                       f"{(side_b if e in side_a else side_a)[0].name}: remove it from buffers")
        toe = next((e for e in side_a + side_b if e.name.endswith(".toe")), None)
        nodes.append(Node((side_a[0].x_m, side_a[0].y_m), tuple(g for e in side_a for g in e.graph_ends),
                          tuple(g for e in side_b for g in e.graph_ends), toe.name[:-4] if toe else ""))
        side_of.update({e.name: (len(nodes) - 1, "a") for e in side_a})
        side_of.update({e.name: (len(nodes) - 1, "b") for e in side_b})
    if open_ends:   # the end of the item written last: the pieces that fall short are usually the last ones
        e = max(open_ends, key=lambda e: e.item[0])
        r.line = e.item[1]
        r.fail(f"track[{e.item[0]}]", f"{e.name} at ({e.x_m:.3f}, {e.y_m:.3f}) m is left open"
               f"{_nearest(e, clusters)}: fix the pieces so the ends meet within {ld.CLOSE_TOLERANCE_M * 1000:.0f}"
               f" mm and {ld.CLOSE_TOLERANCE_DEG} deg, or list {e.name} under buffers if it is a buffer stop")
    _check_joins(r, data, ends, side_of)
    return TrackGraph(sections, switches, nodes)


def _sides(r, cluster):
    """The two sides of the ends meeting at one spot, by outward heading; fails on ends at an angle or on one side
    holding two."""
    first = cluster[0]
    side_a, side_b = [first], []
    for e in cluster[1:]:
        if turn_deg(e.out_rad, first.out_rad) <= ld.CLOSE_TOLERANCE_DEG:
            side_a.append(e)
        elif turn_deg(e.out_rad, first.out_rad + math.pi) <= ld.CLOSE_TOLERANCE_DEG:
            side_b.append(e)
        else:
            r.line = e.item[1]
            r.fail(f"track[{e.item[0]}]", f"{e.name} meets {first.name} at ({e.x_m:.3f}, {e.y_m:.3f}) m at "
                   f"{turn_deg(e.out_rad, first.out_rad + math.pi):.1f} deg (tolerance {ld.CLOSE_TOLERANCE_DEG}): "
                   "ends that meet must run on in line; fix the pieces, or use a switch")
    for side, other in ((side_a, side_b), (side_b, side_a)):
        if len(side) > 1:
            late = max(side, key=lambda e: e.item[0])
            joined = f" to {other[0].name}" if other else ""
            r.line = late.item[1]
            r.fail(f"track[{late.item[0]}]", f"{late.name} is joined twice{joined}: "
                   f"{' and '.join(e.name for e in side)} lie on one spot ({late.x_m:.3f}, {late.y_m:.3f}) m "
                   "facing the same way; an end joins one other end only: remove or move one of them")
    return side_a, side_b


def _check_joins(r, data, ends, side_of):
    """Each explicit join names two ends that meet, facing each other."""
    spec = r.sequence(data.get("joins", []), "joins")
    for i, pair in enumerate(spec):
        r.line = line_of(spec, i)
        if not isinstance(pair, list) or len(pair) != 2:
            r.fail(f"joins[{i}]", f"must be a pair of ends such as [loop.end, W2.diverging], got {pair!r}")
        for name in pair:
            if not isinstance(name, str) or name not in ends:
                r.fail(f"joins[{i}]", f"{name!r} is not an end in track; ends are named like main.end or W1.toe")
        a, b = (ends[n] for n in pair)
        na, nb = side_of[a.name], side_of[b.name]
        if na[0] != nb[0] or na[1] == nb[1]:
            gap = math.hypot(a.x_m - b.x_m, a.y_m - b.y_m)
            r.fail(f"joins[{i}]", f"{a.name} and {b.name} do not meet: they are {gap * 1000:.1f} mm apart and "
                   f"{turn_deg(a.out_rad, b.out_rad + math.pi):.1f} deg off (tolerance "
                   f"{ld.CLOSE_TOLERANCE_M * 1000:.0f} mm, {ld.CLOSE_TOLERANCE_DEG} deg): fix the pieces between them")


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
    off_deg = turn_deg(e.out_rad, o.out_rad + math.pi)
    return f"; the nearest open end is {o.name}, {d * 1000:.1f} mm away and {off_deg:.1f} deg off line"


def _samples(section):
    count = max(2, int(math.ceil(section.length_m / SAMPLE_M)) + 1)
    s = np.linspace(0.0, section.length_m, count)
    return s, section.path.xy(s)


def check_overlaps(r, graph, ends):
    """Centre lines of different pieces closer than the track's width, away from the nodes they share: an error."""
    label = {}
    for e in ends.values():
        for section, _which in e.graph_ends:
            label[section] = e.item
    names = list(graph.sections)
    sampled = {n: _samples(graph.sections[n]) for n in names}
    node_xy = {n: [np.asarray(graph.node_at((n, w)).xy_m) for w in (START, END)] for n in names}
    for ia, a in enumerate(names):
        for b in names[ia:]:
            sec_a, sec_b = graph.sections[a], graph.sections[b]
            if a != b and sec_a.piece and sec_a.piece == sec_b.piece:
                continue     # the legs of one switch, the tracks of one crossing
            shared = [na for na in node_xy[a] for nb in node_xy[b] if np.hypot(*(na - nb)) <= ld.CLOSE_TOLERANCE_M]
            found = _closest_overlap(sampled[a], sampled[b], a == b, shared)
            if found is None:
                continue
            d, i, j = found
            (sa, pa), (sb, _pb) = sampled[a], sampled[b]
            item_a, item_b = label[a], label[b]
            later = max(item_a, item_b)
            r.line = later[1]
            x, y = pa[i]
            what = f"{item_a[2]} runs over itself" if a == b else \
                f"{item_a[2]} (track[{item_a[0]}]) and {item_b[2]} (track[{item_b[0]}]) overlap"
            r.fail(f"track[{later[0]}]", f"{what}: at ({x:.3f}, {y:.3f}) m the centre lines are {d * 1000:.0f} mm "
                   f"apart ({a} at {sa[i]:.3f} m, {b} at {sb[j]:.3f} m), closer than the track's width "
                   f"({CLEARANCE_M * 1000:.0f} mm, 8 studs): move the pieces apart, or join them at a switch")


def _closest_overlap(sampled_a, sampled_b, same, shared_nodes, rows=512):
    """(distance, i, j) of the closest pair of samples closer than CLEARANCE_M that neither lies within NODE_ZONE_M
    of a node both share (nor, on one section, within 2 NODE_ZONE_M of each other along it), or None. Far apart
    boxes are skipped and the rows taken a block at a time, so a long layout costs little memory."""
    (sa, pa), (sb, pb) = sampled_a, sampled_b
    if np.any(pa.min(axis=0) - CLEARANCE_M > pb.max(axis=0)) or np.any(pb.min(axis=0) - CLEARANCE_M > pa.max(axis=0)):
        return None
    near_b = [np.linalg.norm(pb - n, axis=-1) <= NODE_ZONE_M for n in shared_nodes]
    best = None
    for lo in range(0, len(pa), rows):
        block = pa[lo:lo + rows]
        d = np.linalg.norm(block[:, None, :] - pb[None, :, :], axis=-1)
        close = d < CLEARANCE_M
        if not close.any():
            continue
        if same:
            close &= np.abs(sa[lo:lo + rows, None] - sb[None, :]) > 2.0 * NODE_ZONE_M
        for n, nb in zip(shared_nodes, near_b):
            near_a = np.linalg.norm(block - n, axis=-1) <= NODE_ZONE_M
            close &= ~(near_a[:, None] & nb[None, :])
        if close.any():
            i, j = np.unravel_index(np.argmin(np.where(close, d, np.inf)), d.shape)
            if best is None or d[i, j] < best[0]:
                best = (float(d[i, j]), lo + int(i), int(j))
    return best
