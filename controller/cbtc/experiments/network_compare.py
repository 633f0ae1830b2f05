"""Moving block against the fixed-block baseline on a track network: the same trains, plans and interlocking, only the
authority differs (moving block: up to the rear-most plausible tail ahead; fixed block: up to the signal before the
first occupied block, railway.network_layout.section_blocks). Throughput as on a loop: rounds of each itinerary per
hour, all trains together."""

from dataclasses import replace

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.sim.simulation import Simulation

SAFETY = ("collisions", "authority_overruns", "switch_violations")


def network_figures(summary) -> dict:
    """Throughput and safety figures of one network run's summary (sim.network_recorder)."""
    trains = summary["trains"]
    hours = summary["simulated_s"] / 3600.0
    rounds = sum(t["laps"] for t in trains)
    return {
        "policy": summary["policy"],
        "trains_per_hour": round(rounds / hours, 1) if hours else None,
        "stops_per_hour": round(sum(t["station_stops"] for t in trains) / hours, 1) if hours else None,
        "mean_lap_s": round(summary["simulated_s"] * len(trains) / rounds, 2) if rounds else None,
        **{name: summary[name] for name in SAFETY},
        "plan_completed": summary["plan_completed"],
        "emergency_trips": summary["emergency_trips"],
        "granted_beyond_m": summary["granted_beyond_m"],
        "simulated_s": summary["simulated_s"],
    }


def run_network_systems(base, code_ber=0.0) -> dict:
    """The network scenario `base` under moving block and under fixed blocks (speed codes as telegrams with bit-error
    rate `code_ber`): policy -> network_figures, and the gain in trains per hour."""
    systems = {}
    for policy, options in ((MOVING_BLOCK, {}), (FIXED_BLOCK, {"code_ber": code_ber})):
        recorder = Simulation(replace(base, policy=policy, policy_options=options)).run()
        systems[policy] = network_figures(recorder.summary())
    moving, fixed = systems[MOVING_BLOCK]["trains_per_hour"], systems[FIXED_BLOCK]["trains_per_hour"]
    gain = round(100.0 * (moving - fixed) / fixed, 1) if moving is not None and fixed else None
    return {"systems": systems, "trains_per_hour_gain_pct": gain}
