"""Scenarios: virtual trains and a zone controller on the mock broker under a virtual clock, measured against truth.

`run_scenario(config)` is reproducible from `config.seed`: same seed, same figures. It records, per train, the truth
(every loop tick), every report as the controller received it, and the controller's authority limits; `metrics`
turns that into laps, lap times, gaps, collisions and authority overruns.
"""

import hashlib
import math
from dataclasses import dataclass, field

import numpy as np

from cbtc.authority.moving_block import MovingBlockPolicy
from cbtc.authority.rules import AuthorityParams, following_reach_m
from cbtc.bus.mock_broker import LinkProfile, MockBroker
from cbtc.errors import ConfigError
from cbtc.firmware_modules import wire
from cbtc.railway.train_profile import TrainProfile
from cbtc.scheduler import VirtualScheduler
from cbtc.sim.virtual_train import VirtualTrain
from cbtc.zone.controller import TrainSetup, ZoneController


@dataclass
class TrainSpec:
    train_id: str
    s0_m: float
    stops: tuple = ()
    profile: TrainProfile = field(default_factory=TrainProfile)


@dataclass
class ScenarioConfig:
    layout: object
    trains: list
    seed: int = 0
    duration_s: float = 120.0
    laps: int = None                 # stop early once every train has completed this many laps
    cycle_s: float = 0.1             # zone controller period
    loop_s: float = 0.02             # onboard loop period
    policy: str = "moving_block"     # or "fixed_block" (cbtc.authority.fixed_block)
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


def train_key(seed: int, train_id: str) -> bytes:
    """The per-train authentication key of a simulated fleet (derived, so a seed reproduces a run)."""
    return hashlib.sha256(f"lego-cbtc sim key {seed} {train_id}".encode()).digest()[:16]


def make_policy(config: ScenarioConfig):
    if config.policy == "moving_block":
        return MovingBlockPolicy(config.params)
    if config.policy == "fixed_block":
        from cbtc.authority.fixed_block import FixedBlockPolicy
        try:
            policy = FixedBlockPolicy(config.params, **{"seed": config.seed, **config.policy_options})
            blocks = policy.blocks(config.layout)
        except ValueError as exc:
            raise ConfigError(f"fixed block: {exc}") from None
        if config.layout.closed and len(blocks) <= len(config.trains):
            raise ConfigError(f"fixed block: {len(config.trains)} trains on the {len(blocks)} blocks of loop "
                              f"{config.layout.name} cannot move (each needs a clear block ahead): give more blocks "
                              f"than trains, each well longer than a train and its margin, since a train across a "
                              f"block boundary holds two (cbtc sim --blocks)")
        return policy
    raise ConfigError(f"unknown policy {config.policy!r}: use moving_block or fixed_block")


def make_estimator_factory(name: str):
    if name == "ukf":
        from cbtc.estimation.ukf_estimator import UkfEstimator
        return UkfEstimator
    if name == "odometry":
        from cbtc.estimation.odometry_estimator import OdometryEstimator
        return OdometryEstimator
    raise ConfigError(f"unknown estimator {name!r}: use ukf or odometry")


