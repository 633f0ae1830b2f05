"""Headway experiments: moving block against the fixed-block baseline on the paper's scenario, and steady following.

Pure runners over `cbtc.sim.simulation`: each takes a seed and returns plain dicts of figures, so the `compare` command,
the tests and anyone's notebook get the same numbers.
"""

import math
from dataclasses import replace

import numpy as np

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.authority.rules import AuthorityParams, minimum_gap_m
from cbtc.errors import ConfigError
from cbtc.firmware import obu
from cbtc.railway.physics import braking_distance_m
from cbtc.railway.train_profile import TrainProfile
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import ScenarioConfig, TrainSpec, paper_scenario

PAPER = {"fixed_gap_m": 1.89, "cbtc_gap_m": 0.91, "fixed_lap_s": 15.72, "cbtc_lap_s": 6.84,
         "gap_reduction_pct": 52.0, "lap_reduction_pct": 56.0}


def followers(recorder):
    """Indices of the trains that followed: those the train ahead limited at some time in the run (train B of the
    paper scenario); every train if none did."""
    n = len(recorder.sim.trains)
    return [i for i in range(n) if recorder.ever_constrained[i]] or list(range(n))


HEADWAY_STEP_M = 0.05


def mean_headway_s(recorder, i):
    """Train i's mean time headway (s) behind the train ahead of it on a loop: at points every 5 cm of the way it
    ran, the time between the head of the train ahead passing the point and its own head passing it (what a detector
    at each point would count), averaged over the points; None on an open line or before it reached any point."""
    layout = recorder.layout
    trains = recorder.sim.trains
    if not layout.closed or len(trains) < 2:
        return None
    # the train ahead at the start: the nearest head in front (trains never overtake)
    ahead = min((j for j in range(len(trains)) if j != i),
                key=lambda j: layout.ahead_m(trains[i].s0_m, trains[j].s0_m) or layout.length_m)
    t = np.asarray(recorder.t_s)
    # distance along the way from train i's start: monotone (a roll back is passed again, not counted twice)
    own = np.maximum.accumulate(np.asarray(recorder.travelled_m[i]))
    lead = np.maximum.accumulate(np.asarray(recorder.travelled_m[ahead])) + layout.ahead_m(
        trains[i].s0_m, trains[ahead].s0_m)
    start_m, end_m = lead[0], min(own[-1], lead[-1])
    if end_m <= start_m:
        return None
    points = np.arange(start_m + HEADWAY_STEP_M, end_m, HEADWAY_STEP_M)
    if not len(points):
        return None
    return float(np.mean(_first_pass(points, own, t) - _first_pass(points, lead, t)))


def _first_pass(points, distance_m, t_s):
    """The first sample time at which a monotone `distance_m` reached each of `points`."""
    k = np.searchsorted(distance_m, points, side="left")
    return t_s[np.minimum(k, len(t_s) - 1)]


def system_figures(recorder):
    """Gap, lap time, throughput and safety figures of one run: the gaps are those of the trains that followed
    (`followers`: train B of the paper scenario)."""
    summary = recorder.summary()
    t = np.asarray(recorder.t_s)
    behind = followers(recorder)
    gap = np.concatenate([np.asarray(recorder.gap_m[i], dtype=float) for i in behind])
    following = np.concatenate([np.asarray(recorder.constrained[i], dtype=bool) for i in behind])
    top_mps = max(float(np.max(v)) for v in recorder.v_mps) if len(t) else 0.0
    laps = [lap for i in range(len(recorder.sim.trains)) for lap in recorder.lap_times(i)]
    total_laps = sum(len(recorder.lap_times(i)) for i in range(len(recorder.sim.trains)))
    duration_s = float(t[-1]) if len(t) else 0.0
    headways = [h for h in (mean_headway_s(recorder, i) for i in behind) if h is not None]
    return {
        "policy": summary["policy"],
        "mean_gap_m": round(float(np.mean(gap)), 3),
        "mean_gap_following_m": round(float(np.mean(gap[following])), 3) if following.any() else None,
        "following_time_pct": round(100.0 * float(np.mean(following)), 1),
        "min_gap_m": round(float(np.min(gap)), 3),
        "mean_lap_s": round(float(np.mean(laps)), 3) if laps else None,
        "mean_headway_s": round(float(np.mean(headways)), 2) if headways else None,
        "trains_per_hour": round(3600.0 * total_laps / duration_s, 1) if duration_s else None,
        "max_speed_mps": round(top_mps, 3),
        "collisions": summary["collisions"],
        "authority_overruns": summary["authority_overruns"],
        "emergency_trips": summary["emergency_trips"],
        "simulated_s": summary["simulated_s"],
    }


