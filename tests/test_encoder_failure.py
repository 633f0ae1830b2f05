"""A failed encoder stops the train: the OnboardUnit on the train's true physics (cbtc.railway.physics), at line speed
under a valid command, with its encoder failing in each way a real one does; truth decides."""

import pytest

from cbtc.firmware import obu
from cbtc.protocol import wire, wire_zc
from cbtc.railway import physics
from cbtc.railway.train_profile import TrainProfile
from fake_drivers import FakeIps, FakeMotor, FakeRfid

KEY = b"0123456789abcdef"
PASS_MS = 10


class FailingEncoder:
    """Counts the true travel (1 per mm) and times its edges, until it fails at `fail_at_mm` of true travel:
    `raise` (the bus is gone), `freeze` (the count stands), `burst` (200 spurious counts at once), `back` (the count
    drops by 20, which one channel cannot do, no faster than a train rolls), `half` (every second edge lost: it reads
    short)."""

    def __init__(self, way, fail_at_mm):
        self.way, self.fail_at_mm = way, fail_at_mm
        self.travel_mm = 0.0
        self.failed = False
        self.offset = 0
        self.age_us = 0
        self._count = 0

    def move(self, ds_mm, dt_ms, v_mmps):
        before = self._reading()
        self.travel_mm += ds_mm
        if not self.failed and self.travel_mm >= self.fail_at_mm:
            self.failed = True
            self.base_mm = self.travel_mm
            if self.way in ("burst", "back"):
                self.offset = 200 if self.way == "burst" else -20
        after = self._reading()
        if after != before and v_mmps > 0:
            frac_mm = (self.travel_mm - int(self.travel_mm)) if self.way != "half" else 0.0
            self.age_us = int(frac_mm / v_mmps * 1e6)
        else:
            self.age_us += dt_ms * 1000
        self._count = after

    def _reading(self):
        if not self.failed:
            return int(self.travel_mm)
        if self.way == "freeze":
            return int(self.base_mm)
        if self.way == "half":
            return int(self.base_mm) + int((self.travel_mm - self.base_mm) / 2)
        return int(self.travel_mm) + self.offset

    def count(self):
        if self.failed and self.way == "raise":
            raise OSError(5, "EIO")
        return self._count


def drive(way, fail_at_mm, eoa_mm=2000, seconds=6.0, start_v_mmps=0.0, stalls=(), later=()):
    """The unit drives a TrainProfile train from rest under one valid command (600 mm/s, eoa_mm, 10 s) and its encoder
    fails at `fail_at_mm`; its loop stands still over each (from_ms, to_ms) of `stalls` while the train runs on at the
    duty it was left with; each (at_ms, v_mmps, ahead_mm) of `later` is a new command then, at most `v_mmps`, its end
    of authority `ahead_mm` beyond the odometer. Returns (unit, true position mm, true speed, the largest true
    position, the reports)."""
    profile = TrainProfile()
    encoder = FailingEncoder(way, fail_at_mm)
    motor = FakeMotor()
    sent = []
    unit = obu.OnboardUnit("A", KEY, 9, encoder, FakeIps(), FakeRfid(), motor, lambda t, p: sent.append(p),
                           profile.obu_config())
    s_m, v_mps, now_ms = 0.0, start_v_mmps / 1000, 0
    unit.step(now_ms)
    report = wire_zc.decode_report(KEY, wire.topic_report("A"), sent[-1])
    unit.on_message(wire.topic_command("A"), wire_zc.encode_command(
        KEY, "A", 9, 1, 1, report["seq"], 600, eoa_mm, 10000, 600, 800), now_ms)
    furthest_mm = 0.0
    for _ in range(int(seconds * 1000 / PASS_MS)):
        now_ms += PASS_MS
        s_before = s_m
        s_m, v_mps, _a = physics.step(s_m, v_mps, motor.duty_pct, motor.mode, PASS_MS / 1000, profile)
        encoder.move((s_m - s_before) * 1000, PASS_MS, v_mps * 1000)
        if not any(start_ms <= now_ms < end_ms for start_ms, end_ms in stalls):
            unit.step(now_ms)
        for k, (at_ms, v_cap_mmps, ahead_mm) in enumerate(later):
            if at_ms == now_ms:
                report = wire_zc.decode_report(KEY, wire.topic_report("A"), sent[-1])
                unit.on_message(wire.topic_command("A"), wire_zc.encode_command(
                    KEY, "A", 9, 2 + k, 1, report["seq"], v_cap_mmps, unit.odo_mm + ahead_mm, 10000, 600, 800), now_ms)
        furthest_mm = max(furthest_mm, s_m * 1000)
    reports = [wire_zc.decode_report(KEY, wire.topic_report("A"), p) for p in sent]
    return unit, s_m * 1000, v_mps, furthest_mm, encoder, reports


