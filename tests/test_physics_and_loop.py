"""Physics against closed-form results, the scheduler's ordering, and the OnboardUnit's speed loop on the plant."""

import math

import numpy as np
import pytest

from cbtc import physics
from cbtc.firmware_modules import wire
from cbtc.layout import load_layout
from cbtc.mock_broker import MockBroker
from cbtc.scheduler import VirtualScheduler
from cbtc.train_profile import TrainProfile
from cbtc.virtual_train import VirtualTrain
from cbtc.errors import ConfigError

P = TrainProfile()


def integrate(v0, duty, mode, seconds, dt=0.001, p=P):
    s, v = 0.0, v0
    for _ in range(int(seconds / dt)):
        s, v, _a = physics.step(s, v, duty, mode, dt, p)
    return s, v


def test_brake_stops_in_the_emergency_braking_distance():
    s, v = integrate(0.6, 0, "brake", 2.0)
    assert v == 0.0
    assert s == pytest.approx(physics.braking_distance_m(0.6, P.beta_e_mps2), rel=1e-3)


def test_coasting_decelerates_by_friction_only():
    s, v = integrate(0.5, 0, "coast", 1.0)
    assert v == pytest.approx(0.5 - P.friction_mps2 * 1.0, abs=1e-6)


def test_steady_speed_at_a_duty_is_the_first_order_equilibrium():
    # (d/100 * v_nl - v)/tau = friction  ->  v = d/100 * v_nl - tau * friction
    _, v = integrate(0.0, 60, "drive", 8.0)
    assert v == pytest.approx(0.6 * P.v_noload_mps - P.motor_tau_s * P.friction_mps2, abs=1e-3)


def test_acceleration_is_limited_by_adhesion():
    assert physics.acceleration_mps2(0.0, 100, "drive", P) == pytest.approx(P.accel_max_mps2)


def test_profile_rejects_nonsense_with_the_field_named():
    with pytest.raises(ConfigError, match="beta_s_mps2"):
        TrainProfile(beta_s_mps2=-1)
    with pytest.raises(ConfigError, match="v_max_mps"):
        TrainProfile(v_max_mps=2.0)
    with pytest.raises(ConfigError, match="unknown keys"):
        P.with_changes(top_speed=1)


def test_scheduler_runs_in_time_order_and_breaks_ties_by_insertion():
    sched = VirtualScheduler()
    seen = []
    sched.call_at(0.2, seen.append, "b")
    sched.call_at(0.1, seen.append, "a")
    sched.call_at(0.2, seen.append, "c")
    ticks = []
    handle = sched.call_every(0.05, ticks.append)
    sched.run_until(0.2)
    handle.cancel()
    sched.run_until(1.0)
    assert seen == ["a", "b", "c"]
    assert ticks == pytest.approx([0.0, 0.05, 0.1, 0.15, 0.2])


def test_onboard_speed_loop_tracks_the_commanded_speed_on_the_plant():
    """The firmware's OnboardUnit on the physics model: it reaches the commanded speed and holds it within 3 %."""
    sched = VirtualScheduler()
    broker = MockBroker(sched)
    layout = load_layout("itb_square")
    key = b"k" * 16
    train = VirtualTrain("A", key, layout, P, 0.0, broker.connect("train"), np.random.default_rng(0))
    ctl = broker.connect("ctl")
    seq = [0]
    speeds = []

    def answer(topic, payload):
        report = wire.decode_report(key, topic, payload)
        seq[0] += 1
        ctl.publish(wire.topic_command("A"), wire.encode_command(key, "A", seq[0], 1, report["seq"], 400,
                                                                 5000, 800, 600, 800))
    ctl.subscribe(wire.topic_report("A"), answer)
    sched.call_every(0.02, train.tick)
    sched.call_every(0.1, lambda now: speeds.append(train.v_mps), start_s=0.01)
    sched.run_until(6.0)
    held = np.asarray(speeds[30:50])
    assert held.mean() == pytest.approx(0.4, rel=0.03)
    assert np.abs(held - 0.4).max() < 0.03
    sched.run_until(25.0)
    assert train.v_mps == 0.0, "it stops at its end of authority"
    assert train.obu.odo_mm <= train.obu.eoa_mm
    assert math.isfinite(train.travelled_m)
