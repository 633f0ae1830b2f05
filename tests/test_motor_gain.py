"""The motor's gain learnt while a train is driven, and the speed envelope that narrows with it (pure)."""

import pytest

from cbtc.estimation.motor_gain import MotorGain
from cbtc.estimation.speed_envelope import SpeedEnvelope
from cbtc.railway.physics import acceleration_mps2
from cbtc.railway.train_profile import TrainProfile

PROFILE = TrainProfile()


def _drive(gain, v_target_mps, seconds, scale=lambda t: 1.0, settled=True, learner=None, envelope=None, t0_s=0.0,
           v0_mps=0.0):
    """A train whose motor gives `gain` times the profile's no-load speed, held at `v_target_mps` by a speed loop that
    knows only the profile (a pass every 10 ms), its wheel reading `scale(t)` times the truth; every 50 ms a report
    (mean duty of its passes, measured speed) goes to `learner` and `envelope`. Returns (learner, envelope, worst
    envelope excess beyond the drift tolerance, the true speed at the end)."""
    truth = PROFILE.with_changes(v_noload_mps=PROFILE.v_noload_mps * gain)
    learner = learner or MotorGain(PROFILE, 0.10, 0.04, 10.0, 3.0)
    v, duties, worst = v0_mps, [], -1.0
    for k in range(1, int(seconds / 0.01) + 1):
        t = t0_s + k * 0.01
        v_read = v * scale(t)
        duty = max(1, min(100, round(100 * (v_target_mps + 0.02) / PROFILE.v_noload_mps
                                     + 400 * (v_target_mps - v_read))))
        duties.append(duty)
        for _ in range(10):
            v = max(0.0, v + acceleration_mps2(v, duty, "drive", truth) * 0.001)
        if k % 5 == 0:
            mean_duty = sum(duties) // len(duties)
            duties = []
            learner.observe(t, v * scale(t), mean_duty, settled)
            if envelope is not None:
                envelope.set_motor(learner.gain, learner.tol)
                found = envelope.observe(t, v * scale(t), mean_duty)
                if found is not None:
                    worst = max(worst, found[0] - (0.02 + 0.03 * v * scale(t)))
    return learner, envelope, worst, v


@pytest.mark.parametrize("gain", [0.9, 1.0, 1.08])
def test_a_motor_off_the_profile_is_learnt_to_a_percent(gain):
    learner = _drive(gain, 0.45, 12.0)[0]
    assert learner.gain == pytest.approx(gain, abs=0.015)
    assert learner.tol == 0.04 and learner.learnt_s >= 3.0


def test_nothing_is_learnt_at_the_traction_limit_unsettled_or_slow():
    """A start at full duty rides the traction limit, where the motor's law does not hold; a wheel whose scale is not
    settled says nothing of the motor; below 0.15 m/s neither does the speed measure."""
    start = MotorGain(PROFILE, 0.10, 0.04, 10.0, 3.0)
    v = 0.0
    for k in range(1, 16):
        for _ in range(50):
            v += acceleration_mps2(v, 100, "drive", PROFILE) * 0.001
        start.observe(k * 0.05, v, 100, True)
    assert start.learnt_s == 0.0 and start.gain == 1.0 and start.tol == 0.10
    assert _drive(0.9, 0.45, 6.0, settled=False)[0].learnt_s == 0.0
    assert _drive(0.9, 0.1, 6.0)[0].learnt_s == 0.0


def test_a_window_that_caught_a_spin_does_not_move_the_gain_and_reset_forgets():
    learner = _drive(1.0, 0.45, 6.0)[0]
    _drive(1.0, 0.45, 1.2, scale=lambda t: 1.12, learner=learner, t0_s=6.0, v0_mps=0.45)
    _drive(1.0, 0.45, 2.0, learner=learner, t0_s=7.2, v0_mps=0.45 / 1.12)
    assert learner.gain == pytest.approx(1.0, abs=0.015)
    learner.reset()
    assert learner.gain == 1.0 and learner.learnt_s == 0.0 and learner.tol == 0.10


def test_a_wheel_that_begins_to_spin_at_cruise_is_seen_only_by_the_learnt_band():
    """At 0.45 m/s a wheel that begins to read 1.15x within a second stays inside the profile's 10 % band (plus the
    drift tolerance) and leaves the learnt one."""
    def spin(t):
        return 1.0 + 0.15 * min(1.0, max(0.0, t - 8.0))

    learner = _drive(1.0, 0.45, 8.0)[0]
    worst_learnt = _drive(1.0, 0.45, 3.0, scale=spin, learner=learner, envelope=SpeedEnvelope(PROFILE, 0.10, 1.0),
                          t0_s=8.0, v0_mps=0.45)[2]
    profile_only = MotorGain(PROFILE, 0.10, 0.10, 10.0, 3.0)
    worst_profile = _drive(1.0, 0.45, 3.0, scale=spin, learner=profile_only,
                           envelope=SpeedEnvelope(PROFILE, 0.10, 1.0), t0_s=8.0, v0_mps=0.45)[2]
    assert worst_learnt > 0.0 > worst_profile, (worst_learnt, worst_profile)


