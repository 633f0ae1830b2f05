"""Movement authority, moving block with the brick-wall assumption: pure functions of estimates and parameters.

The follower's head may advance to the leader's tail as last estimated (the leader can only have moved on since),
minus the safety margin S_M, minus k standard deviations of the combined uncertainty of both estimates. The onboard
unit enforces the resulting end of authority with its braking curve (which counts its reaction time); the
controller also caps the commanded speed on the same curve with communication latency and data age counted.
"""

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class AuthorityParams:
    margin_m: float = 0.10          # S_M: safety margin kept behind the leader's tail when stopped
    k_sigma: float = 3.0            # standard deviations of estimate uncertainty taken off the authority
    max_leader_age_s: float = 1.0   # older data of the train ahead: the authority is not extended
    latency_s: float = 0.05         # command delivery latency budget counted in the speed cap
    ttl_s: float = 0.8              # command validity on board, from the report it is based on


def combined_sigma_m(sigma_follower_m: float, sigma_leader_m: float) -> float:
    return math.sqrt(sigma_follower_m ** 2 + sigma_leader_m ** 2)


def moving_block_distance_m(gap_est_m: float, sigma_follower_m: float, sigma_leader_m: float,
                            p: AuthorityParams) -> float:
    """Distance (m) the follower's head may still travel, from the estimated gap to the leader's tail."""
    return gap_est_m - p.margin_m - p.k_sigma * combined_sigma_m(sigma_follower_m, sigma_leader_m)


def braking_curve_speed_mps(distance_m: float, v_now_mps: float, beta_mps2: float, dead_time_s: float) -> float:
    """Highest speed (m/s) from which a train stops within `distance_m` at `beta_mps2`, after `dead_time_s` at `v_now_mps`."""
    usable_m = distance_m - v_now_mps * dead_time_s
    if usable_m <= 0.0:
        return 0.0
    return math.sqrt(2.0 * beta_mps2 * usable_m)


def minimum_gap_m(v_mps: float, beta_s_mps2: float, margin_m: float) -> float:
    """Eq. 23: S_min = S_M + v^2 / (2 beta_s), the brick-wall minimum gap at speed v."""
    return margin_m + v_mps * v_mps / (2.0 * beta_s_mps2)
