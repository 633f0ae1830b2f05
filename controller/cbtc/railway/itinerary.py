"""A train's itinerary on a track network: the steps it runs to make its plan's stops in order, round and round.

A plan is station names; the itinerary runs from the train's start step through the shortest route to each stop in
turn (a stop on the start section is on every round) and back to the start, one round of the plan: a closed route
when it comes back running the same way (each section once a round). A plan that cannot come back (a line to a
buffer stop) ends at its last stop's section and runs on while the track leads one way only, to the buffer. Pure:
values in, steps out.
"""

from cbtc.errors import ConfigError
from cbtc.railway.interlocking import find_routes

MAX_STEPS = 24   # sections in one leg of a plan (find_routes' bound)


def itinerary(network, start, plan):
    """The steps ((section, forward), ...) of a train starting on step `start` whose plan is `plan` (station names);
    ConfigError naming the plan and the fix when a stop cannot be reached or a round runs a section twice."""
    graph = network.graph
    start = (str(start[0]), bool(start[1]))
    if start[0] not in graph.sections:
        raise ConfigError(f"{network.source}: no section {start[0]!r} to start a train on; sections are "
                          f"{', '.join(graph.sections)}")
    steps = [start]
    for name in plan:
        target = network.station(name).section
        if target == start[0]:
            continue          # the start section: every round runs it
        leg = _leg(graph, steps, target)
        if leg is None:
            raise ConfigError(f"{network.source}: plan {list(plan)}: station {name} (section {target}) cannot be "
                              f"reached from {steps[-1][0]} without running a section twice in one round: give a "
                              f"plan whose stops lie along one way round")
        steps.extend(leg)
    back = _leg(graph, steps, start[0], closing=True)
    if back is not None:
        steps.extend(back[:-1])
        return tuple(steps)
    while True:
        ways = [w for w in graph.next_steps(*steps[-1]) if w[0] not in {s for s, _f in steps}]
        if len(ways) != 1:
            return tuple(steps)
        steps.append(ways[0])


def _leg(graph, steps, target, closing=False):
    """The steps after `steps[-1]` of the shortest route on to a step on `target`, over no section `steps` holds (when
    `closing`, the route must end on the start step itself); [] when already on it; None when there is none."""
    if not closing and steps[-1][0] == target:
        return []
    used = {s for s, _f in steps}
    for route in find_routes(graph, steps[-1], target, MAX_STEPS):
        rest = route[1:]
        if not rest:
            continue
        if closing:
            if rest[-1] == steps[0] and not used & {s for s, _f in rest[:-1]}:
                return list(rest)
        elif not used & {s for s, _f in rest}:
            return list(rest)
    return None


def default_plans(network, start, count):
    """Plans for `count` trains starting on `start`: train i takes the stations in the layout's order from the i-th on,
    keeping each that one round can still reach, so the trains of a passing loop use both platforms in turn."""
    names = [st.name for st in network.stations]
    plans = []
    for i in range(count):
        plan = []
        for k in range(len(names)):
            name = names[(i + k) % len(names)]
            try:
                itinerary(network, start, plan + [name])
            except ConfigError:
                continue
            plan.append(name)
        plans.append(tuple(plan))
    return plans
