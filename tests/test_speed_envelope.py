"""The speed envelope: reported speeds held to what traction, the motor and the brake allow (pure)."""

import math

import pytest

from cbtc.estimation.speed_envelope import SpeedEnvelope, ride_mps
from cbtc.railway.physics import acceleration_mps2
from cbtc.railway.train_profile import TrainProfile


@pytest.mark.parametrize("v0,v_ss,up,down", [(0.0, 0.6, 0.6, 1.4), (0.5, 0.1, 0.6, 1.4), (0.5, 0.1, 0.6, 0.5),
                                             (0.2, 0.3, 0.6, 1.4)])
def test_ride_is_the_clamped_first_order_motor(v0, v_ss, up, down):
    """The closed form equals a fine Euler integration of dv/dt = clamp((v_ss - v) / tau, -down, up)."""
    tau, v, dt = 0.25, v0, 1e-5
    for _ in range(int(0.8 / dt)):
        v += max(-down, min(up, (v_ss - v) / tau)) * dt
    assert math.isclose(ride_mps(v0, 0.8, v_ss, tau, up, down), v, abs_tol=1e-4)


def _start(scale, duty_pct=90, seconds=1.5, period_s=0.05):
    """A train started from a stand at `duty_pct` under the profile's own physics, its speed read `scale` times the
    truth every `period_s`: what the envelope returns at each report."""
    p = TrainProfile()
    env = SpeedEnvelope(p, motor_tol=0.1, window_s=1.0)
    v, found = 0.0, []
    for k in range(1, int(seconds / period_s) + 1):
        for _ in range(10):
            v = max(0.0, v + acceleration_mps2(v, duty_pct, "drive", p) * period_s / 10)
        found.append(env.observe(k * period_s, v * scale, duty_pct))
    return [f for f in found if f is not None]


def test_a_true_start_stays_inside_the_envelope():
    assert max(f[0] for f in _start(1.0)) < 1e-9


@pytest.mark.parametrize("scale", [1.4, 0.72])
def test_a_wheel_that_spins_or_slides_through_a_start_leaves_it(scale):
    """Traction-limited at 0.6 m/s^2: a wheel reading 1.4x shows 0.84 m/s^2, one reading 0.72x shows 0.43 m/s^2
    while the motor at 90 % cannot give less than 0.54: both leave the band by more than 0.04 m/s within a second."""
    assert max(f[0] for f in _start(scale)) > 0.04


def test_a_duty_cut_between_reports_is_not_a_slide():
    """A loop riding behind a moving limit brakes for a pass: the report of that interval gives its mean duty (21 %),
    the next one 72 %; the speed measure lags the motor, so the band takes the duty of the report before as well
    (fast reports of a lego_oval run)."""
    p = TrainProfile()
    env = SpeedEnvelope(p, motor_tol=0.1, window_s=1.0)
    reports = [(0.0, 0.361, 62), (0.02, 0.368, 59), (0.04, 0.368, 67), (0.06, 0.38, 21), (0.08, 0.371, 72),
               (0.1, 0.368, 75), (0.12, 0.383, 76), (0.14, 0.389, 79), (0.16, 0.399, 80), (0.18, 0.427, 70),
               (0.2, 0.428, 73), (0.22, 0.441, 70), (0.24, 0.441, 68), (0.26, 0.447, 71), (0.28, 0.453, 71),
               (0.3, 0.456, 69), (0.32, 0.459, 76)]
    worst = [env.observe(t, v, d) for t, v, d in reports]
    assert max(w[0] for w in worst if w is not None) < 0.0, worst


def _start_from_a_stand(scale, duty_pct, lag_s):
    """A train braked and standing for three reports, then started at `duty_pct`, its speed read `scale` times the
    truth of `lag_s` before (the speed measure lags a start): the largest departure from a band the envelope
    returns."""
    p = TrainProfile()
    env = SpeedEnvelope(p, motor_tol=0.1, window_s=1.0)
    t_s, v, history, found = 0.0, 0.0, [], []
    for _ in range(3):
        env.observe(t_s, 0.0, 0)
        t_s += 0.05
    for _ in range(30):
        for _ in range(50):
            v = max(0.0, v + acceleration_mps2(v, duty_pct, "drive", p) * 0.001)
            history.append(v)
        t_s += 0.05
        found.append(env.observe(t_s, history[max(0, len(history) - 1 - int(lag_s * 1000))] * scale, duty_pct))
    return max(f[0] for f in found if f is not None)


@pytest.mark.parametrize("duty_pct", [40, 90])
def test_a_start_from_a_stand_whose_speed_measure_lags_is_no_slide(duty_pct):
    """A train braked at a stand anchors the fastest it can go from there: a healthy start whose speed measure lags
    60 ms stays inside every band."""
    assert _start_from_a_stand(1.0, duty_pct, lag_s=0.06) < 1e-9


def test_a_wheel_that_spins_as_a_standing_train_starts_leaves_the_band_from_the_stand():
    """Traction-limited at 0.6 m/s^2 from the stand: a wheel reading 1.25x shows 0.75 m/s^2 and leaves the band."""
    assert _start_from_a_stand(1.25, 90, lag_s=0.03) > 0.05
