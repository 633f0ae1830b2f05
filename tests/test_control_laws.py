"""Takagi's laws against hand-computed values and against an analytic two-train run."""

import math

import pytest

from cbtc.authority.control_laws import (
    departure_accelerations_mps2,
    departure_k_for,
    sync_deceleration_mps2,
)
from cbtc.authority.rules import (
    AuthorityParams,
    braking_curve_speed_mps,
    minimum_gap_m,
    moving_block_distance_m,
)


def test_eq23_minimum_gap_by_hand():
    # S_M = 0.1 m, v = 0.6 m/s, beta_s = 0.8 m/s^2: 0.1 + 0.36 / 1.6 = 0.325 m
    assert minimum_gap_m(0.6, 0.8, 0.1) == pytest.approx(0.325)
    assert minimum_gap_m(0.0, 0.8, 0.1) == pytest.approx(0.1)


def test_eq24_sync_deceleration_by_hand():
    # v_B = 0.5, v_A = 0.3, beta_s = 0.8: 0.8 * 0.2 / 0.5 = 0.32 m/s^2
    assert sync_deceleration_mps2(0.5, 0.3, 0.8) == pytest.approx(0.32)
    assert sync_deceleration_mps2(0.5, 0.5, 0.8) == pytest.approx(0.0)
    assert sync_deceleration_mps2(0.4, 0.6, 0.8) == pytest.approx(-0.4)  # leader faster: follower may accelerate
    assert sync_deceleration_mps2(0.5, 0.0, 0.8) == pytest.approx(0.8)  # leader stopped dead: full service braking
    with pytest.raises(ValueError, match="departure"):
        sync_deceleration_mps2(0.0, 0.3, 0.8)


def test_eqs25_26_departure_by_hand():
    # k = 0.75, beta_s = 0.8: alpha_A = 0.6; alpha_B = 0.8 * (-1 + sqrt(4)) / 2 = 0.4
    alpha_a, alpha_b = departure_accelerations_mps2(0.75, 0.8)
    assert alpha_a == pytest.approx(0.6)
    assert alpha_b == pytest.approx(0.4)
    # k = 2: rejected (0 < k <= 1)
    with pytest.raises(ValueError):
        departure_accelerations_mps2(2.0, 0.8)


def test_departure_k_respects_both_traction_limits():
    k = departure_k_for(0.6, 0.6, 0.8)
    alpha_a, alpha_b = departure_accelerations_mps2(k, 0.8)
    assert alpha_a <= 0.6 + 1e-12 and alpha_b <= 0.6 + 1e-12
    assert k == pytest.approx(0.75)


def _integrate_pair(a_leader, follower_accel, gap0_m, vA0, vB0, beta_s, margin_m, t_end_s, dt_s=1e-4):
    """Two point trains: leader with a given acceleration profile, follower under a control law; returns max gap
    error."""
    xA, xB, vA, vB = gap0_m, 0.0, vA0, vB0
    worst = 0.0
    t = 0.0
    while t < t_end_s:
        aA = a_leader(t, vA)
        aB = follower_accel(vA, vB)
        xA += vA * dt_s + 0.5 * aA * dt_s ** 2
        xB += vB * dt_s + 0.5 * aB * dt_s ** 2
        vA = max(0.0, vA + aA * dt_s)
        vB = max(0.0, vB + aB * dt_s)
        t += dt_s
        if vB > 0.05:
            worst = max(worst, abs((xA - xB) - minimum_gap_m(vB, beta_s, margin_m)))
    return worst, xA - xB, vB


def test_sync_control_holds_the_gap_at_minimum_in_an_analytic_two_train_run():
    beta_s, margin = 0.8, 0.1
    vB0 = 0.6
    # leader slows from 0.6 to 0.2 m/s at 0.3 m/s^2, then cruises; follower starts at S_min(0.6)
    leader = lambda t, vA: -0.3 if vA > 0.2 else 0.0
    follower = lambda vA, vB: -sync_deceleration_mps2(vB, vA, beta_s) if vB > 0 else 0.0
    worst, gap, vB = _integrate_pair(leader, follower, minimum_gap_m(vB0, beta_s, margin), 0.6, vB0, beta_s, margin,
                                     4.0)
    assert worst < 1e-3, f"gap left S_min(v_B) by {worst * 1000:.2f} mm"
    assert vB == pytest.approx(0.2, abs=0.01)


def test_departure_control_keeps_b_at_minimum_from_standstill():
    beta_s, margin, k = 0.8, 0.1, 0.75
    alpha_a, alpha_b = departure_accelerations_mps2(k, beta_s)
    worst, gap, vB = _integrate_pair(lambda t, vA: alpha_a, lambda vA, vB: alpha_b, margin, 0.0, 0.0,
                                     beta_s, margin, 1.0)
    assert worst < 1e-3
    assert gap == pytest.approx(minimum_gap_m(vB, beta_s, margin), abs=1e-3)


def test_moving_block_distance_subtracts_margin_and_uncertainty():
    p = AuthorityParams(margin_m=0.1, k_sigma=3.0)
    # gap 1.0, sigmas 0.03 and 0.04 -> combined 0.05 -> 1.0 - 0.1 - 0.15 = 0.75
    assert moving_block_distance_m(1.0, 0.03, 0.04, p) == pytest.approx(0.75)


def test_stale_leader_data_shrinks_the_moving_block_distance():
    p = AuthorityParams(margin_m=0.1, k_sigma=3.0, stale_after_s=0.2, rollback_mps=0.05)
    fresh = moving_block_distance_m(1.0, 0.03, 0.04, p, leader_age_s=0.05)
    assert fresh == pytest.approx(0.75), "data younger than stale_after_s costs nothing"
    # 1.2 s old: 1.0 s beyond stale_after_s at 0.05 m/s -> 5 cm less
    assert moving_block_distance_m(1.0, 0.03, 0.04, p, leader_age_s=1.2) == pytest.approx(0.70)
    ages = [0.1 * k for k in range(40)]
    distances = [moving_block_distance_m(1.0, 0.03, 0.04, p, leader_age_s=a) for a in ages]
    assert all(b <= a for a, b in zip(distances, distances[1:]))


def test_braking_curve_counts_dead_time():
    # 0.5 m ahead, at 0.4 m/s with 0.25 s dead time: 0.4 m usable -> sqrt(2 * 0.8 * 0.4) = 0.8 m/s
    assert braking_curve_speed_mps(0.5, 0.4, 0.8, 0.25) == pytest.approx(math.sqrt(0.64))
    assert braking_curve_speed_mps(0.05, 0.4, 0.8, 0.25) == 0.0
