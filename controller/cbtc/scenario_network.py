"""The trains of a scenario file on a track network: each starts on a section (its head's offset there, the way it
runs it) and its stops are its plan, whose itinerary it runs (cbtc.railway.itinerary), or, on a line, whose legs it runs
reversing at the buffer stops (cbtc.railway.legs). Errors name the file, the
line, the key and the fix, as the rest of the scenario's do (cbtc.scenario_files)."""

from cbtc.errors import CbtcError
from cbtc.railway.itinerary import default_plans, itinerary
from cbtc.railway.legs import legs
from cbtc.railway.network_layout import route_layout
from cbtc.sim.network_truth import collisions
from cbtc.zone.config import TrainSpec

START_KEYS = ("section", "offset_m", "forward")


def network_train(r, item, where, layout, train_id, profile, dwell_s):
    """The TrainSpec of `item` on the network `layout`: its start, its plan and the itinerary they make."""
    path = f"{where}.start"
    if not isinstance(item.get("start"), dict):
        r.fail(item, "start", path, f"on the track network {layout.name}: a mapping of {', '.join(START_KEYS)}, e.g. "
                                    "{section: main, offset_m: 1.2, forward: true} (the head's offset from the "
                                    "section's start, the way the train runs it)")
    start = r.mapping(item, "start", path, START_KEYS)
    section = start.get("section")
    if section not in layout.graph.sections:
        r.fail(start, "section", f"{path}.section", f"no section {section!r}; sections of {layout.name}: "
                                                     f"{', '.join(layout.graph.sections)}")
    length_m = layout.graph.sections[section].length_m
    offset_m = float(r.number(start, "offset_m", f"{path}.offset_m", minimum=0.0))
    if offset_m > length_m:
        r.fail(start, "offset_m", f"{path}.offset_m", f"{offset_m} m is past the end of section {section} "
                                                       f"({length_m:.3f} m long)")
    forward = start.get("forward", True)
    if not isinstance(forward, bool):
        r.fail(start, "forward", f"{path}.forward", "must be true (the train runs the section from its start to its "
                                                    "end) or false")
    step = (section, forward)
    stops = item.get("stops")
    if stops is None:
        stops = list(default_plans(layout, step, 1)[0])
    elif not isinstance(stops, list) or not all(isinstance(s, str) for s in stops):
        r.fail(item, "stops", f"{where}.stops", f"must be a list of station names from "
                                                f"{[st.name for st in layout.stations]}: the plan, in order")
    found = None
    try:
        steps = itinerary(layout, step, stops)
    except CbtcError as exc:
        found = _reversing(r, item, where, layout, step, stops, profile, train_id, exc)
    route = found[0].route if found else layout.graph.route(steps)
    s0_m = route.s_of(section, offset_m)
    if not route.closed and s0_m < profile.length_m:
        r.fail(item, "start", path, f"the train's tail ({profile.length_m} m behind its head) would stand behind the "
                                    f"start of its itinerary: start it at least that far into section {section}")
    frame = found[0].frame if found else route_layout(layout, steps, name=f"{layout.name} ({train_id}'s itinerary)")
    return TrainSpec(train_id, s0_m, tuple(stops), profile, dwell_s, frame=frame, route=route, legs=found)


def _reversing(r, item, where, layout, step, stops, profile, train_id, exc):
    """The legs of a plan that needs the train to reverse (cbtc.railway.legs), or the failure naming `stops`: the
    plan's own error when it cannot be run reversing either."""
    try:
        found = legs(layout, step, stops, profile.length_m, train_id)
    except CbtcError as reversing:
        r.fail(item, "stops", f"{where}.stops", f"{exc}; reversing at the buffer stops: {reversing}")
    if not found:
        r.fail(item, "stops", f"{where}.stops", str(exc))
    if profile.tail_beacon:
        r.fail(item, "profile", f"{where}.profile", "a train that reverses runs either end first: give it "
                                                    "tail_beacon: 0 (a tail beacon would lead on every other leg)")
    return found


def check_network_apart(r, data, layout, specs):
    """No two trains stand on one section's stretch, or on one switch or crossing, at the start."""
    spans = {spec.train_id: spec.route.span(spec.s0_m - spec.profile.length_m, spec.s0_m) for spec in specs}
    for a, b, section_a, section_b in collisions(layout.graph, spans):
        r.fail(data, "trains", "trains", f"trains {a} and {b} overlap at the start (on {section_a} and "
                                         f"{section_b}): start them further apart")
