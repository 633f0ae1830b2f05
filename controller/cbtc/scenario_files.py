"""Scenario files: a run written in YAML (layout, trains with profile, start, stops and dwell, duration, seed,
faults), read and checked. Every error names the file, the line, the key and the fix. The format is in
docs/scenarios.md and in the shipped examples (`cbtc scenario list`)."""

import difflib
import math
import os
from dataclasses import fields, replace

import yaml

from cbtc.authority.policy import MOVING_BLOCK, policy_names
from cbtc.errors import CbtcError, ConfigError
from cbtc.layout_files import load_track, packaged_names, resolve_packaged
from cbtc.protocol import wire
from cbtc.railway.train_profile import TrainProfile
from cbtc.scenario_network import check_network_apart, network_train
from cbtc.sim import faults as fault_catalogue
from cbtc.yaml_lines import LineMap, LineSeq, YamlKeyError, load_with_lines
from cbtc.zone.config import ScenarioConfig, TrainSpec
from cbtc.zone.factory import make_policy, policy_class

TOP_KEYS = ("name", "description", "layout", "seed", "duration_s", "laps", "policy", "blocks", "estimator", "dwell_s",
            "trains", "faults", "reference", "clear_track")
# figures a `reference:` may give, as `cbtc compare` measures them (cbtc.experiments.headway.system_figures)
REFERENCE_FIGURES = ("mean_gap_m", "mean_gap_following_m", "min_gap_m", "mean_lap_s", "mean_headway_s",
                     "trains_per_hour")
TRAIN_KEYS = ("id", "start", "stops", "dwell_s", "profile")
PROFILE_KEYS = tuple(f.name for f in fields(TrainProfile))
POLICIES = policy_names()
ESTIMATORS = ("ukf", "odometry")
CLEAR_TRACK = ("truth", "none")   # ScenarioConfig.clear_track


def scenario_names():
    """Names of the scenarios shipped with the package (without `.yaml`)."""
    return packaged_names("cbtc.scenarios")


def resolve_scenario(path_or_name) -> str:
    """A readable file path for a scenario file path or a packaged scenario name."""
    return resolve_packaged(path_or_name, "cbtc.scenarios", "scenario", ConfigError)


def load_scenario(path_or_name) -> ScenarioConfig:
    """The ScenarioConfig of a scenario file or packaged name; ConfigError naming file, line, key and fix."""
    source = resolve_scenario(path_or_name)
    try:
        with open(source, encoding="utf-8") as fh:
            data = load_with_lines(fh)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"{source}:{mark.line + 1}" if mark is not None else source
        raise ConfigError(f"{where}: not valid YAML: {getattr(exc, 'problem', None) or exc}; fix the syntax "
                          f"there") from None
    except YamlKeyError as exc:
        raise ConfigError(f"{source}:{exc.line}: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{source}: cannot read it as a UTF-8 text file: {exc}") from None
    return replace(scenario_from_dict(data, source), source=str(path_or_name))


class _Reader:
    """Typed access to the YAML tree; every error names the file, the line and the key path."""

    def __init__(self, source):
        self.source = source

    def fail(self, container, key, path, message):
        line = None
        if isinstance(container, LineMap):
            line = container.lines.get(key, container.line)
        elif isinstance(container, LineSeq):
            line = container.lines[key] if isinstance(key, int) and key < len(container.lines) else container.line
        at = f"{self.source}:{line}" if line else self.source
        raise ConfigError(f"{at}: {path}: {message}")

    def mapping(self, parent, key, path, allowed):
        value = parent[key]
        if not isinstance(value, dict):
            self.fail(parent, key, path, f"must be a mapping of {', '.join(allowed)}, got {_kind(value)}")
        for k in value:
            if k not in allowed:
                near = difflib.get_close_matches(str(k), allowed, n=1)
                hint = f"did you mean {near[0]!r}?" if near else f"known keys: {', '.join(allowed)}"
                self.fail(value, k, f"{path}.{k}" if path else str(k), f"unknown key; {hint}")
        return value

    def number(self, parent, key, path, minimum=None, above=None, default=None, whole=False):
        if key not in parent:
            if default is not None:
                return default
            self.fail(parent, key, path, f"missing: add {'a whole number' if whole else 'a number'}")
        value = parent[key]
        ok = not isinstance(value, bool) and (isinstance(value, int) if whole else isinstance(value, (int, float)))
        if not ok or not math.isfinite(value):
            self.fail(parent, key, path, f"must be {'a whole number' if whole else 'a number'}, got {value!r}")
        if (minimum is not None and value < minimum) or (above is not None and value <= above):
            bound = f">= {minimum}" if minimum is not None else f"> {above}"
            self.fail(parent, key, path, f"must be {bound}, got {value}")
        return value

    def choice(self, parent, key, path, choices, default):
        value = parent.get(key, default)
        if value not in choices:
            self.fail(parent, key, path, f"must be one of {', '.join(choices)}, got {value!r}")
        return value

    def dwell(self, parent, key, path, default):
        if key not in parent:
            return default
        value = parent[key]
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            value = [value, value]
        if not (isinstance(value, list) and len(value) == 2
                and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0
                        for v in value) and value[0] <= value[1]):
            self.fail(parent, key, path, f"must be seconds (e.g. 2) or a range [low, high] with 0 <= low <= high "
                                         f"(e.g. [1, 3]), got {value!r}")
        return (float(value[0]), float(value[1]))


