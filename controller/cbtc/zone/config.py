"""What a zone runs: the trains (ids, start positions, stops, profiles) and the settings of a run, and the presets
that simulated and live runs share (the ITB paper's two trains, a queue of N trains, the fleet of a live run)."""

import hashlib
import math
from dataclasses import dataclass, field

from cbtc.authority.policy import MOVING_BLOCK
from cbtc.authority.rules import AuthorityParams
from cbtc.bus.mock_broker import LinkProfile
from cbtc.errors import ConfigError
from cbtc.railway.train_profile import TrainProfile


@dataclass
class TrainSpec:
    train_id: str
    s0_m: float
    stops: tuple = ()
    profile: TrainProfile = field(default_factory=TrainProfile)
    dwell_s: tuple = None            # (low, high) s at each stop; None: the scenario's
    frame: object = None             # on a track network: the path Layout of its itinerary (s0_m is on it)
    route: object = None             # ... and the itinerary's Route
    legs: tuple = None               # ... or, on a line it reverses on, the legs it runs (cbtc.railway.legs), the first
    #                                  the frame and route above


@dataclass
class ScenarioConfig:
    layout: object
    trains: list
    seed: int = 0
    duration_s: float = 120.0
    laps: int = None                 # stop early once every train has completed this many laps
    cycle_s: float = 0.1             # zone controller period
    loop_s: float = 0.02             # onboard loop period
    policy: str = MOVING_BLOCK       # the name of an AuthorityPolicy (cbtc.zone.factory.POLICIES)
    estimator: str = "ukf"           # or "odometry"
    params: AuthorityParams = field(default_factory=AuthorityParams)
    link: LinkProfile = field(default_factory=lambda: LinkProfile(latency_s=0.004, jitter_s=0.003, loss=0.01))
    # the zone controller runs beside the broker (loopback), not on the Wi-Fi: its legs as `cbtc bench latency`
    # measures them (docs/mqtt.md: uplink and downlink 0.3-0.6 ms at p50). Its handling of a report (UKF update,
    # answer: 0.6-1.0 ms at p50, under 2 ms at p99) is counted on the way in, so every command it sends waits for it
    controller_up: LinkProfile = field(default_factory=lambda: LinkProfile(latency_s=0.0003, jitter_s=0.0005))
    controller_down: LinkProfile = field(default_factory=lambda: LinkProfile(latency_s=0.001, jitter_s=0.001))
    dwell_s: tuple = (1.0, 3.0)
    policy_options: dict = field(default_factory=dict)
    ranging: dict = None             # RangingSensor settings: every train ranges to the one ahead, guard armed
    obu_overrides: dict = None       # OnboardUnit settings for every train (firmware/obu.py DEFAULTS), e.g. report_ms
    report_budget_hz: float = 400.0  # reports a second the zone controller is sized for (fast reports within it)
    faults: tuple = ()               # cbtc.sim.faults.Fault values injected into the simulated world
    name: str = None                 # the scenario file's name, for titles
    source: str = None               # the scenario file or packaged name it was read from
    reference: dict = None           # figures another system gives on this case ({"source": text, figure: value})
    declare_start: bool = True       # the zone is told where each train starts (from the simulation's truth), as an
    #                                  operator declares at the start of a run: a placement that agrees with it is
    #                                  confirmed; a zone restarted later has no declaration and waits for balises
    clear_track: str = "truth"       # "truth": the simulation clears every stretch no vehicle stands on, at the start
    #                                  and after each zone restart, as an operator who has looked at the table would;
    #                                  "none": nothing is cleared, and no authority reaches into unswept track


def train_key(seed: int, train_id: str) -> bytes:
    """The per-train authentication key of a simulated fleet (derived, so a seed reproduces a run)."""
    return hashlib.sha256(f"lego-cbtc sim key {seed} {train_id}".encode()).digest()[:16]


