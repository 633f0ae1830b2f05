"""Headway experiments: moving block against the fixed-block baseline on the paper's scenario, and steady following.

Pure runners over `cbtc.scenario`: each takes a seed and returns plain dicts of figures, so the `compare` command,
the tests and anyone's notebook get the same numbers.
"""

import numpy as np

from .authority import minimum_gap_m
from .firmware_modules import obu
from .scenario import ScenarioConfig, Simulation, TrainSpec, paper_scenario
from .train_profile import TrainProfile

PAPER = {"fixed_gap_m": 1.89, "cbtc_gap_m": 0.91, "fixed_lap_s": 15.72, "cbtc_lap_s": 6.84,
         "gap_reduction_pct": 52.0, "lap_reduction_pct": 56.0}


def system_figures(recorder):
    """Gap, lap time, throughput and safety figures of one run of the paper scenario (train B follows train A)."""
    summary = recorder.summary()
    t = np.asarray(recorder.t_s)
    follower = 1  # B
    gap = np.asarray(recorder.gap_m[follower])
    v_a = np.asarray(recorder.v_mps[0])
    v_b = np.asarray(recorder.v_mps[follower])
    following = np.asarray(recorder.constrained[follower], dtype=bool)
    laps = [lap for i in range(len(recorder.sim.trains)) for lap in recorder.lap_times(i)]
    total_laps = sum(len(recorder.lap_times(i)) for i in range(len(recorder.sim.trains)))
    duration_s = float(t[-1]) if len(t) else 0.0
    return {
        "policy": summary["policy"],
        "mean_gap_m": round(float(np.mean(gap)), 3),
        "mean_gap_following_m": round(float(np.mean(gap[following])), 3) if following.any() else None,
        "following_time_pct": round(100.0 * float(np.mean(following)), 1),
        "min_gap_m": round(float(np.min(gap)), 3),
        "mean_lap_s": round(float(np.mean(laps)), 3) if laps else None,
        "trains_per_hour": round(3600.0 * total_laps / duration_s, 1) if duration_s else None,
        "max_speed_mps": round(float(max(np.max(v_a), np.max(v_b))), 3),
        "collisions": summary["collisions"],
        "authority_overruns": summary["authority_overruns"],
        "emergency_trips": summary["emergency_trips"],
        "simulated_s": summary["simulated_s"],
    }


def run_paper_systems(layout, seed=0, laps=5, blocks=None, estimator="ukf", code_ber=0.0):
    """The paper scenario under moving block (with Takagi control) and under fixed blocks, whose speed codes reach
    the trains as telegrams with bit-error rate `code_ber`; returns (figures, recorders)."""
    results, recorders = {}, {}
    for policy in ("moving_block", "fixed_block"):
        options = {} if policy == "moving_block" else {"blocks": blocks, "code_ber": code_ber}
        config = paper_scenario(layout, seed=seed, laps=laps, duration_s=80.0 * laps, policy=policy,
                                estimator=estimator, policy_options=options)
        sim = Simulation(config)
        if policy == "fixed_block":
            sim.policy.track_circuits = _truth_spans(sim)
        recorders[policy] = sim.run()
        results[policy] = system_figures(recorders[policy])
        if policy == "fixed_block":
            results[policy]["speed_code_telegrams"] = dict(sim.policy.codes.counts)
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


