"""A fault campaign: seeded `cbtc sim` runs over fault classes x layouts x fleet sizes, each judged by truth.

Run k of a plan takes fault class k mod C, then the next layout, then the next fleet size, with seed `seed + k`; the
fault's train, time and size are drawn from that seed within CAMPAIGN_RANGES (parameters given with the class, as in
`rollback:distance_m=0.3`, are kept as given). So run k is the same whatever the number of runs: a longer campaign
reuses a shorter one's results. Every run is a `cbtc sim` command (`RunSpec.command`), and `run_one` builds it as
`cbtc sim` does, so the command printed for a violation reproduces it alone. `none` is the fault-free reference;
`combined` injects two faults of different classes in one run, each at its own time; `overlapping` two or three,
each beginning within OVERLAP_S of the first; `packed_start` starts the trains one behind the other
(two or more in one fixed block), under moving or fixed block.
"""

import functools
import hashlib
import importlib
import logging
import math
import os
import random
import time
from dataclasses import asdict, dataclass

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.errors import ConfigError
from cbtc.sim import faults

NONE, COMBINED, OVERLAPPING, PACKED = "none", "combined", "overlapping", "packed_start"
CLASSES = (NONE,) + tuple(sorted(faults.FAULTS)) + (COMBINED, OVERLAPPING, PACKED)
OVERLAP_S = 2.0   # overlapping: each fault begins within this long after the first
PACKED_GAP_M = (0.05, 0.3)   # packed_start: the gap from a tail to the next head at the start
LAYOUTS = ("itb_square", "lego_oval", "lego_passing_loop", "lego_figure_eight", "lego_branch")
FLEET_SIZES = (2, 3, 4, 5, 6)
NETWORK_FLEET = 4   # at most this many trains on a track network (on its longest section, or a line's terminus tracks)



class LogSigned(tuple):
    """A parameter drawn with a random sign and a magnitude log-uniform in (low, high): small and large alike."""

    def draw(self, rng):
        low, high = self
        return rng.choice((-1.0, 1.0)) * math.exp(rng.uniform(math.log(low), math.log(high)))


# fault class -> {parameter: (low, high) drawn uniformly, a tuple of choices, or a LogSigned range}; "train" and
# "at_s" are drawn for every class that has them
CAMPAIGN_RANGES = {
    "stop_dead": {},
    "reboot": {},
    "link_loss": {"duration_s": (1.0, 8.0), "loss": (0.3, 1.0), "burst_s": (0.0, 0.0, 0.3, 1.0)},
    "link_delay": {"duration_s": (2.0, 8.0), "latency_s": (0.05, 0.5), "jitter_s": (0.0, 0.1)},
    "link_reorder": {"duration_s": (2.0, 8.0), "share": (0.1, 0.5), "delay_s": (0.02, 0.3)},
    "link_duplicate": {"duration_s": (2.0, 8.0), "share": (0.1, 0.5)},
    "broker_outage": {"duration_s": (0.5, 5.0)},
    "controller_restart": {"duration_s": (0.5, 5.0)},
    "encoder_burst": {"counts": (50, 600)},
    "odometer_jump": {"distance_m": LogSigned((0.05, 5.0))},
    "encoder_stuck": {"duration_s": (0.5, 5.0)},
    "encoder_scale": {"duration_s": (1.0, 8.0), "factor": (0.7, 1.5)},
    "ips_offset": {"duration_s": (1.0, 8.0), "offset_m": (0.2, 1.0)},
    "ips_outliers": {"duration_s": (2.0, 10.0), "share": (0.2, 0.8)},
    "ips_blackout": {"duration_s": (2.0, 15.0)},
    "rfid_absent": {"duration_s": (5.0, 20.0)},
    "rfid_misses": {"duration_s": (5.0, 20.0), "share": (0.3, 0.95)},
    "rfid_wrong_tag": {"duration_s": (5.0, 20.0), "share": (0.2, 0.9)},
    "rollback": {"distance_m": (0.05, 0.3), "v_mps": (0.02, 0.1)},
    "reverse_run": {"distance_m": (0.05, 0.5)},
    "length_wrong": {"length_m": (0.1, 0.8)},
    "car_dropped": {"length_m": (0.03, 0.25)},
    "ips_bias": {"duration_s": (5.0, 15.0), "offset_m": LogSigned((0.05, 0.5)), "share": (0.5, 1.0)},
    "encoder_drift": {"duration_s": (20.0, 40.0), "factor": (0.9, 1.12)},
    "boot_moved": {"distance_m": LogSigned((0.05, 1.0))},
    "tag_moved": {"distance_m": LogSigned((0.005, 0.2))},
    "switch_stall": {"duration_s": (2.0, 20.0)},
    "switch_detection_lost": {"duration_s": (2.0, 20.0)},
    "switch_wrong_leg": {"duration_s": (2.0, 20.0)},
    "unknown_board": {"distance_m": (0.3, 4.0)},
    "duplicate_board": {"distance_m": (0.3, 4.0)},
    "unseen_train": {"duration_s": (0.5, 5.0), "distance_m": (0.3, 4.0)},
}
# per-class figures: counted over the runs (sums), or their worst, or their mean
_SUMS = ("collisions", "authority_overruns", "rolled_onto", "emergency_trips", "encoder_trips", "stranded")