def run_paper_systems(layout, seed=0, laps=5, blocks=None, estimator="ukf", code_ber=0.0):
    """The paper scenario under moving block (with Takagi control) and under fixed blocks; see `run_systems`."""
    base = paper_scenario(layout, seed=seed, laps=laps, duration_s=80.0 * laps, estimator=estimator)
    return run_systems(base, blocks, code_ber)


def run_systems(base: ScenarioConfig, blocks=None, code_ber=0.0):
    """The scenario `base` under moving block (with Takagi control) and under fixed blocks (`blocks` equal ones, or
    the scenario's or the layout's own), whose speed codes reach the trains as telegrams with bit-error rate
    `code_ber`; returns (figures, recorders)."""
    results, recorders = {}, {}
    systems = ((MOVING_BLOCK, {}),
               (FIXED_BLOCK, {"blocks": blocks or base.policy_options.get("blocks"), "code_ber": code_ber}))
    for policy, options in systems:
        sim = Simulation(replace(base, policy=policy, policy_options=options), keep_samples=True)
        if sim.policy.needs_spans:   # it reads track circuits: they see every train's true extent
            sim.policy.track_circuits = _truth_spans(sim)
        recorders[policy] = sim.run()
        results[policy] = system_figures(recorders[policy])
        codes = getattr(sim.policy, "codes", None)   # the speed codes a signalled policy sends as telegrams
        if codes is not None:
            results[policy]["speed_code_telegrams"] = dict(codes.counts)
    return results, recorders


def _truth_spans(sim):
    """Track circuits: the true extent of every train (what axle counters or track circuits detect)."""
    return lambda: [(t.train_id, t.head_s, t.tail_s) for t in sim.trains]


def reductions(moving, fixed):
    """Percent reductions of moving block against fixed block, as the paper computes them."""
    def pct(a, b):
        return None if a is None or b in (None, 0) else round(100.0 * (b - a) / b, 1)
    return {"gap_reduction_pct": pct(moving["mean_gap_following_m"], fixed["mean_gap_following_m"]),
            "lap_reduction_pct": pct(moving["mean_lap_s"], fixed["mean_lap_s"])}


def _following_config(layout, seed, leader_v_mps, duration_s, estimator, report_ms, fast):
    """Train A, slowed to `leader_v_mps`, 1.5 m ahead of train B (profile `fast`), both reporting every `report_ms`
    when it is given."""
    params = AuthorityParams() if report_ms is None else AuthorityParams(fast_report_ms=int(report_ms))
    trains = [TrainSpec("A", layout.wrap(1.5), (), fast.with_changes(v_max_mps=leader_v_mps)),
              TrainSpec("B", 0.0, (), fast)]
    return ScenarioConfig(layout=layout, seed=seed, duration_s=duration_s, estimator=estimator, params=params,
                          trains=trains, obu_overrides=None if report_ms is None else {"report_ms": int(report_ms)})