def steady_following(layout, seed=0, leader_v_mps=0.4, duration_s=60.0, settle_s=25.0, estimator="ukf",
                     report_ms=None):
    """Train B (line speed 0.6 m/s) catches up with a slower train A and follows it: achieved gap against
    the theoretical minimum S_M + v^2/(2 beta_s) at the speed B actually runs, sample by sample. `report_ms`: the
    boards' report period (None: the firmware's default)."""
    fast = TrainProfile()
    slow = fast.with_changes(v_max_mps=leader_v_mps)
    start_b = 0.0
    start_a = layout.wrap(start_b + 1.5)
    config = ScenarioConfig(layout=layout, seed=seed, duration_s=duration_s, estimator=estimator,
                            trains=[TrainSpec("A", start_a, (), slow), TrainSpec("B", start_b, (), fast)],
                            obu_overrides=None if report_ms is None else {"report_ms": int(report_ms)})
    sim = Simulation(config)
    below_curve = []   # how far the follower rides inside its service curve (m), sampled with the recorder
    follower = sim.trains[1]

    def probe(_now_s):
        unit = follower.obu
        v_m = max(0, unit.v_mmps) / 1000.0
        dist_m = (unit.eoa_mm - unit.odo_mm - unit.cfg["stop_window_mm"]) / 1000.0
        below_curve.append(dist_m - v_m * v_m / (2.0 * unit.cfg["dec_mmps2"] / 1000.0))

    sim.scheduler.call_every(config.loop_s, probe, start_s=0.0106)
    recorder = sim.run()
    t = np.asarray(recorder.t_s)
    gap = np.asarray(recorder.gap_m[1])
    v_b = np.asarray(recorder.v_mps[1])
    steady = (t >= settle_s) & (v_b > 0.05)
    n = min(len(below_curve), len(t))
    riding_m = float(np.mean(np.asarray(below_curve[:n])[steady[:n]]))
    s_min = minimum_gap_m(v_b[steady], fast.beta_s_mps2, config.params.margin_m)
    achieved = float(np.mean(gap[steady]))
    theoretical = float(np.mean(s_min))
    v_mean = float(np.mean(v_b[steady]))
    return {
        "report_ms": report_ms or obu.DEFAULTS["report_ms"],
        "leader_speed_mps": leader_v_mps,
        "follower_speed_mps": round(v_mean, 3),
        "achieved_gap_m": round(achieved, 4),
        "theoretical_min_gap_m": round(theoretical, 4),
        "achieved_over_theoretical": round(achieved / theoretical, 3),
        "overhead_m": round(achieved - theoretical, 4),
        "overhead_budget_m": _overhead_budget(sim, steady, riding_m, achieved - theoretical),
        "collisions": recorder.summary()["collisions"],
        "authority_overruns": recorder.summary()["authority_overruns"],
    }


def _overhead_budget(sim, steady, riding_m, overhead_m):
    """Where the distance beyond S_min goes, over the steady samples: the stop window the service curve keeps (by
    design), k sigma of both estimates (measured), how far the follower rides inside its curve (measured on board:
    its speed cannot follow the saw-tooth of an end of authority that jumps at each report of the train ahead), and
    the remainder: the age of the leader's data (its report period, latency) and estimate errors."""
    rec = sim.recorder
    sigma_a = np.asarray(rec.est_sigma_m[0])[steady]
    sigma_b = np.asarray(rec.est_sigma_m[1])[steady]
    k_sigma_m = sim.config.params.k_sigma * float(np.nanmean(np.sqrt(sigma_a ** 2 + sigma_b ** 2)))
    window_m = obu.DEFAULTS["stop_window_mm"] / 1000.0
    return {"stop_window_m": round(window_m, 4), "k_sigma_m": round(k_sigma_m, 4),
            "inside_curve_m": round(riding_m, 4),
            "leader_data_age_m": round(overhead_m - window_m - k_sigma_m - riding_m, 4)}


def block_sweep(layout, counts, seed=0, laps=3, estimator="ukf"):
    """Fixed-block figures for each block count: the baseline approaches moving block as blocks shrink."""
    rows = []
    for count in counts:
        config = paper_scenario(layout, seed=seed, laps=laps, duration_s=80.0 * laps, policy="fixed_block",
                                estimator=estimator, policy_options={"blocks": int(count)})
        sim = Simulation(config)
        sim.policy.track_circuits = _truth_spans(sim)
        figures = system_figures(sim.run())
        figures["blocks"] = int(count)
        figures["block_length_m"] = round(layout.length_m / int(count), 3)
        rows.append(figures)
    return rows
