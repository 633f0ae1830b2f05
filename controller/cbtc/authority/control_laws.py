"""Takagi's synchronisation and departure control (paper eqs. 23-26): pure functions, SI units.

Brick-wall minimum gap (eq. 23):  S_min = S_M + v_B^2 / (2 beta_s)
Synchronisation (eq. 24):         beta_B = beta_s (v_B - v_A) / v_B          (v_B != 0)
Departure (eqs. 25-26):           alpha_A = k beta_s,  alpha_B = beta_s (-1 + sqrt(1 + 4k)) / 2,  0 < k <= 1

With the gap at S_min(v_B), eq. 24 keeps it there while both trains move (d/dt of the gap equals d/dt of S_min);
with both standing at S_min(0) = S_M, eqs. 25-26 keep B exactly at S_min(v_B) while both accelerate.
"""

from math import sqrt


def sync_deceleration_mps2(v_follower_mps: float, v_leader_mps: float, beta_s_mps2: float) -> float:
    """Eq. 24: the follower's deceleration (m/s^2, positive = braking; negative = it may accelerate) that holds the
    gap at its minimum. Undefined at v_B = 0: a standing follower needs departure control, so this raises."""
    if v_follower_mps <= 0.0:
        raise ValueError("sync_deceleration_mps2: v_follower_mps must be > 0 (use departure control at standstill)")
    return beta_s_mps2 * (v_follower_mps - v_leader_mps) / v_follower_mps


def departure_accelerations_mps2(k: float, beta_s_mps2: float):
    """Eqs. 25-26: (alpha_A, alpha_B) in m/s^2 for leader A and follower B departing together from minimum distance."""
    if not 0.0 < k <= 1.0:
        raise ValueError(f"departure_accelerations_mps2: k must be in (0, 1], got {k}")
    return k * beta_s_mps2, beta_s_mps2 * (-1.0 + sqrt(1.0 + 4.0 * k)) / 2.0


def departure_k_for(accel_max_leader_mps2: float, accel_max_follower_mps2: float, beta_s_mps2: float) -> float:
    """The largest k in (0, 1] whose accelerations both trains can deliver."""
    k_leader = accel_max_leader_mps2 / beta_s_mps2
    # alpha_B(k) <= a_max  <=>  k <= (a/beta) * (a/beta + 1)
    ratio = accel_max_follower_mps2 / beta_s_mps2
    return max(1e-6, min(1.0, k_leader, ratio * (ratio + 1.0)))