def _kind(value):
    for kind, word in ((dict, "a mapping"), (list, "a list"), (str, "text"), (type(None), "nothing")):
        if isinstance(value, kind):
            return word
    return type(value).__name__


def scenario_from_dict(data, source="<dict>") -> ScenarioConfig:
    """A checked ScenarioConfig from the dict of a scenario file."""
    r = _Reader(source)
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: a scenario is a mapping of {', '.join(TOP_KEYS)}; see docs/scenarios.md")
    data = r.mapping({"": data}, "", "", TOP_KEYS)
    if "layout" not in data:
        r.fail(data, "layout", "layout", "missing: name a packaged layout (e.g. itb_square) or a layout file")
    if not isinstance(data["layout"], str):
        r.fail(data, "layout", "layout", f"must be a layout name or file, got {data['layout']!r}")
    layout_text = data["layout"]
    beside = os.path.join(os.path.dirname(os.path.abspath(source)), layout_text)
    try:
        layout = load_track(beside if os.path.isfile(beside) else layout_text)
    except CbtcError as exc:
        r.fail(data, "layout", "layout", str(exc))
    network = getattr(layout, "is_network", False)
    seed = r.number(data, "seed", "seed", minimum=0, default=0, whole=True)
    duration_s = float(r.number(data, "duration_s", "duration_s", above=0.0, default=120.0))
    laps = None
    if "laps" in data:
        laps = r.number(data, "laps", "laps", minimum=1, whole=True)
        if network:
            r.fail(data, "laps", "laps", f"layout {layout.name} is a track network: its trains run plans, not laps; "
                                         f"give duration_s")
        if not layout.closed:
            r.fail(data, "laps", "laps", f"layout {layout.name} is an open line: it has no laps; remove laps")
    policy = r.choice(data, "policy", "policy", POLICIES, MOVING_BLOCK)
    if network and policy != MOVING_BLOCK:
        r.fail(data, "policy", "policy", f"layout {layout.name} is a track network: it runs under {MOVING_BLOCK} "
                                         f"for now")
    options = {}
    if "blocks" in data:
        if not policy_class(policy).uses_blocks:
            r.fail(data, "blocks", "blocks", f"is for policy: {_with_blocks()}; {policy_class(policy).title} has no "
                   f"blocks")
        options["blocks"] = r.number(data, "blocks", "blocks", minimum=2, whole=True)
    estimator = r.choice(data, "estimator", "estimator", ESTIMATORS, "ukf")
    dwell_s = r.dwell(data, "dwell_s", "dwell_s", (1.0, 3.0))
    clear_track = r.choice(data, "clear_track", "clear_track", CLEAR_TRACK, "truth")
    trains = _trains(r, data, layout)
    injected = _faults(r, data, [spec.train_id for spec in trains])
    config = ScenarioConfig(layout=layout, trains=trains, seed=seed, duration_s=duration_s, laps=laps, policy=policy,
                            estimator=estimator, dwell_s=dwell_s, policy_options=options, faults=injected,
                            clear_track=clear_track,
                            name=str(data.get("name") or os.path.basename(source)[:-5]),
                            reference=_reference(r, data) if "reference" in data else None)
    if policy_class(policy).uses_blocks:   # blocks the trains can move in (more than the trains on a loop)
        try:
            make_policy(config)
        except ConfigError as exc:
            r.fail(data, "blocks" if "blocks" in data else "policy", "policy", str(exc))
    return config


