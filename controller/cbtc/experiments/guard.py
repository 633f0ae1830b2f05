"""The faulty-leader scenario: the zone controller's picture of the leader is wrong; the onboard guard alone saves it.

Paper scenario (train A ahead of B on the square loop, station stops). Train A's sensors fail together in the dangerous
direction: its encoder counts run `encoder_fault` times fast and its IPS places it `ips_offset_m` ahead of where it
stands; its profile was calibrated with that same encoder, so the controller believes its motor and traction that
many times stronger too and its speeds look like ones the motor gives (cbtc.estimation.speed_envelope). The
controller then believes A is well ahead, so B's movement authority runs past A's real tail, and when A stops at a
station B runs into it. With train-to-train ranging on (cbtc.ranging.transponder, cbtc.sim.ranging), B's
OnboardUnit measures the true gap and brakes on its own (the collision guard in firmware/obu.py); the zone controller is
told not to use the measured gap for authority here (it only raises its "picture disagrees" alarm), so the guard alone
is what prevents the collision.
"""

from cbtc.layout_files import load_layout
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import paper_scenario

ENCODER_FAULT = 1.5
IPS_OFFSET_M = 1.0


def faulty_leader_simulation(layout, seed, guard, duration_s=60.0, ranging=None,
                             encoder_fault=ENCODER_FAULT, ips_offset_m=IPS_OFFSET_M):
    """A ready Simulation of the paper scenario with train A's encoder and IPS faulted; `guard` arms ranging and the
    onboard guard on every train (`ranging`: RangingSensor settings, defaults when None)."""
    config = paper_scenario(layout, seed=seed, laps=None, duration_s=duration_s,
                            ranging=(dict(ranging or {}) if guard else None))
    sim = Simulation(config)
    leader = sim.trains[0]
    leader.encoder.scale_fault = encoder_fault
    leader.ips.offset_m = ips_offset_m
    p = leader.profile
    sim.zc.retune(leader.train_id, p.with_changes(v_noload_mps=p.v_noload_mps * encoder_fault,
                                                  accel_max_mps2=p.accel_max_mps2 * encoder_fault))
    sim.zc.use_measured_gap = False   # the onboard guard alone: the controller only raises its alarm
    return sim


def run_guard_case(layout, seed, guard, duration_s=60.0):
    """Figures of one run: collisions, the follower's minimum true gap, and how often its guard braked."""
    sim = faulty_leader_simulation(layout, seed, guard, duration_s)
    recorder = sim.run()
    follower = sim.trains[1]
    summary = recorder.summary()
    return {"seed": seed, "guard": guard, "collisions": sum(recorder.collisions),
            "follower_collisions": recorder.collisions[1],
            "min_gap_m": summary["trains"][1]["min_gap_m"],
            "guard_trips": follower.obu.guard_trips,
            "picture_alarms": sim.zc.view(sim.scheduler.now_s()).train(follower.train_id).gap_alarms,
            "simulated_s": round(summary["simulated_s"], 2)}


def guard_comparison(seeds, layout_name="itb_square", duration_s=60.0):
    """Both ways over `seeds`: {'off': [case...], 'on': [case...]}."""
    layout = load_layout(layout_name)
    return {"off": [run_guard_case(layout, s, False, duration_s) for s in seeds],
            "on": [run_guard_case(layout, s, True, duration_s) for s in seeds]}
