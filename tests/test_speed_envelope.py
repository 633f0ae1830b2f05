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
    """The speed measure lags the motor: a duty cut from 74 % to 21 % shows in the speed a report late. The band
    takes the duty of the report before as well, so the late fall is not taken for a wheel that reads long."""
    p = TrainProfile()
    env = SpeedEnvelope(p, motor_tol=0.1, window_s=1.0)
    reports = [(0.00, 0.317, 66), (0.04, 0.341, 69), (0.10, 0.371, 74), (0.14, 0.391, 21), (0.20, 0.374, 21),
               (0.24, 0.359, 17), (0.30, 0.330, 17)]
    worst = [env.observe(t, v, d) for t, v, d in reports]
    assert max(w[0] for w in worst if w is not None) < 0.04, worst
