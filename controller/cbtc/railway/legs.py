"""A train's itinerary on a track network it cannot run round (a line between termini): legs from buffer stop to
buffer stop, the train reversing at the end of each.

One round of the plan runs from the start step through the cheapest way to each stop in turn and back to the start
step, reversing at a buffer stop where the track ends; a section the round has already run costs REUSE_COST times
its length, so the way back takes the other track of a passing loop. The round is cut at its reversals into legs,
the first running through the start. Each leg is a path the train runs forwards (its own frame, with the plan's
stops on it), and every other leg it runs the other end first: its IPS beacon and RFID reader, fitted at the end that
led at the start, then trail its head by its length, and they read on `sensors`, the leg's frame shifted by that
much. Pure: values in, legs out.
"""

import heapq
from dataclasses import dataclass

from cbtc.errors import ConfigError
from cbtc.railway.network_layout import route_layout, sensor_frame

REUSE_COST = 3.0    # a section already run this round costs this many times its length
TURN_COST_M = 0.5   # a reversal costs this much: a way through is taken before one that reverses


@dataclass(frozen=True)
class Leg:
    """One leg of a reversing itinerary: its Route, its frame (the path Layout the zone and the simulator see the train
    on), `sensors` (where its sensors read: the frame, or the frame shifted by the train's length when it runs the
    other end first, `backwards`), and the plan's stops on it."""
    route: object
    frame: object
    sensors: object
    stops: tuple
    backwards: bool


def _cheapest(graph, origin, goal, used):
    """The steps after `origin` of the cheapest way to a step `goal` accepts, reversing at buffer stops; None."""
    queue, best, count = [(0.0, 0, origin, ())], {}, 1   # the origin may be the goal again, the long way round
    while queue:
        cost, _n, step, path = heapq.heappop(queue)
        if path and goal(step):
            return list(path)
        if cost > best.get(step, float("inf")):
            continue
        ways = [(nxt, graph.sections[nxt[0]].length_m * (REUSE_COST if nxt[0] in used else 1.0))
                for nxt in graph.next_steps(*step)]
        if not ways:    # a buffer stop: the train reverses on the section it stands on
            ways = [((step[0], not step[1]), TURN_COST_M)]
        for nxt, extra in ways:
            if cost + extra < best.get(nxt, float("inf")) and len(path) < 64:
                best[nxt] = cost + extra
                heapq.heappush(queue, (cost + extra, count, nxt, path + (nxt,)))
                count += 1
    return None


def reversing_round(network, start, plan):
    """(steps, stop_at) of one round of `plan` from step `start`, reversals included (two steps on one section, the
    second the other way); stop_at maps each stop to the index of the step it is made on."""
    graph = network.graph
    steps, stop_at, used = [tuple(start)], {}, {start[0]}
    for name in plan:
        target = network.station(name).section
        if target == start[0] and len(steps) == 1:
            stop_at[name] = 0
            continue
        way = _cheapest(graph, steps[-1], lambda step, t=target: step[0] == t, used)
        if way is None:
            raise ConfigError(f"{network.source}: plan {list(plan)}: station {name} (section {target}) cannot be "
                              f"reached from {steps[-1][0]}: give stations the track joins")
        steps.extend(way)
        used.update(s for s, _f in way)
        stop_at[name] = len(steps) - 1
    back = _cheapest(graph, steps[-1], lambda step: step == tuple(start), used)
    if back is None:
        raise ConfigError(f"{network.source}: plan {list(plan)}: no way back to section {start[0]} from "
                          f"{steps[-1][0]}")
    steps.extend(back[:-1])
    return steps, stop_at


def legs(network, start, plan, length_m, name="train"):
    """The legs (Leg, ...) of a train of `length_m` on `network` from step `start` with `plan` (station names), in
    the order it runs them, round and round (an even number: a leg run the other end first comes back to the end
    that led); None when the round needs no reversal (cbtc.railway.itinerary runs it); ConfigError naming the plan
    when a leg would run a section twice."""
    steps, stop_at = reversing_round(network, tuple(start), plan)
    n = len(steps)
    turns = [i for i in range(n) if steps[(i + 1) % n] == (steps[i][0], not steps[i][1])]
    if not turns:
        return None
    out = []
    for k, end in enumerate(turns):
        begin = turns[k - 1] + 1 if k else turns[-1] + 1 - n
        idx = [i % n for i in range(begin, end + 1)]
        leg_steps = tuple(steps[i] for i in idx)
        if len({s for s, _f in leg_steps}) < len(leg_steps):
            raise ConfigError(f"{network.source}: plan {list(plan)}: a leg between reversals runs a section twice "
                              f"({'+'.join(s for s, _f in leg_steps)}): give a plan whose stops lie along the line")
        stops = tuple(stop for stop, i in stop_at.items() if i in idx)
        out.append((leg_steps, stops))
    if len(out) % 2:
        out = out + out
    found = []
    for k, (leg_steps, stops) in enumerate(out):
        frame = route_layout(network, leg_steps, name=f"{network.name} ({name}'s leg {k + 1})", stops=stops)
        backwards = k % 2 == 1
        found.append(Leg(network.graph.route(leg_steps), frame, sensor_frame(frame, length_m) if backwards else frame,
                         stops, backwards))
    return tuple(found)


def turned_head_s(old, new, head_s, length_m):
    """Where the head of a train of `length_m` with its head at `head_s` on leg `old` is on leg `new` once it has
    reversed: where its tail was."""
    section, offset = old.route.locate(head_s - length_m)
    s = new.route.s_of(section, offset)
    if s is None:
        raise ValueError(f"leg {new.frame.name} does not run section {section}, where the train reverses")
    return s


def next_leg(legs, k, backwards, section=None):
    """The index of the first leg after leg `k` in the plan's round that runs `backwards` (or not), over `section`
    when it is given; None if there is none."""
    n = len(legs)
    for j in range(k + 1, k + n):
        leg = legs[j % n]
        if leg.backwards == backwards and (section is None or any(name == section for name, _f in leg.route.steps)):
            return j % n
    return None


def turned_leg(legs, k, head_s, length_m):
    """The leg a train of `length_m` on leg `k` with its head at `head_s` runs on once it has reversed: the next one
    in the plan that runs the other way over the section its tail is on (the next leg, at a leg's end)."""
    section, _offset = legs[k].route.locate(head_s - length_m)
    found = next_leg(legs, k, not legs[k].backwards, section)
    return (k + 1) % len(legs) if found is None else found