def steady_following(layout, seed=0, leader_v_mps=0.4, duration_s=60.0, settle_s=25.0, estimator="ukf",
                     report_ms=None):
    """Train B (line speed 0.6 m/s) catches up with a slower train A and follows it: achieved gap against the
    theoretical minimum S_M + v^2/(2 beta_s) at the speed B actually runs, sample by sample, and where the rest goes,
    measured in the run (`overhead_budget_m`, see _overhead_budget). `report_ms`: every report at this period, the
    fast ones the controller asks of a followed train included (None: the defaults, 50 ms and 20 ms when followed)."""
    fast = TrainProfile()
    config = _following_config(layout, seed, leader_v_mps, duration_s, estimator, report_ms, fast)
    params = config.params
    sim = Simulation(config)
    leader, follower = sim.trains
    basis = {}     # command seq sent to B -> (sample time of A's data behind it, combined sigma taken off)

    def on_command(sent):
        if sent.train_id == follower.train_id:
            basis[sent.command.seq] = (sent.leader_data_t_s, sent.sigma_m)

    rows = []      # one per loop tick: truth and the command B's board obeys
    trips = []     # ... and its trip count and end of authority (odometer mm)

    def probe(now_s):
        unit = follower.obu
        wheel_per_m = follower.encoder.distance_m / follower.travelled_m if follower.travelled_m > 0 else 1.0
        gap_m = layout.ahead_m(follower.head_s, leader.tail_s)
        rows.append((now_s, unit.cseq, (unit.eoa_mm - unit.odo_mm) / 1000.0 / wheel_per_m, leader.travelled_m,
                     follower.v_mps, gap_m))
        trips.append((unit.trips, unit.eoa_mm))

    sim.zc.commands.subscribe(on_command)
    sim.scheduler.call_every(config.loop_s, probe, start_s=0.0106)
    recorder = sim.run()
    t, cseq, eoa_ahead_m, leader_d_m, v_b, gap = (np.asarray(col, dtype=float) for col in zip(*rows))
    steady = (t >= settle_s) & (v_b > 0.05) & np.isin(cseq, list(basis))
    s_min = minimum_gap_m(v_b[steady], fast.beta_s_mps2, params.margin_m)
    achieved = float(np.mean(gap[steady]))
    lowest = float(np.min(gap[steady] / s_min))
    theoretical = float(np.mean(s_min))
    budget = _overhead_budget(config, fast, basis, steady, t, cseq, eoa_ahead_m, leader_d_m, v_b, gap)
    fresh_m = theoretical + budget["k_sigma_m"] + budget["stop_window_m"]   # the safety terms but the data's age
    summary = recorder.summary()
    return {
        "report_ms": report_ms or params.fast_report_ms,
        "leader_speed_mps": leader_v_mps,
        "follower_speed_mps": round(float(np.mean(v_b[steady])), 3),
        "achieved_gap_m": round(achieved, 4),
        "theoretical_min_gap_m": round(theoretical, 4),
        "achieved_over_theoretical": round(achieved / theoretical, 3),
        "lowest_over_theoretical": round(lowest, 3),   # never below 1: the gap is never short of S_min
        "overhead_m": round(achieved - theoretical, 4),
        "overhead_budget_m": budget,
        # what the ratio would be if B rode exactly on its curve with exact estimates: the safety terms alone
        "safety_floor_ratio": round((fresh_m + budget["leader_moved_m"]) / theoretical, 3),
        # ... and with the leader's data of no age as well: what no answer time can go below (k sigma, stop window)
        "fresh_floor_ratio": round(fresh_m / theoretical, 3),
        "collisions": summary["collisions"],
        "authority_overruns": summary["authority_overruns"],
        "emergency_trips": summary["emergency_trips"],
        # trips with no end of authority stepped back in the 0.3 s before: riding the curve itself tripped
        "trips_riding": _trips_riding(trips, config.loop_s),
    }


def _trips_riding(trips, loop_s, within_s=0.3):
    """Trips of the follower (per-tick (trips, eoa_mm)) with no step back of its end of authority in the `within_s`
    before: a bound that widened (the leader's sensors disagreeing) takes ground back and may trip a train riding its
    service curve, as it must; a trip without one is the loop's own."""
    ticks = max(1, int(round(within_s / loop_s)))
    riding = 0
    for i in range(1, len(trips)):
        if trips[i][0] > trips[i - 1][0]:
            back = any(trips[j][1] < trips[j - 1][1] for j in range(max(1, i - ticks), i + 1))
            riding += (trips[i][0] - trips[i - 1][0]) if not back else 0
    return riding


