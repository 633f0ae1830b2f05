"""Physics against closed-form results, the scheduler's ordering, and the OnboardUnit's speed loop on the plant."""

import math

import numpy as np
import pytest

from cbtc.bus.mock_broker import MockBroker
from cbtc.errors import ConfigError
from cbtc.layout_files import load_layout
from cbtc.protocol import wire, wire_zc
from cbtc.railway import physics
from cbtc.railway.train_profile import TrainProfile
from cbtc.scheduler import VirtualScheduler
from cbtc.sim.virtual_train import VirtualTrain

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
        report = wire_zc.decode_report(key, topic, payload)
        seq[0] += 1
        ctl.publish(wire.topic_command("A"), wire_zc.encode_command(key, "A", report["boot"], seq[0], 1, report["seq"],
                                                                 400, 5000, 800, 600, 800))
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


def test_the_speed_loop_rides_the_service_curve_to_a_standstill_without_tripping():
    """On the plant: a train at line speed is given an end of authority 0.5 m ahead. At low speed the motor's own drag
    (v / tau) is less than the service rate, so the loop shorts the windings when it needs more braking; it follows
    the curve to the stop window's edge and never trips the emergency brake."""
    sched = VirtualScheduler()
    broker = MockBroker(sched)
    key = b"k" * 16
    train = VirtualTrain("A", key, load_layout("itb_square"), P, 0.0, broker.connect("train"),
                         np.random.default_rng(1))
    ctl = broker.connect("ctl")
    state = {"seq": 0, "eoa_mm": 6_000}
    modes = []

    def answer(topic, payload):
        report = wire_zc.decode_report(key, topic, payload)
        state["seq"] += 1
        ctl.publish(wire.topic_command("A"), wire_zc.encode_command(key, "A", report["boot"], state["seq"], 1,
                                                                 report["seq"], 600, state["eoa_mm"], 800, 600, 800))
    ctl.subscribe(wire.topic_report("A"), answer)
    sched.call_every(0.02, train.tick)
    over = []   # how far the train's speed (odometer units, as the board sees distance) is above its service curve

    def watch(now):
        modes.append((train.motor.mode, train.motor.duty_pct))
        odo_per_m = train.encoder.distance_m / max(train.travelled_m, 1e-9)
        over.append(train.v_mps * odo_per_m * 1000 - train.obu.braking_curve_mmps(train.obu.cfg["dec_mmps2"]))
    sched.call_every(0.02, watch, start_s=0.011)
    sched.run_until(5.0)
    assert train.v_mps > 0.55
    state["eoa_mm"] = train.obu.odo_mm + 500
    sched.run_until(9.0)
    unit = train.obu
    assert train.v_mps == 0.0 and unit.trips == 0
    window = unit.cfg["stop_window_mm"]
    assert state["eoa_mm"] - window - 6 <= unit.odo_mm <= state["eoa_mm"] - window + 1
    assert "brake" in [mode for mode, _ in modes[250:400]], "more braking than the drag: the short-circuit brake"
    assert max(over[250:]) < 25.0, "it follows the service curve down to the stop (mm/s above it)"
    assert all(duty >= 0 for _, duty in modes), "never a negative (reversing) duty"