def test_a_healthy_encoder_drives_to_the_end_of_authority_without_a_fault():
    unit, s_mm, v, furthest, _, reports = drive("none", fail_at_mm=1e9)
    assert 1900 < s_mm <= 2000 and v == 0 and unit.enc_fails == 0
    assert not any("enc_fail" in r["flt"] for r in reports)


@pytest.mark.parametrize("way", ["raise", "freeze", "burst", "back", "half"])
@pytest.mark.parametrize("fail_at_mm", [500, 900])
def test_an_encoder_failing_at_line_speed_trips_the_train_short_of_its_end_of_authority(way, fail_at_mm):
    """Failing at 0.5 m or 0.9 m, at 0.6 m/s, with the end of authority at 2 m: the train trips (emergency brake),
    stands short of the end of authority in truth, never above the command's speed by more than the trip margin,
    reports enc_fail, and has dropped its command, so it stays standing after the hold."""
    unit, s_mm, v, furthest, encoder, reports = drive(way, fail_at_mm)
    assert encoder.failed and unit.enc_fails >= 1
    assert v == 0 and furthest < 2000
    tripped = [r for r in reports if "enc_fail" in r["flt"]]
    assert tripped and tripped[0]["mode"] == "trip"
    assert reports[-1]["mode"] in ("stop", "trip") and reports[-1]["duty"] == 0
    assert unit.last_sensor_error.startswith("encoder: ")


