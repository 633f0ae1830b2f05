"""A queue of trains on a track network: each with a plan over the layout's stations and its itinerary, all put down
one behind the other on the network's longest plain section, the front one first. On a line (its stations can only be
reached by reversing) the trains stand at its termini instead, one on each terminus track, and shuttle to the track
across the line and back, reversing at its ends."""

from cbtc.authority.rules import AuthorityParams
from cbtc.errors import ConfigError
from cbtc.railway.itinerary import default_plans, itinerary
from cbtc.railway.legs import legs
from cbtc.railway.network_layout import route_layout
from cbtc.railway.train_profile import TrainProfile
from cbtc.zone.config import ScenarioConfig, TrainSpec


def network_queue(network, n_trains, seed=0, duration_s=300.0, **overrides) -> ScenarioConfig:
    """`n_trains` trains on `network`, train k with the k-th of `default_plans`, spread along its longest section that
    is no switch or crossing (running it forwards); on a line they reverse at its ends (cbtc.railway.legs).
    ConfigError when they do not fit there."""
    params = overrides.get("params", AuthorityParams())
    graph = network.graph
    plain = [s for s in graph.sections.values() if not s.piece]
    if not plain:
        raise ConfigError(f"{network.source}: no section outside a switch or crossing to put trains on")
    start = max(plain, key=lambda s: (s.length_m, s.name))
    step = (start.name, True)
    # a train that reverses runs either end first: no tail beacon, which would lead on every other leg
    line = not graph.route(itinerary(network, step, default_plans(network, step, 1)[0])).closed
    termini = _termini(network) if line else None
    if termini and len(termini) % 2 == 0:   # terminus tracks that pair up across the line
        return ScenarioConfig(layout=network, trains=_line_trains(network, n_trains, termini), seed=seed,
                              duration_s=duration_s, **overrides)
    profile = TrainProfile(tail_beacon=0 if line else 1)
    need_m = profile.length_m + params.margin_m + 0.05
    if n_trains < 1 or n_trains * need_m > start.length_m - 0.05:
        raise ConfigError(f"{n_trains} trains do not fit on section {start.name} of {network.name} "
                          f"({start.length_m:.2f} m), where trains are put down: at most "
                          f"{int((start.length_m - 0.05) // need_m)} with {need_m:.2f} m per train")
    spacing_m = (start.length_m - 0.05) / n_trains
    trains = []
    for k, plan in enumerate(default_plans(network, step, n_trains)):
        train_id = f"T{k + 1}"
        head_m = start.length_m - 0.05 - k * spacing_m
        if line:
            found = legs(network, step, plan, profile.length_m, train_id)
            first = found[0]
            trains.append(TrainSpec(train_id, first.route.s_of(start.name, head_m), plan, profile, frame=first.frame,
                                    route=first.route, legs=found))
            continue
        steps = itinerary(network, step, plan)
        route = graph.route(steps)
        frame = route_layout(network, steps, name=f"{network.name} ({train_id}'s itinerary)")
        trains.append(TrainSpec(train_id, route.s_of(start.name, head_m), plan, profile, frame=frame, route=route))
    return ScenarioConfig(layout=network, trains=trains, seed=seed, duration_s=duration_s, **overrides)


def _termini(network):
    """The steps leading out of every station's section that ends at a buffer stop, in the layout's order of
    stations: where trains on a line stand at the start."""
    graph, out = network.graph, []
    for st in network.stations:
        for forward in (True, False):
            step = (st.section, forward)
            if graph.next_steps(*step) and not graph.next_steps(st.section, not forward) and step not in out:
                out.append(step)
    return out


def _line_trains(network, n_trains, termini):
    """Train k stands on the k-th terminus track, facing out, its tail 0.1 m from the buffer stop; its plan is the
    terminus track half the list away (across the line) and its own, by way of a passing station: the first for
    trains from the first half of the termini, the second for the others, and the other one on the way back, so
    trains running one way keep to one track of a passing loop."""
    if not 1 <= n_trains <= len(termini):
        raise ConfigError(f"{network.name} is a line with {len(termini)} terminus tracks: give 1 to {len(termini)} "
                          f"trains (one stands on each at the start)")
    ends = {step[0] for step in termini}
    passing = [st.name for st in network.stations if st.section not in ends] or [None]
    profile = TrainProfile(tail_beacon=0)   # a train that reverses runs either end first: no tail beacon
    half, trains = max(1, len(termini) // 2), []
    for k in range(n_trains):
        start, far = termini[k], termini[(k + half) % len(termini)]
        here, there = (next(st.name for st in network.stations if st.section == step[0]) for step in (start, far))
        out, back = (passing[0], passing[-1]) if k < half else (passing[-1], passing[0])
        plan = tuple(name for name in (out, there, back, here) if name is not None)
        train_id = f"T{k + 1}"
        found = legs(network, start, plan, profile.length_m, train_id)
        trains.append(TrainSpec(train_id, profile.length_m + 0.1, plan, profile, frame=found[0].frame,
                                route=found[0].route, legs=found))
    return trains
