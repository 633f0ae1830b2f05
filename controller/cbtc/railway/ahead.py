"""What lies ahead of a train on its route: the next trains, the switches, the route's end.

On a single path (a loop or a line) the route is the path itself and the trains are ordered by head position:
`ahead_index` and `trains_ahead` give the train ahead, as the zone, the simulator's truth and the recorder ask it.
On a track network `look_ahead` reads a route: every train whose span lies on the route ahead of the head, or fouls
it at a switch or crossing the route runs through (a train on the switch's other leg: the converging branch of a
merge; a train on the crossing's other track), with the distance to it; the switches in the route with the distance
to where the route enters each; the distance to the route's end.
"""

from dataclasses import dataclass
from math import inf

from cbtc.railway.geometry import forward_m


def ahead_index(count, i, closed):
    """The index of the train ahead of the `i`-th of `count` trains ordered by head position along one path, or None:
    alone, or at the front of an open line, where the end of the track limits it."""
    if count < 2 or (i == count - 1 and not closed):
        return None
    return (i + 1) % count


def trains_ahead(heads_m, closed):
    """{i: j}: the index of the train ahead of train i, for trains with heads at `heads_m` along one path (on a line
    the front train has none)."""
    order = sorted(range(len(heads_m)), key=lambda i: heads_m[i])
    ahead = {}
    for rank, i in enumerate(order):
        j = ahead_index(len(order), rank, closed)
        if j is not None:
            ahead[i] = order[j]
    return ahead


@dataclass(frozen=True)
class Ahead:
    """What a train at `head_s_m` on a route meets, distances from its head along the route (m)."""
    trains: tuple      # ((train, distance_m), ...) nearest first: to the nearest point of its span that fouls the route
    switches: tuple    # ((switch, distance_m, leg), ...) in route order: where the route enters the switch, its leg
    end_m: float       # to the end of the route; inf on a closed route


def look_ahead(route, head_s_m, spans, own=None):
    """What lies ahead of a head at route coordinate `head_s_m`. `spans` maps train -> ((section, lo_m, hi_m), ...),
    each already widened by its uncertainty; `own` names the train itself, whose span is left out."""
    graph, length, closed = route.graph, route.length_m, route.closed
    loop_m = length if closed else None      # forward_m's loop length: None on an open route
    on_route = {name: (start, forward) for (name, forward), start in zip(route.steps, route.starts_m)}
    piece_entry = {}     # switch or crossing -> distance to where the route enters it
    switches = []
    for (name, _fwd), start in zip(route.steps, route.starts_m):
        section = graph.sections[name]
        if section.piece:
            into = forward_m(start, head_s_m, loop_m)            # how far the head is past the route's entry
            if 0.0 <= into < section.length_m:
                d = 0.0                                          # on the piece
            elif closed or into < 0.0:
                d = forward_m(head_s_m, start, loop_m)
            else:
                continue                                         # passed
            piece_entry[section.piece] = min(d, piece_entry.get(section.piece, inf))
            if section.switch:
                switches.append((section.switch, d, section.leg))
    found = {}
    for train, intervals in spans.items():
        if train == own:
            continue
        for name, lo, hi in intervals:
            piece = graph.sections[name].piece      # one train anywhere on a switch or crossing fouls all of it
            if piece in piece_entry:
                found[train] = min(found.get(train, inf), piece_entry[piece])
            if name not in on_route:
                continue
            start, forward = on_route[name]
            sec_len = graph.sections[name].length_m
            a, b = (start + lo, start + hi) if forward else (start + sec_len - hi, start + sec_len - lo)
            if closed:
                d = 0.0 if forward_m(a, head_s_m, loop_m) <= b - a else forward_m(head_s_m, a, loop_m)
            elif b < head_s_m:
                continue
            else:
                d = max(a - head_s_m, 0.0)
            found[train] = min(found.get(train, inf), d)
    end_m = inf if closed else max(length - head_s_m, 0.0)
    return Ahead(tuple(sorted(found.items(), key=lambda kv: (kv[1], kv[0]))), tuple(switches), end_m)
