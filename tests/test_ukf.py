"""The track-constrained UKF: a linear-KF oracle on a straight, NEES consistency, outlier gate, loop seam, late data.

Streams are synthetic: the simulator's own sensor models (cbtc.sim.drivers) driven along a prescribed speed profile,
packed into reports the way the OnboardUnit packs them (10 Hz, newest IPS fix, tag reads with their odometer).
"""

import json
import math

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from scipy.stats import chi2

from cbtc.cli import main
from cbtc.errors import ConfigError
from cbtc.estimation import ukf_params, wheel_watch
from cbtc.estimation.estimate import BoardClock
from cbtc.estimation.track_ukf import TrackUkf
from cbtc.estimation.ukf_estimator import UkfEstimator
from cbtc.estimation.ukf_model import (
    NoiseModel,
    along_track_residual,
    initial_covariance,
    process_noise,
    tag_read_model,
)
from cbtc.firmware import obu
from cbtc.layout_files import load_layout
from cbtc.railway import balise
from cbtc.railway.ips_frame import track_to_ips
from cbtc.railway.train_profile import TrainProfile
from cbtc.sim.drivers import SimEncoder, SimIps, SimRfid

BOARD_OFFSET_MS = 5_000_000     # the board's clock runs this far ahead of the controller's
LINK_S = 0.0                    # report transit time: zero, so board stamps map exactly onto truth times
LOOP_MS = 20


def cruise_and_stop(t_s):
    """Target speed (m/s): 8 s at 0.5 m/s, then 2 s standing, repeated."""
    return 0.5 if t_s % 10.0 < 8.0 else 0.0


def synthetic_run(layout, profile, seed, duration_s, s0_m=0.0, target=cruise_and_stop, rfid_every=1):
    """(reports, truth): reports as the OnboardUnit sends them; truth rows (controller time s, unwrapped s m, v m/s)
    at every 20 ms loop tick. Acceleration 0.5 m/s^2, braking 0.8 m/s^2. The reader answers at every `rfid_every`-th
    tick (a slower reader, or polls that fail in between)."""
    rng = np.random.default_rng(seed)
    enc, ips, rfid = SimEncoder(profile, rng), SimIps(profile, layout, rng), SimRfid(profile, layout, rng)
    travelled_m = v_mps = 0.0
    truth, reports, ring = [], [], []
    fix, tags = None, []
    dt_s = LOOP_MS / 1000.0
    for k in range(int(duration_s / dt_s) + 1):
        t_s = k * dt_s
        t_ms = BOARD_OFFSET_MS + k * LOOP_MS
        v_mps += max(-0.8 * dt_s, min(0.5 * dt_s, target(t_s) - v_mps))
        travelled_m += v_mps * dt_s
        enc.advance(v_mps * dt_s)
        s_m = float(layout.wrap(s0_m + travelled_m))
        ips.sample(t_ms, s_m)
        rfid.sense(s_m)
        odo_mm = enc.count() * 1000 // profile.counts_per_m
        ring.append((t_ms, odo_mm))
        polled = ips.poll(t_ms)
        if polled is not None:
            fix = [polled[0], polled[1], polled[2]]
        uid = rfid.poll(t_ms) if k % rfid_every == 0 else None
        if uid is not None:   # the board's entry: the time since the reader's previous poll that answered
            tags.append([uid, odo_mm, t_ms, rfid_every * LOOP_MS if k else 0])
        truth.append((t_s, s0_m + travelled_m, v_mps))
        if k % 5 == 0:
            old_ms, old_mm = ring[max(0, len(ring) - 6)]
            v_mmps = (odo_mm - old_mm) * 1000 // (t_ms - old_ms) if t_ms > old_ms else 0
            reports.append({"t_ms": t_ms, "odo_mm": odo_mm, "v_mmps": v_mmps, "ips": fix, "tags": tags})
            fix, tags = None, []
    return reports, np.array(truth)


def controller_s(t_ms):
    return (t_ms - BOARD_OFFSET_MS) / 1000.0


def feed(estimator, reports, clock=None):
    """Deliver reports in list order, each LINK_S after its sampling; returns the clock."""
    clock = clock or BoardClock()
    for report in reports:
        clock.observe(report["t_ms"], controller_s(report["t_ms"]) + LINK_S)
        estimator.on_report(report, clock)
    return clock


def along_error_m(layout, s_est_m, s_true_m):
    return float(along_track_residual(layout)(np.array([s_est_m]), np.array([float(layout.wrap(s_true_m))]))[0])


@pytest.fixture(scope="module")
def loop():
    return load_layout("itb_square")


@pytest.fixture(scope="module")
def straight():
    return load_layout("straight_test")


# --- the oracle: on a straight the IPS model is linear, so the UKF must be the Kalman filter --------------------------

def test_ukf_equals_linear_kalman_filter_on_a_straight(straight):
    noise = NoiseModel(accel_psd_m2ps3=0.3, slip_var_m2_per_m=2e-6, scale_var_per_m=0.0, odo_var_m2=1e-7,
                       ips_var_m2=0.05 ** 2, tag_var_m2=4e-6, rfid_range_m=0.015, gate_prob=0.999999)
    x0 = np.array([1.0, 0.3, 0.0])
    P0 = initial_covariance(3, 0.05, 0.1, 0.002, 0.0)
    ukf = TrackUkf(straight, noise, x0, P0, t_s=0.0)
    p0 = np.array([float(c) for c in straight.xy(0.0)])
    u = np.array([float(c) for c in straight.xy(1.0)]) - p0      # unit direction of the straight
    kf = KalmanFilter(dim_x=3, dim_z=1)
    kf.x, kf.P = x0.copy(), P0.copy()
    rng = np.random.default_rng(7)
    t_s, s_true, v_true, d_true = 0.0, 1.0, 0.3, 0.0
    for step in range(60):
        dt_s = float(rng.uniform(0.02, 0.15))       # irregular, as measurements arrive
        t_s += dt_s
        s_true += v_true * dt_s
        d_true += v_true * dt_s
        kf.F = np.array([[1.0, dt_s, 0.0], [0.0, 1.0, 0.0], [0.0, dt_s, 1.0]])
        kf.Q = process_noise(3, dt_s, kf.x[1], 0.0, noise)
        kf.predict()
        ukf.predict_to(t_s)
        if step % 3 == 2:
            z = p0 + u * s_true + rng.normal(0.0, 0.05, 2)
            H = np.array([[u[0], 0.0, 0.0], [u[1], 0.0, 0.0]])
            kf.update(z - p0, R=np.eye(2) * noise.ips_var_m2, H=H)
            assert ukf.update_ips(*z)
        else:
            d = d_true + rng.normal(0.0, 3e-4)
            kf.update(np.array([d]), R=np.array([[noise.odo_var_m2]]), H=np.array([[0.0, 0.0, 1.0]]))
            assert ukf.update_odometer(d)
        np.testing.assert_allclose(ukf.x, kf.x, rtol=0, atol=1e-9)
        np.testing.assert_allclose(ukf.P, kf.P, rtol=0, atol=1e-12)
    assert abs(ukf.x[0] - s_true) < 0.02