def paper_scenario(layout, seed=0, laps=5, duration_s=200.0, **overrides) -> ScenarioConfig:
    """The source paper's experiment: train A ahead of train B on the square loop, both standing at main at the start;
    A stops 1-3 s at stations A and main, B at stations B and main."""
    names = {st.name for st in layout.stations}
    for needed in ("main", "A", "B"):
        if needed not in names:
            raise ConfigError(f"the paper scenario needs stations main, A and B; layout {layout.name} has "
                              f"{sorted(names)}")
    profile = TrainProfile()
    params = overrides.get("params", AuthorityParams())
    main_s = layout.station("main").s_m
    s0_a = main_s
    s0_b = layout.wrap(main_s - profile.length_m - params.margin_m - 0.05)
    trains = [TrainSpec("A", s0_a, ("A", "main"), profile), TrainSpec("B", s0_b, ("B", "main"), profile)]
    return ScenarioConfig(layout=layout, trains=trains, seed=seed, laps=laps, duration_s=duration_s, **overrides)


def queue_scenario(layout, n_trains, seed=0, duration_s=300.0, start_gap_m=None, **overrides) -> ScenarioConfig:
    """N trains spread evenly along a loop (or a line, each wholly on it), each stopping at every station, each
    following the one ahead; with `start_gap_m`, they start one behind the other, that far from a tail to the next
    head (on a line, at its start)."""
    profile = TrainProfile(tail_beacon=1)   # simulated trains carry a tail beacon
    params = overrides.get("params", AuthorityParams())
    spacing_m = layout.length_m / n_trains
    need_m = profile.length_m + params.margin_m + 0.05
    if start_gap_m is not None:
        if not (math.isfinite(start_gap_m) and start_gap_m > 0.0):
            raise ConfigError(f"--start-gap {start_gap_m}: trains would touch; give a distance in metres above 0, "
                              f"such as 0.1")
        spacing_m = profile.length_m + start_gap_m
        need_m = spacing_m
        if n_trains >= 1 and n_trains * spacing_m > layout.length_m - need_m:
            raise ConfigError(f"{n_trains} trains {start_gap_m} m apart do not fit on {layout.name} "
                              f"({layout.length_m:.2f} m): give fewer trains or a smaller --start-gap")
    elif n_trains < 1 or spacing_m < need_m:
        raise ConfigError(f"{n_trains} trains do not fit on {layout.name} ({layout.length_m:.2f} m): at most "
                          f"{int(layout.length_m // need_m)} with {need_m:.2f} m per train")
    stops = tuple(st.name for st in layout.stations)
    if layout.closed:
        heads_m = [layout.wrap(-k * spacing_m if start_gap_m is not None else k * spacing_m) for k in range(n_trains)]
    elif start_gap_m is not None:   # a line: the queue stands at its start, T1 in front, every train on the track
        heads_m = [profile.length_m + (n_trains - 1 - k) * spacing_m for k in range(n_trains)]
    else:                           # a line: spread along it, every train on the track, the front one with room to go
        spacing_m = (layout.length_m - profile.length_m) / n_trains
        heads_m = [profile.length_m + k * spacing_m for k in range(n_trains)]
    trains = [TrainSpec(f"T{k + 1}", heads_m[k], stops, profile) for k in range(n_trains)]
    return ScenarioConfig(layout=layout, trains=trains, seed=seed, duration_s=duration_s, **overrides)


def fleet_config(layout, train_ids=None, count: int = None, scenario: str = "auto", seed: int = 0, **overrides):
    """The ScenarioConfig both sides of a live run share: start positions and station stops per train.

    `paper`: paper_scenario (two trains, stations main/A/B); `queue`: queue_scenario (N trains
    spread along the loop, stopping everywhere); `auto`: paper for two trains on a layout that has its stations.
    Given `train_ids`, the scenario's trains take those ids in order."""
    n = len(train_ids) if train_ids else count
    if not n or n < 1:
        raise ConfigError("give the trains: --trains N (N >= 1) or --train-ids A,B")
    if scenario == "auto":
        names = {st.name for st in layout.stations}
        scenario = "paper" if n == 2 and {"main", "A", "B"} <= names else "queue"
    if scenario == "paper":
        if n != 2:
            raise ConfigError(f"the paper scenario has 2 trains, not {n}: use --scenario queue")
        config = paper_scenario(layout, seed=seed, **overrides)
    elif scenario == "queue":
        config = queue_scenario(layout, n, seed=seed, **overrides)
    else:
        raise ConfigError(f"unknown scenario {scenario!r}: use auto, paper or queue")
    if train_ids:
        for spec, train_id in zip(config.trains, train_ids):
            spec.train_id = train_id
    return config