@dataclass(frozen=True)
class RunSpec:
    """One run of a campaign: a `cbtc sim` command."""

    fault_class: str
    layout: str
    trains: int
    seed: int
    duration_s: float
    faults: tuple   # fault texts, NAME:param=value,... with every parameter written out
    policy: str = MOVING_BLOCK
    blocks: int = None          # fixed block: that many equal blocks (None: the layout's own)
    start_gap_m: float = None   # the trains start one behind the other this far apart (None: spread evenly)
    scenario: str = None        # a scenario file or name: its layout, trains and faults (the drawn fault added)

    def command(self) -> str:
        """The `cbtc sim` command that makes this run alone."""
        where = [f"--scenario {self.scenario}"] if self.scenario else [f"--layout {self.layout}",
                                                                       f"--trains {self.trains}"]
        words = ["cbtc sim", *where, f"--seed {self.seed}", f"--duration {self.duration_s:g}"]
        if self.policy != MOVING_BLOCK:
            words.append(f"--policy {self.policy}")
        if self.blocks is not None:
            words.append(f"--blocks {self.blocks}")
        if self.start_gap_m is not None:
            words.append(f"--start-gap {self.start_gap_m:g}")
        return " ".join(words + [f"--fault {text}" for text in self.faults])

    def config(self):
        """The ScenarioConfig of this run, as `cbtc sim` builds it from the command; ConfigError for a bad value."""
        from cbtc.sim.runs import scenario_config, sim_config
        if self.scenario:
            return scenario_config(self.scenario, self.seed, self.duration_s, fault_texts=self.faults)
        return sim_config(self.layout, self.trains, self.seed, self.duration_s, self.policy, blocks=self.blocks,
                          fault_texts=self.faults, start_gap_m=self.start_gap_m)


def parse_classes(texts) -> list:
    """Fault classes as given to --faults: a class name, `none`, `combined`, or NAME:param=value,... with some
    parameters fixed; ConfigError naming an unknown one."""
    classes = []
    for text in texts:
        name = text.partition(":")[0]
        if name in (NONE, COMBINED, OVERLAPPING, PACKED):
            if ":" in text:
                raise ConfigError(f"fault class {text!r}: {name} takes no parameters")
        else:
            faults.parse(text)
        classes.append(text)
    if not classes:
        raise ConfigError("no fault classes: give names from " + ", ".join(CLASSES))
    return classes


@functools.lru_cache(maxsize=None)
def _track_kind(layout: str) -> tuple:
    """(is a track network, has switches) of `layout`, read once: a plan asks for every run."""
    from cbtc.layout_files import load_track
    track = load_track(layout)
    return bool(getattr(track, "is_network", False)), bool(getattr(getattr(track, "graph", None), "switches", None))


def is_network(layout: str) -> bool:
    return _track_kind(layout)[0]


def has_switches(layout: str) -> bool:
    return _track_kind(layout)[1]


def runs_on(cls: str, layout: str) -> bool:
    """Whether fault class `cls` runs on `layout`: the switch faults on track networks with switches only;
    packed_start and the faults that place a train, a car or a tag along one path on single paths only."""
    name, network = cls.partition(":")[0], is_network(layout)
    if name in faults.SWITCH_FAULTS:
        return has_switches(layout)
    return not network or (name not in faults.PATH_ONLY and name != PACKED)