def _reference(r, data):
    """`reference:`: another system's figures on this case, and where they come from."""
    ref = r.mapping(data, "reference", "reference", ("source",) + REFERENCE_FIGURES)
    if not isinstance(ref.get("source"), str) or not ref["source"].strip():
        r.fail(data, "reference", "reference.source", "missing: say where the figures come from, e.g. source: "
               "Eclipse SUMO")
    out = {"source": ref["source"].strip()}
    for name in REFERENCE_FIGURES:
        if name in ref:
            out[name] = float(r.number(ref, name, f"reference.{name}", minimum=0.0))
    if len(out) == 1:
        r.fail(data, "reference", "reference", f"gives no figure; give one or more of {', '.join(REFERENCE_FIGURES)}")
    return out


def _trains(r, data, layout):
    if "trains" not in data:
        r.fail(data, "trains", "trains", "missing: list the trains, e.g. - {id: A, start: main}")
    items = data["trains"]
    if not isinstance(items, list) or not items:
        r.fail(data, "trains", "trains", "must be a list of at least one train, e.g. - {id: A, start: main}")
    specs, by_id = [], {}
    station_names = [st.name for st in layout.stations]
    for i, _item in enumerate(items):
        where = f"trains[{i}]"
        item = r.mapping(items, i, where, TRAIN_KEYS)
        train_id = item.get("id")
        if train_id is None:
            r.fail(items, i, where, "missing id: give the train an id, e.g. id: A")
        train_id = str(train_id)
        try:
            wire.check_train_id(train_id)
        except wire.WireError as exc:
            r.fail(item, "id", f"{where}.id", exc.reason)
        if train_id in by_id:
            r.fail(item, "id", f"{where}.id", f"train {train_id} is listed twice; give each train its own id")
        profile = _profile(r, item, where)
        dwell_s = r.dwell(item, "dwell_s", f"{where}.dwell_s", None)
        if getattr(layout, "is_network", False):
            specs.append(by_id.setdefault(train_id, network_train(r, item, where, layout, train_id, profile,
                                                                    dwell_s)))
            continue
        s0_m = _start(r, item, where, layout, by_id, profile)
        stops = item.get("stops", station_names)
        if not isinstance(stops, list) or not all(isinstance(s, str) for s in stops):
            r.fail(item, "stops", f"{where}.stops", f"must be a list of station names from {station_names}")
        for name in stops:
            if name not in station_names:
                near = difflib.get_close_matches(name, station_names, n=1)
                hint = f"did you mean {near[0]!r}?" if near else f"stations of {layout.name}: {station_names}"
                r.fail(item, "stops", f"{where}.stops", f"no station {name!r}; {hint}")
        spec = TrainSpec(train_id, s0_m, tuple(stops), profile, dwell_s)
        by_id[train_id] = spec
        specs.append(spec)
    if getattr(layout, "is_network", False):
        check_network_apart(r, data, layout, specs)
    else:
        _check_apart(r, data, layout, specs)
    return specs


def _profile(r, item, where):
    if "profile" not in item:
        return TrainProfile()
    values = r.mapping(item, "profile", f"{where}.profile", PROFILE_KEYS)
    for key in values:
        r.number(values, key, f"{where}.profile.{key}")
    try:
        return TrainProfile().with_changes(**{k: v for k, v in values.items()})
    except ConfigError as exc:
        r.fail(item, "profile", f"{where}.profile", str(exc).removeprefix("train profile: "))