def _overhead_budget(config, profile, basis, steady, t, cseq, eoa_ahead_m, leader_d_m, v_b, gap):
    """Where the gap beyond S_min goes, each term measured on the steady samples against truth; they add up to the
    overhead exactly (gap - S_M - v^2/(2 beta_s)):

    leader_moved     how far the leader travelled since the sample of its data behind the end of authority B obeys
                     (its report period, both links, B's loop): the price of the brick wall with data of that age
    k_sigma          k times the combined sigma of both estimates that the controller took off
    estimates        the rest of the distance from the leader's true tail (at its data time) to B's end of authority
                     beyond S_M and k sigma: both estimates' errors, the low bound of B's encoder scale
    stop_window      the service curve ends this short of the end of authority (keeps it under the trip curve)
    inside_curve     how far B rides inside its service curve: the end of authority jumps forward at each report of
                     the leader and B cannot speed up at once; and its encoder, reading long, thinks it faster
    """
    p = config.params
    data_t = np.array([basis[int(c)][0] for c in cseq[steady]])
    k_sigma_m = p.k_sigma * np.array([basis[int(c)][1] for c in cseq[steady]])
    moved_m = leader_d_m[steady] - np.interp(data_t, t, leader_d_m)
    window_m = obu.DEFAULTS["stop_window_mm"] / 1000.0
    braking_m = braking_distance_m(v_b[steady], profile.beta_s_mps2)
    inside_m = eoa_ahead_m[steady] - window_m - braking_m
    # gap = moved + (tail at data time - end of authority) + (end of authority - head)
    estimates_m = gap[steady] - moved_m - eoa_ahead_m[steady] - p.margin_m - k_sigma_m
    terms = {"leader_moved_m": moved_m, "k_sigma_m": k_sigma_m, "estimates_m": estimates_m,
             "stop_window_m": np.full(moved_m.shape, window_m), "inside_curve_m": inside_m}
    return {name: round(float(np.mean(values)), 4) for name, values in terms.items()}


def check_block_counts(layout, counts, seed=0, base: ScenarioConfig = None):
    """Raise ConfigError naming the first block count of `counts` the fixed block of `base` (default: the paper
    scenario) refuses (no more blocks than trains on the loop, or a count the layout cannot be cut into): checked
    before any run starts."""
    from cbtc.zone.factory import make_policy
    base = base or paper_scenario(layout, seed=seed)
    for count in counts:
        try:
            make_policy(replace(base, policy=FIXED_BLOCK, policy_options={"blocks": int(count)}))
        except ConfigError as exc:
            raise ConfigError(f"--blocks {count}: {exc}") from None


def block_sweep(layout, counts, seed=0, laps=3, estimator="ukf", base: ScenarioConfig = None):
    """Fixed-block figures for each block count of `base` (default: the paper scenario): the baseline approaches
    moving block as blocks shrink."""
    base = base or paper_scenario(layout, seed=seed, laps=laps, duration_s=80.0 * laps, estimator=estimator)
    rows = []
    for count in counts:
        sim = Simulation(replace(base, policy=FIXED_BLOCK, policy_options={"blocks": int(count)}), keep_samples=True)
        sim.policy.track_circuits = _truth_spans(sim)
        figures = system_figures(sim.run())
        figures["blocks"] = int(count)
        figures["block_length_m"] = round(base.layout.length_m / int(count), 3)
        rows.append(figures)
    return rows


def minimum_leg_s(distance_m: float, profile) -> float:
    """The least time (s) to run `distance_m` from standing to standing: accelerate at the profile's traction limit,
    cruise at line speed, brake at its service rate (a triangle when the leg is too short to reach line speed)."""
    a, b, v = profile.accel_max_mps2, profile.beta_s_mps2, profile.v_max_mps
    ramps_m = v * v / (2 * a) + v * v / (2 * b)
    if distance_m >= ramps_m:
        return (distance_m - ramps_m) / v + v / a + v / b
    peak = math.sqrt(2.0 * distance_m * a * b / (a + b))
    return peak / a + peak / b


