"""Movement authority, moving block with the brick-wall assumption: pure functions of estimates and parameters.

The follower's head may advance to the leader's tail as last estimated (brick wall: the leader may have stopped dead
since, so its position is not extrapolated), minus the safety margin S_M, minus k standard deviations of the combined
uncertainty of both estimates, minus a rollback allowance that grows with the age of the leader's data: a train not
heard from for a while may have rolled back or been moved by hand, so stale data shrinks the authority. The onboard
unit enforces the resulting end of authority with its service and trip curves (the trip curve counts the reaction
time); the end of authority is a point of the follower's own odometer, so the follower's data age and the command
latency do not move it.
"""

from dataclasses import dataclass
from math import sqrt

from cbtc.railway.physics import braking_distance_m


@dataclass(frozen=True)
class AuthorityParams:
    margin_m: float = 0.10          # S_M: safety margin kept behind the leader's tail when stopped
    k_sigma: float = 3.0            # standard deviations of estimate uncertainty taken off the authority
    max_leader_age_s: float = 1.0   # older data of the train ahead: the authority is not extended
    latency_s: float = 0.05         # command delivery latency budget counted in the speed cap
    ttl_s: float = 0.8              # command validity on board, from the report it is based on
    fast_report_ms: int = 20        # report period asked of a train while the train behind is held by it
    fast_hold_s: float = 1.0        # ... and for this long after
    stale_after_s: float = 0.2      # leader data older than this shrinks the authority (several reports + latency)
    rollback_mps: float = 0.05      # ... by this much per second of age beyond that: how fast a train not heard from
    #                                 may have moved back (rolled back, pushed by hand)
    restricted_mps: float = 0.15    # the most a train not yet confirmed by two independent references may run
    slide_share: float = 0.3        # a wheel may begin to read this much short of the travel at any moment, with
    #                                 nothing to show it until the train has moved: the authority held on board, in
    #                                 odometer units, still ends within the margin for such a wheel


def combined_sigma_m(sigma_follower_m: float, sigma_leader_m: float) -> float:
    return sqrt(sigma_follower_m ** 2 + sigma_leader_m ** 2)


def rollback_allowance_m(leader_age_s: float, p: AuthorityParams, leader_v_mps: float = None,
                         leader_beta_e_mps2: float = None) -> float:
    """How far (m) behind its last-seen position a train whose data is `leader_age_s` old may be. Any train may roll
    back (a slope its brakes do not hold) at `rollback_mps` over the data's age plus the command's time to live; one
    moving at `leader_v_mps` when last seen first goes forward at least the way it takes to stop at its emergency
    rate, which is taken off. Its stopping time is not: as a train ahead brakes at up to its emergency rate, its
    position grows at least as fast as this allowance, so an end of authority behind it never steps back (a follower
    riding its braking curve would trip). Once its data is stale it may also have been moved by hand at
    `rollback_mps` (None for the speed: that rule alone)."""
    stale_m = p.rollback_mps * max(0.0, leader_age_s - p.stale_after_s)
    if leader_v_mps is None:
        return stale_m
    v_mps = max(0.0, leader_v_mps)
    roll_m = p.rollback_mps * (max(0.0, leader_age_s) + p.ttl_s) - v_mps * v_mps / (2.0 * leader_beta_e_mps2)
    return max(stale_m, roll_m)


def moving_block_distance_m(gap_est_m: float, sigma_follower_m: float, sigma_leader_m: float,
                            p: AuthorityParams, leader_age_s: float = 0.0, leader_v_mps: float = None,
                            leader_beta_e_mps2: float = None) -> float:
    """Distance (m) the follower's head may still travel, from the estimated gap to the leader's tail as last seen,
    whose data is `leader_age_s` old at the time the authority is computed (rollback_allowance_m)."""
    return (gap_est_m - p.margin_m - p.k_sigma * combined_sigma_m(sigma_follower_m, sigma_leader_m)
            - rollback_allowance_m(leader_age_s, p, leader_v_mps, leader_beta_e_mps2))


def checked_gap_m(gap_est_m: float, sigma_m: float, measured, now_s: float, p: AuthorityParams,
                  ranging_sigma_m: float, use_measured: bool):
    """(gap m the authority may use, alarm) from the estimated gap (1-sigma `sigma_m`) and the train's own measured
    one, `measured` = (time s, gap m) or None: the shorter of the two while the measurement is fresh (not older than
    max_leader_age_s; only the estimate when `use_measured` is False). The alarm ("the picture disagrees") is raised
    when they differ by more than 3 sigma of the estimate plus 3 sigma of the ranging; None without a fresh one."""
    if measured is None or now_s - measured[0] > p.max_leader_age_s:
        return gap_est_m, None
    measured_m = measured[1]
    alarm = abs(gap_est_m - measured_m) > 3.0 * (sigma_m + ranging_sigma_m)
    return (min(gap_est_m, measured_m) if use_measured else gap_est_m), alarm


def scale_trusted(odo_per_m: float, lowest: float, highest: float) -> bool:
    """True when `odo_per_m` (odometer metres per true metre) is finite and within [lowest, highest], the band a real
    wheel can have: outside it, an authority turned into odometer units could reach anywhere (or flip sign)."""
    return lowest <= odo_per_m <= highest   # False for NaN


def braking_curve_speed_mps(distance_m: float, v_now_mps: float, beta_mps2: float, dead_time_s: float) -> float:
    """Highest speed (m/s) from which a train stops within `distance_m` at `beta_mps2`, after `dead_time_s` at
    `v_now_mps`."""
    usable_m = distance_m - v_now_mps * dead_time_s
    if usable_m <= 0.0:
        return 0.0
    return sqrt(2.0 * beta_mps2 * usable_m)


def following_reach_m(profile) -> float:
    """Distance (m) within which an end of authority limits a train's speed: its braking distance from line speed,
    the reaction distance, and 5 cm. A train whose authority is shorter is held by the train ahead (it follows)."""
    v = profile.v_max_mps
    return braking_distance_m(v, profile.beta_s_mps2) + v * profile.reaction_s + 0.05


def horizon_m(profile, p: AuthorityParams) -> float:
    """The furthest (m) an end of authority is set ahead of a train: its following reach plus what it travels at line
    speed over a command's time to live. A train running at line speed is never held by it (a fresh command comes
    every report), while an odometer that starts to read short (a slipping wheel) can carry the train past its end by
    a share of this at most, not of the whole way to the train ahead."""
    return following_reach_m(profile) + profile.v_max_mps * p.ttl_s


def within_horizon(auth, reach_m: float):
    """`auth` (an Authority) cut to `reach_m`, the train's horizon_m, its reason saying so; unchanged when it is
    within."""
    if auth.distance_m <= reach_m:
        return auth
    return auth.cut_to(reach_m, f"horizon ({auth.reason} further)")


def minimum_gap_m(v_mps: float, beta_s_mps2: float, margin_m: float) -> float:
    """Eq. 23: S_min = S_M + v^2 / (2 beta_s), the brick-wall minimum gap at speed v."""
    return margin_m + braking_distance_m(v_mps, beta_s_mps2)
