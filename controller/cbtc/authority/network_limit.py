"""Moving block on a track network: where a train's authority ends along the route the interlocking holds for it.

The limit is the first of: the rear-most plausible tail of any other train whose span (widened by its uncertainty)
lies on the route ahead or fouls it at a switch the route runs through (a train converging on the other leg of a
merge included), a switch whose detected position is not the route's leg (moving, detection lost, wrong leg), the end
of the held route (the end of the track included: a route ends at a buffer stop at the latest). The fixed-block
baseline stops a train at the signal before the first occupied block instead. Pure: values in.
"""

from dataclasses import dataclass

from cbtc.railway.ahead import look_ahead
from cbtc.railway.geometry import forward_m
from cbtc.railway.network_layout import BLOCK_M, block_name, section_blocks


@dataclass(frozen=True)
class NetworkLimit:
    distance_m: float   # from the front-most plausible head, along the route
    reason: str         # what bounds it, in words


def network_limit(route, head_s_m, own, spans, detected_legs, reach_m=0.0) -> NetworkLimit:
    """The end of authority of train `own` with its front-most plausible head at `head_s_m` on `route` (the steps the
    interlocking holds for it, from the section its head is on), its head anywhere up to `reach_m` behind that: what
    lies ahead is read from the rear-most plausible head, so a switch or train between the two bounds it at 0.
    `spans`: every train's span, widened; `detected_legs`: switch -> leg its detection reports (None while moving or
    lost)."""
    ahead = look_ahead(route, head_s_m - reach_m, spans, own)
    best = NetworkLimit(max(0.0, ahead.end_m - reach_m), "the end of the route the interlocking holds for it")
    if ahead.trains and ahead.trains[0][1] - reach_m < best.distance_m:
        train, distance = ahead.trains[0]
        best = NetworkLimit(max(0.0, distance - reach_m), f"the rear-most plausible tail of train {train}")
    for switch, distance, leg in sorted(ahead.switches, key=lambda w: w[1]):   # nearest first (a loop comes round)
        distance = max(0.0, distance - reach_m)
        detected = detected_legs.get(switch)
        if detected != leg:
            if distance < best.distance_m:
                state = "not detected so (moving, detection lost, or out of correspondence with its command)" \
                    if detected is None else f"detected {detected}"
                best = NetworkLimit(distance, f"switch {switch}: the route needs {leg}, it is {state}")
            break
    return best


def fixed_block_limit(route, head_s_m, own, spans, detected_legs, block_m=BLOCK_M, reach_m=0.0) -> NetworkLimit:
    """The fixed-block baseline on a network: a signal at the entry of every block (railway.network_layout's
    section_blocks: every switch's toe and heels, and plain track cut every `block_m` at most), and a train may run up
    to the signal in front of the first block ahead that another train occupies or fouls (any part of a switch or
    crossing occupied fouls all of it; a switch or crossing whose exit block is taken counts as taken); never past
    what moving block allows either."""
    bound = network_limit(route, head_s_m, own, spans, detected_legs, reach_m)
    graph = route.graph
    sections = graph.sections
    occupied = set()   # (section, block index)
    for train, intervals in spans.items():
        if train == own:
            continue
        for name, lo, hi in intervals:
            occupied.update((mate, 0) for mate in graph.piece_mates(name))   # a piece's leg is one block
            for k, (b_lo, b_hi) in enumerate(section_blocks(sections[name], block_m)):
                if lo < b_hi and hi > b_lo:
                    occupied.add((name, k))
    ahead = []
    for (name, fwd), start in zip(route.steps, route.starts_m):
        length = sections[name].length_m
        for k, (b_lo, b_hi) in enumerate(section_blocks(sections[name], block_m)):
            entry = start + (b_lo if fwd else length - b_hi)
            d = forward_m(head_s_m, entry, route.length_m if route.closed else None)
            if d > 0.0:
                ahead.append((d, name, k))
    ahead.sort()
    # a switch's or crossing's signal clears only with the block beyond it clear too: a train let onto a junction
    # it cannot leave would hold it against the trains it waits for (a ring of blocks locked up)
    exit_taken = False
    for i in range(len(ahead) - 1, -1, -1):
        d, name, k = ahead[i]
        taken = (name, k) in occupied or (bool(sections[name].piece) and exit_taken)
        exit_taken = taken
        ahead[i] = (d, name, k, taken)
    for d, name, k, taken in ahead:
        if taken and d < bound.distance_m:
            block = block_name(name, k, len(section_blocks(sections[name], block_m)))
            why = "occupied" if (name, k) in occupied else "clear, the block beyond it not"
            return NetworkLimit(d, f"block {block} {why}: its signal is at danger")
    return bound