def least_headway_s(profile, margin_m: float, dwell_s: float) -> float:
    """The least time headway (s) of identical trains that stop `dwell_s` at every station (stations far enough
    apart for line speed), with exact positions and no reaction time: the leader departs, and its tail must be
    `margin_m` past the mark before the follower, braking from line speed at its service rate, may aim at it. So
    dwell + the time to run the train's length and the margin from standing + the time to brake from line speed;
    the follower's way is the leader's, later by it, at every point."""
    a, b, v = profile.accel_max_mps2, profile.beta_s_mps2, profile.v_max_mps
    clear_m = profile.length_m + margin_m
    ramp_m = v * v / (2 * a)
    clear_s = math.sqrt(2.0 * clear_m / a) if clear_m <= ramp_m else v / a + (clear_m - ramp_m) / v
    return dwell_s + clear_s + v / b


def _stands_near_stations(layout, t, v, head_s, near_m=0.1):
    """Every standstill within `near_m` of a station: (how long it stood (s), how far its head was past the
    station's mark (mm; negative: short of it))."""
    stands, k, n = [], 0, len(t)
    while k < n:
        if v[k] > 0.0:
            k += 1
            continue
        end = k
        while end < n and v[end] <= 0.0:
            end += 1
        past = [layout.wrap(head_s[k] - st.s_m + layout.length_m / 2) - layout.length_m / 2 for st in layout.stations]
        nearest = min(past, key=abs)
        if abs(nearest) <= near_m:
            stands.append((t[end - 1] - t[k], 1000.0 * nearest))
        k = end
    return stands


def lone_lap(layout, profile=None, dwell_s=2.0, seed=0, laps=4):
    """One train alone on a loop, stopping `dwell_s` at every station: its lap time (laps after the first, which
    starts from the start position) against the minimum-time lap for its profile (`minimum_leg_s` between
    consecutive stations plus the dwells), its top speed against line speed, how far from the mark it stops, and how
    often it stood short of a stop and moved on to it (crept)."""
    if not layout.closed or not layout.stations:
        raise ConfigError(f"layout {layout.name}: the lone lap needs a loop with stations")
    profile = profile or TrainProfile()
    stations = sorted(st.s_m for st in layout.stations)
    legs = [layout.ahead_m(a, b) or layout.length_m for a, b in zip(stations, stations[1:] + stations[:1])]
    minimum_s = sum(minimum_leg_s(d, profile) for d in legs) + dwell_s * len(legs)
    # it starts halfway along the longest leg: laps are counted where it runs, not where a stop a mm short of the
    # line would count the dwell into the lap before or after
    k = max(range(len(legs)), key=legs.__getitem__)
    start_m = layout.wrap(stations[k] + legs[k] / 2.0)
    config = ScenarioConfig(layout=layout, seed=seed, duration_s=(laps + 1) * 2.0 * minimum_s, laps=laps,
                            dwell_s=(dwell_s, dwell_s),
                            trains=[TrainSpec("A", start_m, tuple(st.name for st in layout.stations), profile)])
    sim = Simulation(config, keep_samples=True)
    recorder = sim.run()
    times = recorder.lap_times(0)[1:]
    t = np.asarray(recorder.t_s)
    v = np.asarray(recorder.v_mps[0])
    stands = _stands_near_stations(layout, t, v, np.asarray(recorder.head_s_m[0]))
    errors_mm = [past_mm for stood_s, past_mm in stands if stood_s >= 1.0]   # the stops: stood through a dwell
    lap_s = float(np.mean(times)) if times else None
    summary = recorder.summary()
    return {
        "layout": layout.name, "dwell_s": dwell_s, "laps": len(times),
        "lap_s": None if lap_s is None else round(lap_s, 3),
        "minimum_lap_s": round(minimum_s, 3),
        "lap_over_minimum": None if lap_s is None else round(lap_s / minimum_s, 4),
        "top_speed_mps": round(float(v.max()), 4), "line_speed_mps": profile.v_max_mps,
        "station_stops": summary["trains"][0]["station_stops"],
        "stop_error_mean_mm": round(float(np.mean(np.abs(errors_mm))), 1) if errors_mm else None,
        "stop_error_max_mm": round(float(np.max(np.abs(errors_mm))), 1) if errors_mm else None,
        # a train that stood still near a station and moved on before its dwell: it crept up to the mark
        "stops_with_creep": sum(1 for stood_s, _ in stands if stood_s < 1.0),
        "collisions": summary["collisions"], "authority_overruns": summary["authority_overruns"],
    }