# --- consistency ------------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("tags, rfid_every", [(True, 1), (True, 3), (False, 1)],
                         ids=["encoder+ips+rfid", "encoder+ips+rfid every 60 ms", "encoder+ips"])
def test_nees_within_chi_square_bounds(loop, tags, rfid_every):
    """Monte-Carlo NEES of the along-track position over 6 seeded runs: at each report time the run-averaged NEES lies
    inside the 99 % chi-square(6)/6 interval nearly always, and its time average is near 1 (1 degree of freedom).
    A reader that answers every third pass (its reads up to 30 mm past the field's edge at 0.5 m/s) keeps it so: the
    reads say how long ago the reader's previous poll was."""
    profile = TrainProfile()
    runs = 6
    nees = []
    for seed in range(runs):
        reports, truth = synthetic_run(loop, profile, seed, duration_s=40.0, s0_m=0.3 * seed, rfid_every=rfid_every)
        est = UkfEstimator(loop, profile)
        clock = BoardClock()
        row = []
        for report in reports:
            feed(est, [report if tags else dict(report, tags=[])], clock)
            t_s = controller_s(report["t_ms"])
            if t_s < 5.0:
                continue   # settled
            e = est.estimate(t_s)
            err = along_error_m(loop, e.s_m, truth[round(t_s * 1000) // LOOP_MS, 1])
            row.append(err ** 2 / e.sigma_s_m ** 2)
        nees.append(row)
    mean_over_runs = np.mean(np.array(nees), axis=0)
    low, high = chi2.ppf(0.005, runs) / runs, chi2.ppf(0.995, runs) / runs
    inside = np.mean((mean_over_runs > low) & (mean_over_runs < high))
    assert inside >= 0.9, f"only {inside:.2f} of the times are inside [{low:.2f}, {high:.2f}]"
    assert 0.4 < float(np.mean(mean_over_runs)) < 1.6, f"time-averaged NEES {np.mean(mean_over_runs):.2f}"


def test_scale_error_is_learnt_and_encoder_alone_keeps_going(loop):
    profile = TrainProfile()   # its wheel reads 2 % long; the filter starts from 0 +- 3 %
    reports, truth = synthetic_run(loop, profile, seed=3, duration_s=60.0)
    est = UkfEstimator(loop, profile)
    feed(est, reports[:400])
    assert abs(est.scale_error - profile.encoder_scale_error) < 0.004
    # IPS and RFID lost for the last 20 s: the learnt scale keeps the error near the pure slip walk
    blind = [dict(r, ips=None, tags=[]) for r in reports[400:]]
    feed(est, blind)
    t_s = controller_s(reports[-1]["t_ms"])
    e = est.estimate(t_s)
    err = along_error_m(loop, e.s_m, truth[-1, 1])
    assert abs(err) < 0.03
    assert abs(err) < 3.0 * e.sigma_s_m


# --- robustness -------------------------------------------------------------------------------------------------------

def test_ips_outlier_of_one_metre_moves_the_estimate_less_than_a_centimetre(loop):
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    reports, _truth = synthetic_run(loop, profile, seed=5, duration_s=20.0)
    i = next(i for i in range(150, 200) if reports[i]["ips"] is not None)
    bad = [dict(r) for r in reports]
    fix_t_ms, x_mm, y_mm = bad[i]["ips"]
    bad[i]["ips"] = [fix_t_ms, x_mm + 600, y_mm + 800]     # 1 m off
    clean, spoiled = UkfEstimator(loop, profile), UkfEstimator(loop, profile)
    feed(clean, reports[:i + 1])
    feed(spoiled, bad[:i + 1])
    t_s = controller_s(reports[i]["t_ms"])
    assert abs(along_error_m(loop, spoiled.estimate(t_s).s_m, clean.estimate(t_s).s_m)) < 0.01
    assert spoiled.rejected_ips == clean.rejected_ips + 1


def test_unknown_tag_is_counted_and_ignored(loop):
    profile = TrainProfile()
    reports, _truth = synthetic_run(loop, profile, seed=6, duration_s=10.0)
    odd = [dict(r) for r in reports]
    odd[60] = dict(odd[60], tags=odd[60]["tags"] + [["deadbeef", odd[60]["odo_mm"], odd[60]["t_ms"], 8]])
    a, b = UkfEstimator(loop, profile), UkfEstimator(loop, profile)
    feed(a, reports)
    feed(b, odd)
    t_s = controller_s(reports[-1]["t_ms"])
    assert b.unknown_tags == 1 and a.unknown_tags == 0
    assert a.estimate(t_s).s_m == b.estimate(t_s).s_m


def test_crossing_the_loop_seam_gives_no_jump(loop):
    profile = TrainProfile()
    reports, truth = synthetic_run(loop, profile, seed=8, duration_s=16.0, s0_m=loop.length_m - 3.0,
                                   target=lambda t_s: 0.5)
    est = UkfEstimator(loop, profile)
    clock = BoardClock()
    previous = None
    crossed = False
    for report in reports:
        feed(est, [report], clock)
        t_s = controller_s(report["t_ms"])
        if t_s < 3.0:
            continue
        e = est.estimate(t_s)
        true_s = truth[round(t_s * 1000) // LOOP_MS, 1]
        assert abs(along_error_m(loop, e.s_m, true_s)) < 0.02
        assert 0.0 <= e.s_m < loop.length_m
        if previous is not None:
            step_m = along_error_m(loop, e.s_m, previous)
            assert -0.005 < step_m < 0.5 * 0.1 + 0.01        # at most v * 100 ms forward, never a lap
            crossed = crossed or e.s_m < previous
        previous = e.s_m
    assert crossed


def test_dropout_predicts_and_uncertainty_grows(loop):
    profile = TrainProfile()
    reports, truth = synthetic_run(loop, profile, seed=9, duration_s=30.0, target=lambda t_s: 0.4)
    est = UkfEstimator(loop, profile)
    feed(est, reports[:200])
    t_s = controller_s(reports[199]["t_ms"])
    before = est.estimate(t_s)
    later = est.estimate(t_s + 1.0)      # no report for a second: prediction only
    assert later.sigma_s_m > before.sigma_s_m
    assert abs(along_error_m(loop, later.s_m, before.s_m) - before.v_mps * 1.0) < 1e-9
    assert later.age_s == pytest.approx(1.0 + before.age_s)
    err = along_error_m(loop, later.s_m, truth[round((t_s + 1.0) * 1000) // LOOP_MS, 1])
    assert abs(err) < 3.0 * later.sigma_s_m


def test_train_moved_by_hand_is_covered_until_a_balise_places_it(loop):
    """A train lifted and set down 1.2 m further on: its wheel saw nothing, so the IPS disagrees with the filter, and
    nothing but a balise can say which is right (multipath looks the same). While they disagree the estimate covers
    both and the wheel's scale is held at the lowest a wheel can read; a balise read that agrees with the IPS places
    the train there."""
    profile = TrainProfile().with_changes(ips_outlier=0.0, rfid_miss=0.0)
    reports, truth = synthetic_run(loop, profile, seed=10, duration_s=30.0, target=lambda t_s: 0.3)
    est = UkfEstimator(loop, profile)
    feed(est, reports[:150])
    moved = []
    for r in reports[150:]:
        r = dict(r, tags=[])
        if r["ips"] is not None:
            t_ms, x_mm, y_mm = r["ips"]
            s_true = truth[round(controller_s(t_ms - 60) * 1000) // LOOP_MS, 1] + 1.2
            x, y = (float(c) for c in loop.xy(s_true))
            xi, yi = track_to_ips(x, y, loop.ips)
            r["ips"] = [t_ms, int(round(xi * 1000)), int(round(yi * 1000))]
        moved.append(r)
    feed(est, moved[:-1])
    t_s = controller_s(moved[-2]["t_ms"])
    now = est.estimate(t_s)
    s_true = truth[round(t_s * 1000) // LOOP_MS, 1] + 1.2
    assert est.counters()["relocations"] == 0 and est.counters()["disagreeing"]
    assert est.counters()["disagreements"] == 1
    assert along_error_m(loop, now.s_m, s_true) < -1.1                       # the filter keeps its wheel's position
    assert now.ahead_m >= -along_error_m(loop, now.s_m, s_true)   # and covers the IPS's; behind, the wheel's reach
    # over the 4.5 m since the last balise: with no fix taken the IPS does not watch the wheel, so at the prior band
    # (1 -+ 9 %), not only the one the balises vouched for (2 % long)
    assert now.behind_m < 0.3
    assert est.odometer_per_m_low(3.0) == 0.5
    # a balise (its position in its telegram) read where the IPS puts the train
    last = moved[-1]
    read_s = truth[round(controller_s(last["t_ms"]) * 1000) // LOOP_MS, 1] + 1.2 + profile.rfid_range_m
    data = balise.image(77, float(loop.wrap(read_s))).hex()
    feed(est, [dict(last, tags=[["0a0b0c0d", last["odo_mm"], last["t_ms"], 8, data]])])
    t_s = controller_s(last["t_ms"])
    assert est.counters()["relocations"] == 1 and not est.counters()["disagreeing"]
    placed = est.estimate(t_s)
    assert abs(along_error_m(loop, placed.s_m, truth[round(t_s * 1000) // LOOP_MS, 1] + 1.2)) < 0.03
    assert placed.ahead_m < 0.01 and placed.behind_m < 0.01   # (the wheel's reach from the balise: mm)


def test_ips_offset_is_covered_and_never_believed(loop):
    """Multipath puts every fix 0.5 m behind the train for 4 s: the filter keeps the wheel's position (within 3 cm or
    3 sigma of the truth throughout), the estimate covers the fixes' story while it lasts, and all is as before once
    it ends."""
    profile = TrainProfile().with_changes(ips_outlier=0.0, rfid_miss=0.0)
    reports, truth = synthetic_run(loop, profile, seed=12, duration_s=30.0, target=lambda t_s: 0.3)
    est = UkfEstimator(loop, profile)
    off = []
    for k, r in enumerate(reports):
        if 150 <= k < 190 and r["ips"] is not None:
            t_ms, _x, _y = r["ips"]
            s_off = truth[round(controller_s(t_ms - 60) * 1000) // LOOP_MS, 1] - 0.5
            xi, yi = track_to_ips(*(float(c) for c in loop.xy(s_off)), loop.ips)
            r = dict(r, ips=[t_ms, int(round(xi * 1000)), int(round(yi * 1000))])
        off.append(r)
    widest = 0.0
    clock = BoardClock()
    for r in off:
        feed(est, [r], clock)
        t_s = controller_s(r["t_ms"])
        now = est.estimate(t_s)
        if now is None:
            continue
        assert abs(along_error_m(loop, now.s_m, truth[round(t_s * 1000) // LOOP_MS, 1])) < max(0.03, 3 * now.sigma_s_m)
        if est.confirmed:   # before its first balise, the IPS placement's own bias is covered both ways
            widest = max(widest, now.behind_m)
            # the wheel's reach from the last balise: at the prior band (9 %) over the travel since it until
            # balises vouch for the wheel's scale, then at the band they vouch for (7 % over the first 0.9 m), or
            # the prior band again while the fixes are gated (no IPS watches the wheel)
            assert now.ahead_m < 0.1
    assert 0.45 < widest < 0.8
    assert est.counters()["disagreements"] >= 1 and not est.counters()["disagreeing"]
    assert est.estimate(controller_s(off[-1]["t_ms"])).behind_m < 0.01


# --- time: late and reordered data ------------------------------------------------------------------------------------

def test_late_ips_fix_is_applied_at_its_own_time(loop):
    """The same fix delivered in time and one second late (stamped with its sampling time) gives the same estimate."""
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    reports, _truth = synthetic_run(loop, profile, seed=11, duration_s=20.0)
    j = next(j for j in range(30, 60) if reports[j]["ips"] is not None)   # cruising at 0.5 m/s
    fix = reports[j]["ips"]
    in_time = [dict(r) for r in reports[:j + 12]]
    in_time[j + 10]["ips"] = None
    late = [dict(r) for r in in_time]
    late[j]["ips"] = None
    late[j + 10]["ips"] = fix                # 1 s late, still stamped with its own time
    stamped_late = [dict(r) for r in late]
    stamped_late[j + 10]["ips"] = [reports[j + 10]["t_ms"], fix[1], fix[2]]   # what ignoring its stamp would do
    without = [dict(r) for r in late]
    without[j + 10]["ips"] = None
    a, b, c, d = (UkfEstimator(loop, profile) for _ in range(4))
    for estimator, stream in ((a, in_time), (b, late), (c, stamped_late), (d, without)):
        feed(estimator, stream)
    t_s = controller_s(reports[j + 11]["t_ms"])
    ea, eb, _ = a.estimate(t_s), b.estimate(t_s), d.estimate(t_s)
    assert abs(ea.s_m - eb.s_m) < 1e-9 and abs(ea.sigma_s_m - eb.sigma_s_m) < 1e-12
    assert b.counters()["ips_used"] == d.counters()["ips_used"] + 1      # the late fix was used
    assert c.rejected_ips == b.rejected_ips + 1     # taken at its arrival it would sit 0.5 m behind: gated out


def test_reports_out_of_order_give_the_same_estimate(loop):
    profile = TrainProfile()
    reports, _truth = synthetic_run(loop, profile, seed=12, duration_s=20.0)
    shuffled = list(reports[:150])
    shuffled[100], shuffled[101] = shuffled[101], shuffled[100]
    shuffled[120], shuffled[123] = shuffled[123], shuffled[120]
    a, b = UkfEstimator(loop, profile), UkfEstimator(loop, profile)
    feed(a, reports[:150])
    feed(b, shuffled)
    t_s = controller_s(reports[149]["t_ms"])
    assert abs(a.estimate(t_s).s_m - b.estimate(t_s).s_m) < 1e-9


def test_measurement_older_than_the_history_is_dropped(loop):
    profile = TrainProfile()
    reports, _truth = synthetic_run(loop, profile, seed=13, duration_s=12.0)
    est = UkfEstimator(loop, profile, history_s=1.0)
    feed(est, reports[50:100])
    t_s = controller_s(reports[99]["t_ms"])
    before = est.estimate(t_s)
    feed(est, [reports[10]])
    assert est.late_measurements >= 1
    assert est.estimate(t_s) == before


# --- interface --------------------------------------------------------------------------------------------------------

def _standing_reports(layout, s_m, fixes_xy, t0_ms=BOARD_OFFSET_MS, period_ms=125):
    """Reports of a train standing at `s_m` (odometer 0), one IPS fix each from `fixes_xy` (layout frame, m)."""
    from cbtc.railway.ips_frame import track_to_ips

    reports = []
    for i, (x_m, y_m) in enumerate(fixes_xy):
        t_ms = t0_ms + i * period_ms
        xi, yi = track_to_ips(x_m, y_m, layout.ips)
        reports.append({"seq": i, "t_ms": t_ms, "odo_mm": 0, "v_mmps": 0, "duty": 0, "mode": "idle", "cseq": -1,
                        "ips": [t_ms, int(round(xi * 1000)), int(round(yi * 1000))], "tags": [], "flt": []})
    return reports


def test_not_localized_until_a_tag_or_enough_fixes_agree(loop):
    profile = TrainProfile()
    reports, _truth = synthetic_run(loop, profile, seed=14, duration_s=3.0)
    est = UkfEstimator(loop, profile)
    feed(est, [dict(r, ips=None, tags=[]) for r in reports])
    assert not est.localized and est.estimate(1.0) is None, "the encoder alone cannot place a train"
    x, y = (float(c) for c in loop.xy(1.0))
    est = UkfEstimator(loop, profile)
    standing = _standing_reports(loop, 1.0, [(x + 0.02, y), (x - 0.03, y), (x, y + 0.04)])
    feed(est, standing[:2])
    assert not est.localized, "two fixes are not enough"
    feed(est, standing[2:])
    assert est.localized and est.name == "ukf"
    placed = est.estimate(controller_s(standing[-1]["t_ms"]))
    assert abs(along_error_m(loop, placed.s_m, 1.0)) < 0.05


def test_an_outlier_as_the_first_fix_does_not_place_the_train(loop):
    """One IPS fix in a hundred is 0.3-1 m off. Placed by such a first fix, a train standing behind another could be
    put ahead of it and granted its whole gap: the train is placed only where three fixes agree."""
    profile = TrainProfile()
    x, y = (float(c) for c in loop.xy(1.0))
    ox, oy = (float(c) for c in loop.xy(1.7))                    # 0.7 m ahead along the track
    fixes = [(ox, oy), (x + 0.02, y - 0.01), (x - 0.01, y + 0.02), (x + 0.03, y)]
    est = UkfEstimator(loop, profile)
    standing = _standing_reports(loop, 1.0, fixes)
    feed(est, standing[:3])
    assert not est.localized, "the outlier and two good fixes: no three agree yet"
    feed(est, standing[3:])
    placed = est.estimate(controller_s(standing[-1]["t_ms"]))
    assert est.localized and abs(along_error_m(loop, placed.s_m, 1.0)) < 0.05, placed


def test_started_afresh_and_placed_by_the_ips_alone_the_estimate_covers_where_the_train_was_until_a_balise(loop):
    """The zone starts a train's estimator afresh when its encoder fails, telling it where the train was (keep_doubt):
    fixes that put it 0.8 m back may be the ones that are wrong, so the estimate placed by them reaches forward to
    the old span; a balise read that agrees with the fixes confirms them and the span goes."""
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    x, y = (float(c) for c in loop.xy(1.0))
    est = UkfEstimator(loop, profile)
    est.keep_doubt(1.75, 1.85)                     # where the train was: 0.8 m ahead of the fixes
    standing = _standing_reports(loop, 1.0, [(x + 0.01, y), (x - 0.01, y), (x, y + 0.01)])
    feed(est, standing)
    placed = est.estimate(controller_s(standing[-1]["t_ms"]))
    assert est.localized and abs(along_error_m(loop, placed.s_m, 1.0)) < 0.05
    assert placed.ahead_m >= 0.8 and placed.behind_m == pytest.approx(ukf_params.UkfParams().ips_bias_m, abs=0.01)
    est.keep_doubt(0.0, 3.0)                       # once located, a later call changes nothing
    last = standing[-1]
    data = balise.image(77, float(loop.wrap(1.0 + profile.rfid_range_m))).hex()
    feed(est, [dict(last, seq=last["seq"] + 1, t_ms=last["t_ms"] + 125,
                    tags=[["0a0b0c0d", 0, last["t_ms"] + 100, 0, data]])])
    confirmed = est.estimate(controller_s(last["t_ms"] + 125))
    assert confirmed.ahead_m < 0.01 and confirmed.behind_m < 0.01
    assert abs(along_error_m(loop, confirmed.s_m, 1.0)) < 0.05
    # placed by a balise, no span is kept: the balise is the arbiter (its own placement error is covered until a
    # second reference confirms it)
    tagged = UkfEstimator(loop, profile)
    tagged.keep_doubt(1.75, 1.85)
    feed(tagged, [dict(standing[0], ips=None, tags=[["0a0b0c0d", 0, standing[0]["t_ms"], 0, data]])])
    first = tagged.estimate(controller_s(standing[0]["t_ms"]))
    assert tagged.localized and first.ahead_m == pytest.approx(ukf_params.UkfParams().tag_bias_m, abs=0.01)
    assert first.behind_m == pytest.approx(ukf_params.UkfParams().tag_bias_m, abs=0.01)


@pytest.mark.parametrize("head_past_tag_m", [-0.015, 0.0, 0.015])
def test_a_train_booted_standing_over_a_tag_is_covered_wherever_in_the_field_it_stands(loop, head_past_tag_m):
    """A board that starts with its reader over a tag reads it at once, without driving into the field: its head is
    anywhere within the reader's range either side of the tag, and the estimate covers that (it placed the head
    1.5 cm behind the truth at 5 sigma, as if it had driven in)."""
    profile = TrainProfile()
    tag = loop.tags[3]
    s_m = tag.s_m + head_past_tag_m
    t_ms = BOARD_OFFSET_MS
    report = {"seq": 0, "t_ms": t_ms, "odo_mm": 0, "v_mmps": 0, "duty": 0, "mode": "idle", "cseq": -1, "ips": None,
              "tags": [[tag.uid, 0, t_ms, 0]], "flt": []}
    est = UkfEstimator(loop, profile)
    feed(est, [report])
    placed = est.estimate(controller_s(t_ms))
    assert est.localized and abs(along_error_m(loop, placed.s_m, s_m)) <= 3.0 * placed.sigma_s_m, placed


def test_a_roll_widens_the_estimate_by_all_it_rolled_not_in_quadrature(loop):
    """A standing train's board reports 100 steps of 2 mm as `roll` (motion of unknown sign): the train may be 0.2 m
    either way, so the estimate's sigma grows to at least that (steps added in quadrature gave 2 cm), and the
    odometer the filter sees does not move."""
    profile = TrainProfile()
    tag = loop.tags[2]
    t_ms = BOARD_OFFSET_MS
    reports = [{"seq": 0, "t_ms": t_ms, "odo_mm": 0, "v_mmps": 0, "duty": 0, "mode": "idle", "cseq": -1, "ips": None,
                "tags": [[tag.uid, 0, t_ms, 0]], "flt": []}]
    for k in range(1, 101):
        reports.append(dict(reports[0], seq=k, t_ms=t_ms + 50 * k, odo_mm=2 * k, tags=[], flt=["roll"]))
    est = UkfEstimator(loop, profile)
    feed(est, reports)
    placed = est.estimate(controller_s(reports[-1]["t_ms"]))
    assert placed.sigma_s_m >= 0.2 and abs(along_error_m(loop, placed.s_m, tag.s_m)) < 0.02, placed


def test_a_balise_read_the_filter_gates_is_covered_as_a_wheel_that_slipped(loop):
    """The wheel counts 0.15 m short between two balises: the second read is gated (the filter trusts its wheel),
    but the train may be where the balise says, so the estimate reaches that far ahead and the odometer scale the
    controller converts with falls to the lowest a wheel can read. A read metres off is another tag: not covered."""
    profile = TrainProfile()
    first, second = loop.tags[2], loop.tags[3]
    spacing_m = loop.ahead_m(first.s_m, second.s_m)
    t_ms = BOARD_OFFSET_MS
    base = {"seq": 0, "t_ms": t_ms, "odo_mm": 0, "v_mmps": 500, "duty": 70, "mode": "run", "cseq": -1, "ips": None,
            "tags": [[first.uid, 0, t_ms, 0]], "flt": []}
    reports = [base]
    odo_mm, k, target_mm = 0, 0, int((spacing_m - 0.15) * 1000)
    while odo_mm < target_mm:
        k += 1
        odo_mm = min(25 * k, target_mm)
        reports.append(dict(base, seq=k, t_ms=t_ms + 50 * k, odo_mm=odo_mm, tags=[]))
    reports[-1] = dict(reports[-1], tags=[[second.uid, odo_mm, reports[-1]["t_ms"], 8]])
    est = UkfEstimator(loop, profile)
    est.declare_position(first.s_m, 0.02)   # the first tag's placement confirmed by an operator's declaration
    feed(est, reports)
    now = est.estimate(controller_s(reports[-1]["t_ms"]))
    assert est.counters()["tags_rejected"] == 1 and 0.13 < now.ahead_m < 0.17, now
    assert est.odometer_per_m_low(3.0) == 0.5
    far = loop.tags[7]
    est = UkfEstimator(loop, profile)
    est.declare_position(first.s_m, 0.02)
    feed(est, reports[:-1] + [dict(reports[-1], tags=[[far.uid, odo_mm, reports[-1]["t_ms"], 8]])])
    now = est.estimate(controller_s(reports[-1]["t_ms"]))
    assert now.ahead_m < 0.05 and now.behind_m < 0.05 and est.odometer_per_m_low(3.0) > 0.9
    # placed by the first tag alone, a second one further off than that placement's bound (the tag's 3 cm) leaves
    # nothing to place the train: it is located afresh, not kept where one of the two tags put it
    est = UkfEstimator(loop, profile)
    feed(est, reports)
    assert not est.localized and est.estimate(controller_s(reports[-1]["t_ms"])) is None


def _cruise_reports(tag, counts_per_true_m):
    """A train placed on `tag` that runs at 0.5 m/s, reporting every 50 ms: its wheel counts `counts_per_true_m(k)`
    odometer m per true m over report k's travel."""
    t_ms = BOARD_OFFSET_MS
    base = {"seq": 0, "t_ms": t_ms, "odo_mm": 0, "v_mmps": 500, "duty": 70, "mode": "run", "cseq": -1, "ips": None,
            "tags": [[tag.uid, 0, t_ms, 0]], "flt": []}
    reports, odo_m = [base], 0.0
    for k in range(1, 121):
        scale = counts_per_true_m(k)
        odo_m += 0.025 * scale
        reports.append(dict(base, seq=k, t_ms=t_ms + 50 * k, odo_mm=int(odo_m * 1000), v_mmps=int(500 * scale),
                            tags=[]))
    return reports


def test_a_speed_step_no_train_can_make_reopens_the_wheel_scale(loop):
    """At 0.5 m/s the wheel starts to spin, counting 1.3 times the travel: the reported speed jumps by 0.14 m/s
    between two reports, five times what traction allows. The step is counted, the scale is open again (the
    controller converts with about the lowest a wheel reads) and the position widens with the travel, faster than a
    wheel that keeps its scale (no step) on dead reckoning alone."""
    profile = TrainProfile()
    tag = loop.tags[2]
    seen = {}
    for spin, steps in ((1.3, 1), (1.02, 0)):
        est = UkfEstimator(loop, profile)
        reports = _cruise_reports(tag, lambda k, spin=spin: spin if k >= 40 else 1.02)
        clock = feed(est, reports[:41])
        low = est.odometer_per_m_low(3.0)
        feed(est, reports[41:], clock)
        # the step, then the speed envelope again while nothing pins the scale (no IPS here): the wheel still spins
        assert (est.counters()["speed_steps"] >= 1) == (steps == 1), est.counters()["speed_steps"]
        seen[steps] = low, est.estimate(controller_s(reports[-1]["t_ms"])).sigma_s_m
    assert seen[1][0] < 0.6 and seen[0][0] > 0.9, seen
    assert seen[1][1] > 1.5 * seen[0][1], seen


@pytest.mark.parametrize("duty,mode,flt,steps", [(70, "run", [], 1), (0, "stop", [], 0), (70, "run", ["undriven"], 0)])
def test_a_driven_train_that_slows_faster_than_its_motor_drags_it_slides(loop, duty, mode, flt, steps):
    """The wheel starts to read 0.85 of the travel at 0.5 m/s: the speed falls 85 mm/s between two reports. Driven at
    70 % (the motor pulls it on, friction slows it 0.08 m/s^2) that is a slide; braking (1.4 m/s^2) it could be true,
    also when the board drives at both reports but braked at a pass in between (it names `undriven`)."""
    profile = TrainProfile()
    est = UkfEstimator(loop, profile)
    slid = _cruise_reports(loop.tags[2], lambda k: 0.85 if k >= 40 else 1.02)
    reports = [dict(r, duty=duty, mode=mode, flt=flt if k >= 40 else []) for k, r in enumerate(slid)]
    feed(est, reports[:45])
    assert est.counters()["speed_steps"] == steps


def test_a_slide_that_begins_between_two_reports_is_caught_over_both(loop):
    """The wheel starts to slide as a report is made: the speed measure shows the fall half in one interval and half
    in the next (510 -> 470 -> 435 mm/s), each under the tolerance beyond what the motor's drag allows. Over the
    two intervals together it is a slide; a wheel that keeps its scale shows none."""
    profile = TrainProfile()
    for scales, steps in (((0.94, 0.87), 1), ((1.02, 1.02), 0)):
        est = UkfEstimator(loop, profile)
        reports = _cruise_reports(loop.tags[2], lambda k, scales=scales: 1.02 if k < 40 else scales[k > 40])
        feed(est, reports[:43])
        assert est.counters()["speed_steps"] == steps, scales


def test_a_roll_reported_while_braking_from_speed_leaves_the_scale_alone(loop):
    """The board flags as a roll every count while braked, also braking from 0.5 m/s. Taken as a standing odometer
    while the filter's speed did not stand, that pulled an open scale (after a speed step) to -1; counts the train
    surely made forward are travel, and the rest holds it still: the scale stays within half its open sigma (0.15)
    of where it was."""
    profile = TrainProfile()
    tag = loop.tags[2]
    reports = _cruise_reports(tag, lambda k: 1.3 if k >= 40 else 1.02)[:45]
    last = reports[-1]
    for k in range(1, 11):
        reports.append(dict(last, seq=last["seq"] + k, t_ms=last["t_ms"] + 50 * k,
                            odo_mm=last["odo_mm"] + int(30 * k - 1.5 * k * k), v_mmps=max(0, 600 - 60 * k),
                            flt=["roll"], duty=0, mode="trip"))
    est = UkfEstimator(loop, profile)
    feed(est, reports)
    assert est.counters()["speed_steps"] == 1 and abs(est.scale_error - 0.02) < 0.075, est.scale_error


def test_counts_flagged_roll_that_a_train_braking_from_speed_surely_made_forward_are_travel(loop):
    """The board flags every count while braked as a roll, also a tripped train's braking from 0.5 m/s. A train
    cannot turn back before it stops, nor stop faster than the adhesion limit allows: counts made while it surely
    still went forward are travel (the position neither stands nor widens), and so is every count between two
    reports whose speeds it cannot have turned between. The rest, and counts after a standstill, still widen it."""
    profile = TrainProfile()
    cruise = _cruise_reports(loop.tags[2], lambda k: 1.0)[:40]
    last = cruise[-1]

    def then(*steps):
        est = UkfEstimator(loop, profile)
        reports, t_ms, odo_mm = list(cruise), last["t_ms"], last["odo_mm"]
        for k, (moved_mm, v_mmps, dt_ms) in enumerate(steps, 1):
            t_ms, odo_mm = t_ms + dt_ms, odo_mm + moved_mm
            reports.append(dict(last, seq=last["seq"] + k, t_ms=t_ms, odo_mm=odo_mm, v_mmps=v_mmps, flt=["roll"],
                                duty=0, mode="trip"))
        feed(est, reports)
        return est.estimate(controller_s(reports[-1]["t_ms"]))

    before = then()
    braking = then((12, 300, 40))                 # braking from 0.5 m/s to 0.3 m/s: forward
    slowing = then((12, 300, 40), (8, 150, 40))   # 0.3 to 0.15 m/s in 40 ms: it cannot have turned between
    beyond = then((12, 300, 40), (30, 0, 200))    # 30 mm in 0.2 s to a standstill: more than it surely went (6 mm)
    standing = then((12, 300, 40), (0, 0, 200), (4, 20, 40))   # a count after it stood: a roll
    assert braking.s_m - before.s_m == pytest.approx(0.012, abs=0.003)
    assert braking.sigma_s_m < before.sigma_s_m + 0.002
    assert slowing.s_m - braking.s_m == pytest.approx(0.008, abs=0.003) and slowing.v_mps > 0.1
    assert beyond.sigma_s_m > braking.sigma_s_m + 0.005
    assert standing.sigma_s_m > braking.sigma_s_m


def test_the_zone_bounds_braking_by_the_boards_adhesion_limit():
    assert wheel_watch.ADHESION_MPS2 * 1000 == obu._ADHESION_MMPS2


def test_a_train_located_after_an_encoder_fault_starts_with_its_scale_open(loop):
    """After the board named an encoder fault the wheel may read anything the band allows: the fresh estimator is
    told so, and the controller converts with the lowest a wheel reads until other sensors pin the scale."""
    seen = {}
    for distrust in (False, True):
        est = UkfEstimator(loop, TrainProfile())
        if distrust:
            est.distrust_wheel()
        feed(est, _cruise_reports(loop.tags[2], lambda k: 1.02)[:3])
        seen[distrust] = est.odometer_per_m_low(3.0)
    assert seen[False] > 0.9 and seen[True] < 0.7, seen


def test_unknown_setting_is_a_config_error(loop):
    with pytest.raises(ConfigError, match="accel_psd_m2ps3"):
        UkfEstimator(loop, TrainProfile(), accel_psd=1.0)
    with pytest.raises(ConfigError, match="gate_prob"):
        UkfEstimator(loop, TrainProfile(), gate_prob=1.5)


def test_seam_residual_takes_the_short_way(loop):
    residual = along_track_residual(loop)
    y = residual(np.array([0.01, 5.0]), np.array([loop.length_m - 0.01, 4.0]))
    assert y[0] == pytest.approx(0.02) and y[1] == pytest.approx(1.0)
    assert math.isclose(residual(np.array([loop.length_m - 0.01]), np.array([0.01]))[0], -0.02, abs_tol=1e-12)


# --- the paper's Table 1 ----------------------------------------------------------------------------------------------

def test_fusion_command_reproduces_the_papers_ordering(capsys):
    """Two laps of the paper scenario: dead reckoning > IPS > UKF enc+IPS (at most half of IPS) > UKF enc+IPS+RFID,
    the last within 1 cm along the track; the paper's numbers are printed beside ours."""
    assert main(["fusion", "--laps", "2", "--seed", "1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    rows = {row["method"]: row for row in result["rows"]}
    assert all(result["checks"].values()), result["checks"]
    assert (rows["ukf_enc_ips"]["paper_x_cm"], rows["ukf_enc_ips"]["paper_y_cm"]) == (13.2, 11.6)
    assert rows["ukf_enc_ips_rfid"]["along_cm"] <= 1.0
    assert set(rows["ips"]["trains"]) == {"A", "B"}
    # IPS alone must show the profile's noise: 5 cm per axis plus the 1 % outliers of 0.3-1 m
    assert 4.0 < rows["ips"]["x_cm"] < 10.0


def test_fusion_command_names_bad_input(capsys):
    assert main(["fusion", "--ips-sigma", "-1"]) == 2
    assert "--ips-sigma" in capsys.readouterr().err


@pytest.mark.parametrize("layout_name", ["itb_square", "straight_test"])
def test_filter_steps_equal_filterpy_reference(layout_name):
    """TrackUkf gives what filterpy's UnscentedKalmanFilter gives (ReferenceUkf), to 1e-9, on random runs of every
    step: predicts of random length, odometer, IPS fixes (some outliers, gated alike), balise reads (some in the
    field) and ranges, with and without the scale error in the state, on a loop and on a line."""
    from cbtc.estimation.reference_ukf import ReferenceUkf

    layout = load_layout(layout_name)
    rng = np.random.default_rng(7)
    noise = NoiseModel(0.01, 1e-4, 1e-6, 1e-6, 4e-4, 1e-4, 0.02, 0.999)
    worst, gated = 0.0, 0
    for n in (3, 4):
        for _ in range(8):
            A = rng.normal(size=(n, n))
            P0 = A @ A.T * 1e-3 + np.eye(n) * 1e-4
            x0 = [rng.uniform(0.3, layout.length_m - 0.3), rng.uniform(0, 0.6), rng.uniform(0, 5),
                  rng.normal(0, 0.02)][:n]
            ours, ref = TrackUkf(layout, noise, x0, P0, 0.0), ReferenceUkf(layout, noise, x0, P0, 0.0)
            t_s = 0.0
            for _ in range(30):
                t_s += rng.uniform(0.01, 0.1)
                ours.predict_to(t_s)
                ref.predict_to(t_s)
                d_m = ref.x[2] + rng.normal(0, 0.002)
                assert ours.update_odometer(d_m) and ref.update_odometer(d_m)
                px, py = layout.xy_m(ref.x[0] + rng.normal(0, 0.02))
                z = (px + rng.normal(0, 0.02) + (0.5 if rng.random() < 0.1 else 0.0), py + rng.normal(0, 0.02))
                used = ours.update_ips(*z)
                assert used == ref.update_ips(*z)
                gated += not used
                if rng.random() < 0.3:
                    tag_m = float(layout.wrap(ref.x[0] + rng.normal(0.02, 0.01)))
                    in_field, span_s = bool(rng.random() < 0.3), float(rng.uniform(0.0, 0.06))
                    assert ours.update_tag(tag_m, ref.x[2], in_field, span_s) == ref.update_tag(tag_m, ref.x[2],
                                                                                               in_field, span_s)
                if rng.random() < 0.3:
                    r_m = float(np.hypot(*(layout.xy(ref.x[0]) - (0.3, -0.2)))) + rng.normal(0, 0.02)
                    assert ours.update_range(0.3, -0.2, r_m, 0.03) == ref.update_range(0.3, -0.2, r_m, 0.03)
                worst = max(worst, float(np.max(np.abs(ours.x - ref.x))), float(np.max(np.abs(ours.P - ref.P))))
    assert worst < 1e-9
    assert gated > 0   # the gate was exercised, and agreed


def test_gates_are_chi_square_quantiles():
    from cbtc.estimation.ukf_model import gate_sigmas

    for p in (0.9, 0.99, 0.999, 0.9999):
        one, two = gate_sigmas(p)
        assert math.isclose(one, math.sqrt(chi2.ppf(p, 1)), rel_tol=1e-12)
        assert math.isclose(two, math.sqrt(chi2.ppf(p, 2)), rel_tol=1e-12)


def test_every_filter_setting_is_in_the_fusion_doc_with_its_default():
    """docs/fusion.md's settings table names every UkfParams field with the default the code has."""
    import dataclasses
    import pathlib
    import re

    from cbtc.estimation.ukf_params import UkfParams

    doc = (pathlib.Path(__file__).resolve().parents[1] / "docs" / "fusion.md").read_text()
    rows = {}
    for line in doc.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2:
            names = re.findall(r"`(\w+)`", cells[0])
            values = re.findall(r"[-\d.e]+", cells[1])
            if len(names) == len(values):
                rows.update(zip(names, values))
    for f in dataclasses.fields(UkfParams):
        assert f.name in rows, f"docs/fusion.md does not list {f.name}"
        assert math.isclose(float(rows[f.name]), f.default), (f.name, rows[f.name], f.default)


def test_a_tag_read_lands_anywhere_in_the_run_since_the_readers_previous_poll():
    """The head came `rfid_range_m` short of the tag somewhere in the run since the reader's previous poll (the
    read's span at the train's speed): uniformly there, whatever the board's loop pace; a read in the field at boot:
    either side."""
    noise = NoiseModel(accel_psd_m2ps3=0.02, slip_var_m2_per_m=2e-6, scale_var_per_m=0.0, odo_var_m2=1e-7,
                       ips_var_m2=0.05 ** 2, tag_var_m2=4e-6, rfid_range_m=0.015, gate_prob=0.999)
    assert tag_read_model(noise, 0.0) == (0.015, 4e-6)
    offset_m, var_m2 = tag_read_model(noise, 0.02)     # a 50 ms poll at 0.4 m/s: 20 mm of run
    assert offset_m == pytest.approx(0.005) and var_m2 == pytest.approx(4e-6 + 0.02 ** 2 / 12.0)
    assert tag_read_model(noise, 0.02, in_field=True) == (0.0, pytest.approx(4e-6 + 0.015 ** 2 / 3.0))


def test_the_reads_spans_of_a_virtual_train_cover_where_its_head_came_into_the_readers_field(loop):
    """Truth against the board's entries: at every read the head lies between the field's edge and the run at the
    train's speed over the read's span past it (the reader polled at every 20 ms pass)."""
    profile = TrainProfile().with_changes(rfid_miss=0.0)
    reports, truth = synthetic_run(loop, profile, 3, 30.0)
    tags = {tag.uid: tag.s_m for tag in loop.tags}
    checked = 0
    for report in reports:
        for uid, _odo_mm, t_ms, span_ms in report["tags"]:
            _t_s, head_m, v_mps = truth[round(controller_s(t_ms) * 1000) // LOOP_MS]
            past_edge_m = loop.ahead_m(tags[uid] - profile.rfid_range_m, head_m)
            assert -1e-6 <= past_edge_m <= v_mps * span_ms / 1000.0 + 1e-6, (uid, past_edge_m, span_ms)
            checked += 1
    assert checked >= 10