def _start(r, item, where, layout, by_id, profile):
    """The head position (m) the train starts at: a station, a distance along the track, or behind a train."""
    path = f"{where}.start"
    if "start" not in item:
        r.fail(item, "start", path, "missing: a station name, metres along the track, or {behind: A, gap_m: 0.2}")
    start = item["start"]
    if isinstance(start, str):
        if start not in [st.name for st in layout.stations]:
            r.fail(item, "start", path, f"no station {start!r}; give one of {[st.name for st in layout.stations]}, "
                                        f"or metres along the track")
        s0_m = layout.station(start).s_m
    elif isinstance(start, dict):
        start = r.mapping(item, "start", path, ("behind", "gap_m"))
        ahead = str(start.get("behind"))
        if ahead not in by_id:
            r.fail(start, "behind", f"{path}.behind", f"must name a train listed before this one, one of "
                                                      f"{sorted(by_id) or 'none yet'}")
        gap_m = r.number(start, "gap_m", f"{path}.gap_m", minimum=0.0)
        if gap_m <= 0.0:
            r.fail(start, "gap_m", f"{path}.gap_m", f"{gap_m}: the train would touch {ahead}; give a gap above 0, "
                                                    f"e.g. gap_m: 0.15")
        s0_m = by_id[ahead].s0_m - by_id[ahead].profile.length_m - gap_m
        if layout.closed:
            s0_m = layout.wrap(s0_m)
    else:
        s0_m = r.number(item, "start", path, minimum=0.0)
        if layout.closed and s0_m >= layout.length_m:
            r.fail(item, "start", path, f"{s0_m} m is past the loop's end ({layout.length_m:.3f} m round): give a "
                                        f"position from 0 to {layout.length_m:.3f} m, e.g. "
                                        f"{s0_m % layout.length_m:.3f}")
    if profile.length_m >= layout.length_m:
        r.fail(item, "profile", f"{where}.profile.length_m", f"a train {profile.length_m} m long does not fit on "
                                                             f"{layout.name} ({layout.length_m:.3f} m): give a "
                                                             f"shorter train")
    if not layout.closed and not profile.length_m <= s0_m <= layout.length_m:
        r.fail(item, "start", path, f"the train's head at {s0_m:.3f} m puts it off the line (it is "
                                    f"{profile.length_m} m long, the line {layout.length_m:.3f} m): start it between "
                                    f"{profile.length_m} and {layout.length_m:.3f} m")
    return float(s0_m)


def _check_apart(r, data, layout, specs):
    """No two trains overlap or touch at the start."""
    order = sorted(specs, key=lambda s: s.s0_m)
    pairs = zip(order, order[1:] + (order[:1] if layout.closed and len(order) > 1 else []))
    for behind, ahead in pairs:
        gap_m = layout.ahead_m(behind.s0_m, ahead.s0_m - ahead.profile.length_m)
        if layout.closed and gap_m > layout.length_m - ahead.profile.length_m - behind.profile.length_m:
            gap_m = -1.0   # round the loop the long way: the head is past the tail
        if gap_m <= 0.0:
            r.fail(data, "trains", "trains", f"trains {behind.train_id} and {ahead.train_id} overlap or touch at the "
                                             f"start (heads at {behind.s0_m:.3f} and {ahead.s0_m:.3f} m): start them "
                                             f"further apart")


def _faults(r, data, train_ids):
    if "faults" not in data:
        return ()
    items = data["faults"]
    if not isinstance(items, list):
        r.fail(data, "faults", "faults", "must be a list, e.g. - {name: link_loss, train: A, at_s: 20}")
    out = []
    for i, item in enumerate(items):
        where = f"faults[{i}]"
        if not isinstance(item, dict) or "name" not in item:
            names = ", ".join(sorted(fault_catalogue.FAULTS))
            r.fail(items, i, where, f"must be a mapping with a name, one of {names}")
        params = {k: v for k, v in item.items() if k != "name"}
        if "train" in params and str(params["train"]) not in train_ids:
            r.fail(item, "train", f"{where}.train", f"no train {params['train']!r} in this scenario; one of "
                                                    f"{train_ids}")
        text = str(item["name"]) + (":" + ",".join(f"{k}={v}" for k, v in params.items()) if params else "")
        try:
            out.append(fault_catalogue.parse(text))
        except ConfigError as exc:
            r.fail(items, i, where, f"{exc}; see docs/faults.md")
    return tuple(out)


def _with_blocks() -> str:
    return " or ".join(name for name in POLICIES if policy_class(name).uses_blocks)