def plan(runs: int, classes, layouts, fleet_sizes, duration_s: float, seed: int, scenario=None) -> list:
    """The RunSpecs of a campaign of `runs` runs (module docstring: which run is which); with `scenario` (its name or
    file, and its ScenarioConfig), every run is that scenario with its seed and a fault drawn for its trains."""
    specs = []
    if scenario is not None:
        name, config = scenario
        ids = [spec.train_id for spec in config.trains]
        for k in range(runs):
            cls = classes[k % len(classes)]
            drawn = draw_faults(cls, seed + k, len(ids), duration_s, ids)
            specs.append(RunSpec(cls, config.layout.name, len(ids), seed + k, duration_s, drawn, scenario=name))
        return specs
    own = {cls: [name for name in layouts if runs_on(cls, name)] for cls in classes}
    lacking = [cls for cls, names in own.items() if not names]
    if lacking:
        raise ConfigError(f"fault classes {', '.join(lacking)} run on none of the layouts {', '.join(layouts)} (switch "
                          f"faults need a track network with switches, such as lego_passing_loop; packed_start and the "
                          f"faults that place things along one path need a loop or a line): add one to --layouts")
    for k in range(runs):
        cls = classes[k % len(classes)]
        combo, names = k // len(classes), own[cls]
        layout = names[combo % len(names)]
        n = fleet_sizes[(combo // len(names)) % len(fleet_sizes)]
        if is_network(layout):
            n = min(n, NETWORK_FLEET)
        run_seed = seed + k
        if cls == PACKED:
            specs.append(packed_start(layout, n, run_seed, duration_s))
        else:
            specs.append(RunSpec(cls, layout, n, run_seed, duration_s,
                                 draw_faults(cls, run_seed, n, duration_s, network=is_network(layout),
                                             switches=has_switches(layout))))
    return specs


def packed_start(layout: str, n_trains: int, seed: int, duration_s: float) -> RunSpec:
    """A packed_start run: the trains start one behind the other, PACKED_GAP_M apart (drawn), so that under fixed
    block (every other run, drawn) two or more stand in one block; fixed block gets more equal blocks than trains
    where the layout's own are too few."""
    rng = random.Random(f"{PACKED}/{seed}")
    gap_m = round(rng.uniform(*PACKED_GAP_M), 3)
    if rng.random() < 0.5:
        return RunSpec(PACKED, layout, n_trains, seed, duration_s, (), start_gap_m=gap_m)
    from cbtc.layout_files import load_layout
    own = len(load_layout(layout).blocks)
    blocks = None if own >= n_trains + 2 else n_trains + 2
    return RunSpec(PACKED, layout, n_trains, seed, duration_s, (), FIXED_BLOCK, blocks, gap_m)


def draw_faults(cls: str, seed: int, n_trains: int, duration_s: float, train_ids=None, network=False,
                switches=None) -> tuple:
    """The fault texts of class `cls` (as given to --faults) for a run: drawn from `seed`, the same on every machine;
    a fault's train is one of `train_ids` (default T1..Tn); `combined` and `overlapping` draw among the faults that run
    on the layout (a track network: `network`; one with switches: `switches`, by default `network`)."""
    rng = random.Random(f"{cls}/{seed}")
    ids = list(train_ids or [f"T{i + 1}" for i in range(n_trains)])
    switches = network if switches is None else switches
    shut_out = (faults.PATH_ONLY if network else ()) + (() if switches else faults.SWITCH_FAULTS)
    pool = sorted(name for name in CAMPAIGN_RANGES if name not in shut_out)
    if cls == NONE:
        return ()
    if cls == COMBINED:
        first, second = rng.sample(pool, 2)
        return (_draw(first, rng, ids, duration_s), _draw(second, rng, ids, duration_s))
    if cls == OVERLAPPING:
        names = rng.sample(pool, rng.choice((2, 3)))
        start_s = _draw_at_s(rng, duration_s)
        return tuple(_draw(name, rng, ids, duration_s, round(start_s + rng.uniform(0.0, OVERLAP_S), 1))
                     for name in names)
    return (_draw(cls, rng, ids, duration_s),)


def _draw_at_s(rng, duration_s) -> float:
    low_s = min(10.0, 0.25 * duration_s)
    return round(rng.uniform(low_s, max(low_s, min(30.0, duration_s - 30.0))), 1)


def _draw(text, rng, ids, duration_s, at_s=None) -> str:
    name, _, given = text.partition(":")
    named = {item.partition("=")[0] for item in given.split(",") if item}
    fixed = {k: v for k, v in faults.parse(text).params.items() if k in named}
    defaults = faults.FAULTS[name][1]
    params = {}
    if "train" in defaults:
        params["train"] = ids[rng.randrange(len(ids))]
    if "at_s" in defaults:
        params["at_s"] = _draw_at_s(rng, duration_s) if at_s is None else at_s
    for key, span in CAMPAIGN_RANGES[name].items():
        kind = type(defaults[key])
        if isinstance(span, LogSigned):
            value = span.draw(rng)
        else:
            value = rng.choice(span) if len(span) > 2 else rng.uniform(*span)
        params[key] = int(round(value)) if kind is int else round(value, 3)
    params.update(fixed)
    return str(faults.Fault(name, dict(defaults, **params)))


def run_one(spec: RunSpec) -> dict:
    """Make one run and return its record: the spec, the summary figures, the violations, the wall time."""
    from cbtc.sim.recorder import violations
    from cbtc.sim.simulation import Simulation

    logger = logging.getLogger("cbtc")
    level = logger.level
    logger.setLevel(logging.ERROR)   # the figures count what the zone would log; the caller's level comes back after
    started = time.perf_counter()
    keep = ("collisions", "authority_overruns", "rolled_onto", "granted_beyond_m", "emergency_trips", "encoder_trips",
            "stranded", "mean_following_gap_m", "min_gap_m", "mean_lap_s", "simulated_s")
    try:
        summary = Simulation(spec.config()).run().summary()
        found, error = violations(summary), None
    except Exception as exc:   # one run that raises is a finding of the campaign, not its end
        summary = dict.fromkeys(keep, None)
        summary.update(dict.fromkeys(_SUMS, 0), simulated_s=0.0)
        found, error = ["raised"], f"{type(exc).__name__}: {exc}"
    finally:
        logger.setLevel(level)
    record = {"command": spec.command(), "spec": asdict(spec), "summary": {k: summary[k] for k in keep},
              "violations": found, "wall_s": round(time.perf_counter() - started, 3), "code": code_fingerprint()}
    if error is not None:
        record["error"] = error
    return record


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """A digest of the code that makes a run (cbtc, the firmware, the packaged layouts): a results file's run made by
    other code (a changed estimator or authority rule) is made again, not reused."""
    digest = hashlib.sha256()
    for package in ("cbtc", "cbtc.firmware", "cbtc.track_layouts"):
        root = os.path.dirname(importlib.import_module(package).__file__)
        for folder, dirs, files in os.walk(root):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__" and not (package == "cbtc" and folder == root
                                                                               and d in ("firmware", "track_layouts")))
            for name in sorted(f for f in files if f.endswith((".py", ".yaml"))):
                path = os.path.join(folder, name)
                digest.update(f"{package}/{os.path.relpath(path, root)}\n".encode())
                with open(path, "rb") as fh:
                    digest.update(fh.read())
    return digest.hexdigest()[:16]


