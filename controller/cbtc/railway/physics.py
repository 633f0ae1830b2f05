"""Longitudinal train dynamics: a DC motor's first-order response to signed duty, friction, adhesion and brake limits.

Pure: `step` maps (state, motor command, dt) to the next state. Trains run forward only (the testbed's loops are
one-way); a negative duty acts as a reverse-torque brake bounded by the emergency deceleration.
"""

from cbtc.railway.train_profile import TrainProfile


def acceleration_mps2(v_mps: float, duty_pct: float, motor_mode: str, p: TrainProfile) -> float:
    """Acceleration (m/s^2) at speed `v_mps` under `motor_mode` ('drive' | 'coast' | 'brake') and `duty_pct`."""
    if motor_mode == "brake":
        return -p.beta_e_mps2 if v_mps > 0 else 0.0
    friction = p.friction_mps2 if v_mps > 0 else 0.0
    if motor_mode == "coast":
        return -friction
    drive = (duty_pct / 100.0 * p.v_noload_mps - v_mps) / p.motor_tau_s
    if v_mps <= 0 and drive <= friction:
        return 0.0  # static friction holds the train
    return max(-p.beta_e_mps2, min(p.accel_max_mps2, drive - friction))


def step(s_m: float, v_mps: float, duty_pct: float, motor_mode: str, dt_s: float, p: TrainProfile):
    """Advance one step of `dt_s` seconds. Returns (s_m, v_mps, a_mps2); the speed never goes below zero."""
    a_mps2 = acceleration_mps2(v_mps, duty_pct, motor_mode, p)
    v_next = v_mps + a_mps2 * dt_s
    if v_next < 0.0:
        # stops inside the step: travel only until standstill
        t_stop = v_mps / -a_mps2 if a_mps2 < 0 else 0.0
        return s_m + 0.5 * v_mps * t_stop, 0.0, a_mps2
    return s_m + 0.5 * (v_mps + v_next) * dt_s, v_next, a_mps2


def braking_distance_m(v_mps: float, decel_mps2: float) -> float:
    """Distance (m) to stop from `v_mps` at constant deceleration `decel_mps2`."""
    return v_mps * v_mps / (2.0 * decel_mps2)