class Simulation:
    """Everything of one run, wired and ready to `run()`; the parts are public for tests and fault injection."""

    def __init__(self, config: ScenarioConfig):
        self.config = config
        layout = config.layout
        ids = [t.train_id for t in config.trains]
        if len(set(ids)) != len(ids):
            raise ConfigError(f"scenario: duplicate train ids in {ids}")
        if not config.trains:
            raise ConfigError("scenario: at least one train is needed")
        self.scheduler = VirtualScheduler()
        self.broker = MockBroker(self.scheduler, seed=config.seed)
        setups = [TrainSetup(t.train_id, train_key(config.seed, t.train_id), t.profile, tuple(t.stops), config.dwell_s)
                  for t in config.trains]
        self.zc_client = self.broker.connect("zone-controller", will=(wire.topic_zone_status("zc1"), b"offline", True),
                                             up=config.controller_up, down=config.controller_down)
        self.policy = make_policy(config)
        self.zc = ZoneController(layout, setups, self.zc_client, self.scheduler.now_s, self.policy, config.params,
                                 make_estimator_factory(config.estimator), config.cycle_s, seed=config.seed,
                                 report_budget_hz=config.report_budget_hz)
        self.trains = []
        for index, spec in enumerate(config.trains):
            rng = np.random.default_rng([config.seed, index])
            client = self.broker.connect(f"train-{spec.train_id}",
                                         will=(wire.topic_status(spec.train_id), b"offline", True),
                                         up=config.link, down=config.link)
            offset_ms = int(rng.integers(0, 10_000_000))
            self.trains.append(VirtualTrain(spec.train_id, train_key(config.seed, spec.train_id), layout, spec.profile,
                                            spec.s0_m, client, rng, offset_ms, obu_overrides=config.obu_overrides,
                                            ranging=self._ranging(index)))
        if config.policy == "fixed_block":
            self._check_not_gridlocked()
        self.recorder = Recorder(self)
        self.zc.start()
        for train in self.trains:
            train.client.publish(wire.topic_status(train.train_id), b"online", retain=True)
        for index, train in enumerate(self.trains):
            # stagger the boards' loops a little, as real boards are
            self.scheduler.call_every(config.loop_s, self._ticker(train), start_s=0.001 * (index + 1))
        self.scheduler.call_every(config.cycle_s, self.zc.cycle, start_s=0.05)
        self.scheduler.call_every(config.loop_s, self.recorder.sample, start_s=0.0105)

    def _check_not_gridlocked(self):
        """Fixed blocks on a loop: if every train starts within the margin of an occupied block ahead, none can ever
        move (each holds a block another needs)."""
        layout = self.config.layout
        if not layout.closed or len(self.trains) < 2:
            return
        blocks = self.policy.blocks(layout)
        spans = [(t.train_id, t.head_s, t.tail_s) for t in self.trains]
        margin_m = self.config.params.margin_m
        if all(self.policy.clear_run(layout, blocks, spans, t.train_id, t.head_s)[1] <= margin_m
               for t in self.trains):
            raise ConfigError(f"fixed block: the {len(self.trains)} trains start on the {len(blocks)} blocks of "
                              f"{layout.name} each at an occupied block, so none can move: give another block count "
                              f"(cbtc sim --blocks)")

    def _ranging(self, index):
        """The train-to-train ranging driver of train `index` (None unless the config asks for ranging)."""
        if self.config.ranging is None:
            return None
        from cbtc.ranging.transponder import RangingSensor
        from cbtc.sim.ranging import SimRanging
        sensor = RangingSensor(seed=self.config.seed, **self.config.ranging)
        rng = np.random.default_rng([self.config.seed, index, 7])
        return SimRanging(self.config.layout, self.trains, index, sensor, rng)

    @staticmethod
    def _ticker(train):
        return train.tick

    def run(self):
        config = self.config
        step_s = 1.0
        t_s = 0.0
        while t_s < config.duration_s:
            t_s = min(config.duration_s, t_s + step_s)
            self.scheduler.run_until(t_s)
            if config.laps is not None and all(self.recorder.laps(i) >= config.laps for i in range(len(self.trains))):
                break
        return self.recorder