def tables(specs, records: dict) -> dict:
    """The campaign's figures over `specs` from `records` ({command: record}): totals, `by_fault` (the same keys per
    fault class, in the order of the classes) and `violations` (each with its reproducing command)."""
    by_fault = {}
    for spec in specs:
        by_fault.setdefault(spec.fault_class, [])
        if spec.command() in records:
            by_fault[spec.fault_class].append(records[spec.command()])
    result = _figures([r for rows in by_fault.values() for r in rows])
    result["by_fault"] = {cls: _figures(rows) for cls, rows in by_fault.items()}
    result["violations"] = [{"command": r["command"], "kinds": r["violations"], "fault_class": r["spec"]["fault_class"],
                             "layout": r["spec"]["layout"], "trains": r["spec"]["trains"], "seed": r["spec"]["seed"],
                             "collisions": r["summary"]["collisions"],
                             "authority_overruns": r["summary"]["authority_overruns"],
                             "granted_beyond_m": r["summary"]["granted_beyond_m"],
                             **({"error": r["error"]} if "error" in r else {})}
                            for rows in by_fault.values() for r in rows if r["violations"]]
    return result


def _figures(rows) -> dict:
    out = {"runs": len(rows)}
    for key in _SUMS:
        out[key] = sum(r["summary"][key] for r in rows)
    out["runs_with_violations"] = sum(1 for r in rows if r["violations"])
    beyond = [r["summary"]["granted_beyond_m"] for r in rows if r["summary"]["granted_beyond_m"] is not None]
    out["worst_granted_beyond_m"] = max(beyond) if beyond else None
    gaps = [r["summary"]["mean_following_gap_m"] for r in rows if r["summary"]["mean_following_gap_m"] is not None]
    out["mean_following_gap_m"] = round(sum(gaps) / len(gaps), 3) if gaps else None
    worst = [r["summary"]["min_gap_m"] for r in rows if r["summary"]["min_gap_m"] is not None]
    out["worst_gap_m"] = min(worst) if worst else None
    laps = [r["summary"]["mean_lap_s"] for r in rows if r["summary"]["mean_lap_s"] is not None]
    out["mean_lap_s"] = round(sum(laps) / len(laps), 3) if laps else None
    out["simulated_s"] = round(math.fsum(r["summary"]["simulated_s"] for r in rows), 1)
    return out