def test_a_window_begins_at_the_first_usable_report_and_means_the_speed_by_the_trapezoid():
    """A train speeding up under a steady duty (the exact first-order motor), its scale settled from the second
    report on: the window begins at that report, not with the interval before it, and the speed's mean over each
    interval is the trapezoid's, so one window gives the motor's gain to 0.1 % (both half-measures were 0.4 % off,
    either way)."""
    import math
    gain, duty_pct, v0_mps = 1.05, 60, 0.36
    v_ss_mps = duty_pct / 100.0 * PROFILE.v_noload_mps * gain - PROFILE.friction_mps2 * PROFILE.motor_tau_s
    learner = MotorGain(PROFILE, 0.10, 0.04, 10.0, 3.0)
    for k in range(30):
        t_s = 0.05 * k
        v_mps = v_ss_mps + (v0_mps - v_ss_mps) * math.exp(-t_s / PROFILE.motor_tau_s)
        learner.observe(t_s, v_mps, duty_pct, k > 0)
    assert learner.learnt_s == 1.0
    assert learner.gain == pytest.approx(gain, rel=1e-3)


def test_a_stop_keeps_the_motor_learnt():
    """A lone train on itb_square learns its motor between stations; the counts its board flags `roll` while braking
    to a stand at each one tell nothing of the motor and must not make it forget (on the code that reset it there,
    the 2 s learnt by 8 s went back to 0, and a wheel that began to spin 12 % after a stop went unseen)."""
    from cbtc.sim.runs import sim_config
    from cbtc.sim.simulation import Simulation

    sim = Simulation(sim_config("itb_square", 1, 0, 20.0))
    learnt = []
    for t_s in range(1, 21):
        sim.scheduler.run_until(float(t_s))
        learnt.append(sim.zc.state_of("T1").estimator.counters()["motor_learnt_s"])
    assert learnt[-1] >= 3.0 and all(b >= a for a, b in zip(learnt, learnt[1:])), learnt


# a train on lego_branch (seed 1, T1) driven off a stand, braked for a switch not yet detected, driven on again:
# (board time s, speed m/s as the filter read the wheel, mean duty %) of its reports
_BRAKE_AND_GO = [
    (0.0, 0.0, 22), (0.02, 0.0, 25), (0.04, 0.0, 27), (0.06, 0.0, 30), (0.08, 0.02962, 30), (0.1, 0.04542, 31),
    (0.12, 0.06221, 32), (0.14, 0.06517, 35), (0.16, 0.0859, 35), (0.18, 0.09281, 38), (0.2, 0.10455, 39),
    (0.22, 0.1223, 40), (0.24, 0.13512, 42), (0.26, 0.14103, 44), (0.28, 0.15385, 45), (0.3, 0.17555, 46),
    (0.32, 0.1795, 48), (0.34, 0.19348, 50), (0.36, 0.20927, 51), (0.38, 0.2142, 53), (0.4, 0.23493, 54),
    (0.42, 0.24085, 56), (0.44, 0.24875, 58), (0.46, 0.2664, 59), (0.48, 0.27429, 61), (0.5, 0.28712, 63),
    (0.52, 0.29699, 65), (0.54, 0.31672, 65), (0.56, 0.32658, 67), (0.58, 0.33238, 18), (0.6, 0.3383, 13),
    (0.62, 0.31956, 11), (0.64, 0.30871, 8), (0.66, 0.28898, 7), (0.68, 0.26334, 6), (0.7, 0.24066, 4),
    (0.72, 0.23376, 1), (0.74, 0.21699, 0), (0.76, 0.18542, 0), (0.78, 0.17358, 0), (0.8, 0.12723, 0),
    (0.82, 0.1144, 46), (0.84, 0.09427, 51), (0.86, 0.0992, 54), (0.88, 0.10411, 57), (0.9, 0.11786, 59),
    (0.92, 0.13357, 60), (0.94, 0.14634, 62), (0.96, 0.16009, 63), (0.98, 0.16402, 66), (1.0, 0.18071, 67),
    (1.02, 0.18857, 69), (1.04, 0.20134, 71), (1.06, 0.22393, 61), (1.08, 0.20863, 66), (1.1, 0.23058, 67),
    (1.12, 0.22983, 68), (1.14, 0.23935, 69), (1.16, 0.25213, 70), (1.18, 0.26941, 70), (1.2, 0.27288, 72),
    (1.22, 0.28227, 73), (1.24, 0.29926, 73), (1.28, 0.31374, 76)]


def test_a_train_braked_hard_and_driven_on_again_is_no_wheel_that_slides():
    """Its speed measure lags: braking it read above the train, driven on again below; a band anchored on a lagging
    reading opens by the change over the lag, or the wheel of a train that only braked and went on would be taken to
    slide and its scale opened (the train then stood short of the tag that would have closed it, for good)."""
    envelope = SpeedEnvelope(PROFILE, 0.10, 1.0)
    envelope.set_motor(1.0039, 0.10)
    worst = -1.0
    for t_s, v_mps, duty_pct in _BRAKE_AND_GO:
        found = envelope.observe(t_s, v_mps, duty_pct)
        if found is not None:
            worst = max(worst, found[0] - (0.02 + 0.03 * v_mps))
    assert worst < 0.0, worst