class Recorder:
    """Truth, reports and authority limits of a run, and the figures computed from them."""

    def __init__(self, sim: Simulation):
        self.sim = sim
        self.layout = sim.config.layout
        n = len(sim.trains)
        self.t_s = []
        self.travelled_m = [[] for _ in range(n)]
        self.head_s_m = [[] for _ in range(n)]
        self.v_mps = [[] for _ in range(n)]
        self.gap_m = [[] for _ in range(n)]       # true gap to the train ahead (head to its tail)
        self.est_s_m = [[] for _ in range(n)]
        self.est_sigma_m = [[] for _ in range(n)]
        self.constrained = [[] for _ in range(n)]  # the train ahead limits this train's speed now
        self.collisions = [0] * n
        self.overruns = [0] * n
        self._colliding = [False] * n
        self._overrun = [False] * n
        self.reports = [[] for _ in range(n)]     # (recv_s, report dict)
        self._index = {t.train_id: i for i, t in enumerate(sim.trains)}
        self._sniffer = sim.broker.connect("recorder")
        self._sniffer.subscribe(wire.REPORT_FILTER, self._on_report)

    def _on_report(self, topic, payload):
        try:
            train_id = wire.train_id_of(topic)
            i = self._index[train_id]
            report = wire.decode_report(train_key(self.sim.config.seed, train_id), topic, payload)
        except (wire.WireError, KeyError):
            return
        self.reports[i].append((self.sim.scheduler.now_s(), report))

    def sample(self, now_s):
        layout = self.layout
        trains = self.sim.trains
        self.t_s.append(now_s)
        heads = [t.head_s for t in trains]
        spans = [(t.train_id, t.head_s, t.tail_s) for t in trains]
        order = sorted(range(len(trains)), key=lambda i: heads[i])
        for rank, i in enumerate(order):
            train = trains[i]
            self.travelled_m[i].append(train.travelled_m)
            self.head_s_m[i].append(heads[i])
            self.v_mps[i].append(train.v_mps)
            if len(trains) > 1:
                j = order[(rank + 1) % len(order)]
                gap = layout.ahead_m(heads[i], trains[j].tail_s)
                inside = layout.ahead_m(trains[j].tail_s, heads[i]) <= trains[j].profile.length_m
                if inside and not self._colliding[i]:
                    self.collisions[i] += 1
                self._colliding[i] = inside
                self.gap_m[i].append(-layout.ahead_m(trains[j].tail_s, heads[i]) if inside else gap)
            state = self.sim.zc.trains[train.train_id]
            self.constrained[i].append(state.safe_m is not None and state.safe_m < following_reach_m(train.profile))
            over = self.sim.policy.protected_m(layout, train.train_id, spans) < -0.001
            if over and not self._overrun[i]:
                self.overruns[i] += 1
            self._overrun[i] = over
            est = None
            if state.report is not None and state.estimator.localized:
                est = state.estimator.estimate(now_s)
            self.est_s_m[i].append(math.nan if est is None else est.s_m)
            self.est_sigma_m[i].append(math.nan if est is None else est.sigma_s_m)

    # --- figures --------------------------------------------------------------------------------------------------

    def lap_times(self, i):
        """Times (s) of each completed lap of train i, counted at its start position."""
        if not self.layout.closed:
            return []
        length = self.layout.length_m
        times, crossings = [], []
        next_mark = length
        for t_s, d in zip(self.t_s, self.travelled_m[i]):
            if d >= next_mark:
                crossings.append(t_s)
                next_mark += length
        last = 0.0
        for t in crossings:
            times.append(t - last)
            last = t
        return times

    def laps(self, i):
        if not self.layout.closed or not self.travelled_m[i]:
            return 0
        return int(self.travelled_m[i][-1] // self.layout.length_m)

    def estimation_error(self, i):
        """RMSE and max of the controller's estimate against truth along the track (m), while located."""
        errs = []
        for s_est, s_true in zip(self.est_s_m[i], self.head_s_m[i]):
            if s_est == s_est:
                e = self.layout.ahead_m(s_true, s_est)
                if self.layout.closed and e > self.layout.length_m / 2:
                    e -= self.layout.length_m
                errs.append(e)
        if not errs:
            return None
        arr = np.asarray(errs)
        return {"rmse_m": float(np.sqrt(np.mean(arr ** 2))), "max_abs_m": float(np.max(np.abs(arr)))}

    def summary(self):
        trains = []
        for i, train in enumerate(self.sim.trains):
            laps = self.lap_times(i)
            gaps = np.asarray(self.gap_m[i]) if self.gap_m[i] else None
            state = self.sim.zc.trains[train.train_id]
            err = self.estimation_error(i)
            trains.append({
                "train": train.train_id,
                "laps": len(laps),
                "mean_lap_s": round(float(np.mean(laps)), 3) if laps else None,
                "distance_m": round(self.travelled_m[i][-1], 3) if self.travelled_m[i] else 0.0,
                "mean_gap_m": None if gaps is None else round(float(np.mean(gaps)), 3),
                "min_gap_m": None if gaps is None else round(float(np.min(gaps)), 3),
                "collisions": self.collisions[i],
                "authority_overruns": self.overruns[i],
                "station_stops": state.dwells,
                "estimation_rmse_m": None if err is None else round(err["rmse_m"], 4),
                "estimation_max_error_m": None if err is None else round(err["max_abs_m"], 4),
                "commands_rejected_onboard": train.obu.rejected,
                "emergency_trips": train.obu.trips,
                "reports_rejected": state.reports_rejected,
            })
        return {
            "layout": self.layout.name,
            "policy": self.sim.policy.name,
            "estimator": self.sim.config.estimator,
            "seed": self.sim.config.seed,
            "simulated_s": round(self.t_s[-1], 3) if self.t_s else 0.0,
            "trains": trains,
            "collisions": sum(self.collisions),
            "authority_overruns": sum(self.overruns),
            "emergency_trips": sum(t.obu.trips for t in self.sim.trains),
            "all_standing_at_end_s": round(all_standing_s(self.t_s, self.v_mps), 3),
        }


def all_standing_s(t_s, v_mps_by_train):
    """How long (s) every train had been standing still at the last sample (sample times `t_s`, speeds per train):
    long means gridlock."""
    for k in range(len(t_s) - 1, -1, -1):
        if any(v[k] > 0.0 for v in v_mps_by_train):
            return t_s[-1] - t_s[k]
    return t_s[-1] - t_s[0] if t_s else 0.0


def paper_scenario(layout, seed=0, laps=5, duration_s=200.0, **overrides) -> ScenarioConfig:
    """The source paper's experiment: train A ahead of train B on the square loop, both standing at main at the start;
    A stops 1-3 s at stations A and main, B at stations B and main."""
    names = {st.name for st in layout.stations}
    for needed in ("main", "A", "B"):
        if needed not in names:
            raise ConfigError(f"the paper scenario needs stations main, A and B; layout {layout.name} has {sorted(names)}")
    profile = TrainProfile()
    params = overrides.get("params", AuthorityParams())
    main_s = layout.station("main").s_m
    s0_a = main_s
    s0_b = layout.wrap(main_s - profile.length_m - params.margin_m - 0.05)
    trains = [TrainSpec("A", s0_a, ("A", "main"), profile), TrainSpec("B", s0_b, ("B", "main"), profile)]
    return ScenarioConfig(layout=layout, trains=trains, seed=seed, laps=laps, duration_s=duration_s, **overrides)


def queue_scenario(layout, n_trains, seed=0, duration_s=300.0, **overrides) -> ScenarioConfig:
    """N trains spread evenly along a loop, each stopping at every station, each following the one ahead."""
    profile = TrainProfile()
    params = overrides.get("params", AuthorityParams())
    spacing_m = layout.length_m / n_trains
    need_m = profile.length_m + params.margin_m + 0.05
    if n_trains < 1 or spacing_m < need_m:
        raise ConfigError(f"{n_trains} trains do not fit on {layout.name} ({layout.length_m:.2f} m): at most "
                          f"{int(layout.length_m // need_m)} with {need_m:.2f} m per train")
    stops = tuple(st.name for st in layout.stations)
    trains = [TrainSpec(f"T{k + 1}", layout.wrap(k * spacing_m), stops, profile) for k in range(n_trains)]
    return ScenarioConfig(layout=layout, trains=trains, seed=seed, duration_s=duration_s, **overrides)