@pytest.mark.parametrize("stall_ms", [300, 700, 1200])
def test_a_loop_that_stalls_does_not_take_its_healthy_encoder_for_failed(stall_ms):
    """A board's loop can stand still for a while (a WiFi reconnect, a long collection) while the motor keeps its
    duty: the pass after it integrates at most 0.1 s, so the reference does not run ahead of the train and trip the
    drive-ceiling or no-count checks (a 0.4-1.2 s stall tripped them); an encoder that freezes is still caught."""
    stalls = ((500, 500 + stall_ms), (2000, 2000 + stall_ms // 2))
    unit, s_mm, v, furthest, _, reports = drive("none", fail_at_mm=1e9, stalls=stalls)
    assert unit.enc_fails == 0 and not any("enc_fail" in r["flt"] for r in reports), unit.last_sensor_error
    assert v == 0 and furthest <= 2000
    unit, s_mm, v, furthest, _, reports = drive("freeze", fail_at_mm=900, stalls=stalls)
    assert unit.enc_fails >= 1 and v == 0 and furthest < 2000


def test_a_count_that_goes_back_trips_a_one_channel_board_and_commands_on_older_reports_are_refused():
    """The count drops 20 mm at 0.1 m of travel: the board trips, and a command the zone sealed on a report from
    before the glitch (its end of authority now 20 mm further from the odometer) is refused, not held."""
    unit, s_mm, v, furthest, _, reports = drive("back", fail_at_mm=100, seconds=1.0)
    assert unit.enc_fail_ms is not None and unit.last_sensor_error == "encoder: count went back"
    before = [r for r in reports if "enc_fail" not in r["flt"]][-1]
    command = wire_zc.encode_command(KEY, "A", 9, 1, 2, before["seq"], 600, 2000, 10000, 600, 800)
    unit.on_message(wire.topic_command("A"), command, unit._last_step_ms)
    assert not unit.command_valid(unit._last_step_ms) and "before the encoder failed" in unit.last_reject


def test_a_frozen_encoder_from_standstill_trips_within_the_slack_of_commanded_travel():
    unit, s_mm, v, furthest, _, reports = drive("freeze", fail_at_mm=0)
    assert unit.enc_fails >= 1 and v == 0
    # the reference asked for the slack (60 mm) and 3 counts; the train, about as far, then brakes from 0.28 m/s
    assert furthest < unit.cfg["enc_slack_mm"] + 40, furthest
    assert "no count in" in unit.last_sensor_error


def test_a_frozen_encoder_under_a_short_authority_trips_within_it():
    """Standing 30 mm short of its end of authority, the train starts on a count that stands still: the reference asks
    for the 30 mm left and 3 counts, not the full slack of 60 mm, before the board trips, and the train stops 46 mm
    on (90 mm with the full slack; within a zone's margin beyond the end of authority, not through it)."""
    unit, s_mm, v, furthest, _, reports = drive("freeze", fail_at_mm=0, eoa_mm=30)
    assert unit.enc_fails >= 1 and v == 0 and "no count in" in unit.last_sensor_error
    assert furthest < 30 + 3 + 20, furthest


def test_reference_travel_before_a_stop_is_not_carried_into_the_next_start():
    """A train braked to a stand holds no reference travel over from before it stopped: the next command, 4 mm of
    authority, does not find 7.8 mm "driven without a count" and trip the board (it did after controller restarts)."""
    unit, s_mm, v, furthest, _, reports = drive("none", fail_at_mm=1e9, eoa_mm=300, seconds=3.0)
    assert v == 0 and unit.enc_fails == 0
    unit._ref_mm = 7.8   # asked at creep speed while static friction held the train, just before it braked
    unit.step(unit._last_step_ms + PASS_MS)
    report = reports[-1]
    unit.on_message(wire.topic_command("A"), wire_zc.encode_command(
        KEY, "A", 9, 1, 2, report["seq"], 600, report["odo_mm"] + 4, 10000, 600, 800), unit._last_step_ms)
    for _ in range(19):
        unit.step(unit._last_step_ms + PASS_MS)
    assert unit.enc_fails == 0


def test_the_hold_ends_and_a_new_command_is_needed():
    unit, s_mm, v, furthest, _, reports = drive("burst", fail_at_mm=500, seconds=4.0)
    assert unit.enc_fail_ms is None and unit.mode == "stop"      # the hold is over; the old command was dropped
    assert "enc_fail" not in reports[-1]["flt"] and any("enc_fail" in r["flt"] for r in reports)


def test_the_zone_gives_a_train_with_a_failed_encoder_no_authority_until_it_is_located_again():
    """Two trains on the square loop; the leader's encoder bus fails for 0.5 s at line speed. Its board trips and holds;
    the controller forgets where it is, holds every train (no collision, no overrun), and lets the trains go again
    only once the leader reports healthy and a fresh estimator has located it."""
    from cbtc.layout_files import load_layout
    from cbtc.sim.simulation import Simulation
    from cbtc.zone.config import ScenarioConfig, TrainSpec

    layout = load_layout("itb_square")
    profile = TrainProfile()
    sim = Simulation(ScenarioConfig(layout=layout, seed=1, duration_s=30.0,
                                    trains=[TrainSpec("A", layout.wrap(1.5 + profile.length_m), (), profile),
                                            TrainSpec("B", 0.0, (), profile)]))
    sim.scheduler.run_until(10.0)
    leader = sim.trains[0]
    state = sim.zc.state_of("A")
    assert leader.v_mps > 0.3 and state.estimator.localized
    count = leader.encoder.count

    def broken():
        raise OSError(5, "EIO")

    leader.encoder.count = broken
    sim.scheduler.run_until(10.5)
    assert leader.obu.mode == "trip" and state.encoder_failed and not state.estimator.localized
    leader.encoder.count = count
    held = []
    sim.scheduler.call_every(0.05, lambda now: held.append((now, state.estimator.localized, sim.zc.state_of("B").eoa_mm,
                                                            sim.trains[1].v_mps)), start_s=10.5)
    sim.scheduler.run_until(30.0)
    summary = sim.recorder.summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    assert summary["encoder_trips"] == 1 and state.encoder_failures == 1
    located_at = next(t for t, located, _, _ in held if located)
    assert located_at > 12.5, "healthy only after the board's 2 s hold"
    assert min(v for t, _, _, v in held if t < located_at) == 0.0, "the follower was held meanwhile"
    assert leader.travelled_m > 0 and leader.v_mps > 0.2, "the leader runs again once located"


@pytest.mark.parametrize("ahead_mm", [0, -2, -20])
def test_a_train_braked_to_a_stop_is_not_taken_for_a_failed_encoder_when_its_authority_steps_back(ahead_mm):
    """Asked to stop from line speed, the speed loop brakes the train harder than the reference slows, so the train
    stands before the reference does; the travel the reference asks meanwhile is not driven. A command whose end of
    authority then lies at or behind the train (its estimate moved) leaves no slack: that travel counted as driven
    tripped the no-count check of a healthy encoder (3 of 50 trains in a packed queue, 30 s)."""
    # stopping from 0.6 m/s at 1.5 s, the train stands from 2.18 s, the reference from 2.26 s
    unit, s_mm, v, furthest, _, reports = drive("none", fail_at_mm=1e9, seconds=3.0,
                                                later=[(1500, 0, 1000), (2200, 0, ahead_mm)])
    assert unit.enc_fails == 0 and not any("enc_fail" in r["flt"] for r in reports), unit.last_sensor_error
    assert v == 0
