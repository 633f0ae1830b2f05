"""The OnboardUnit's safety behaviour with scripted drivers: no authority no motion, watchdog, replay, staleness,
trip."""

import pytest

from cbtc.firmware import obu
from cbtc.protocol import wire, wire_zc
from cbtc.railway import train_profile
from cbtc.railway.train_profile import TrainProfile
from fake_drivers import (
    BrokenSensor,
    FakeEncoder,
    FakeIps,
    FakeMotor,
    FakeRfid,
    TimedEncoder,
)

KEY = b"0123456789abcdef"
CMD = "cbtc/train/A/cmd"


class Bench:
    def __init__(self, boot_id=9, **drivers):
        self.sent = []
        self.enc = drivers.get("encoder", FakeEncoder())
        self.motor = FakeMotor()
        self.unit = obu.OnboardUnit("A", KEY, boot_id, self.enc, drivers.get("ips", FakeIps()),
                                    drivers.get("rfid", FakeRfid()), self.motor,
                                    lambda topic, payload: self.sent.append((topic, payload)), {"counts_per_m": 1000})
        self.now_ms = 0
        self.cmd_seq = 0
        self._travel_mm = 0.0

    def step(self, ms=20, v_mmps=None):
        """Advance board time; optionally move the train at v_mmps (the encoder counts 1 per mm; one that times its
        edges is told how long ago the newest one came)."""
        self.now_ms += ms
        timed = isinstance(self.enc, TimedEncoder)
        if timed:
            self.enc.age_us += ms * 1000
        if v_mmps:
            self._travel_mm += v_mmps * ms / 1000.0   # whole counts of the distance travelled, fractions kept
            if int(self._travel_mm) != self.enc.counts and timed:
                self.enc.age_us = int((self._travel_mm - int(self._travel_mm)) / v_mmps * 1e6)
            self.enc.counts = int(self._travel_mm)
        self.unit.step(self.now_ms)

    def last_report(self):
        return wire_zc.decode_report(KEY, self.sent[-1][0], self.sent[-1][1])

    def reported_tags(self):
        """Every tag entry of every report sent so far, in order."""
        return [tag for topic, payload in self.sent for tag in wire_zc.decode_report(KEY, topic, payload)["tags"]]

    def command(self, v_mmps=500, eoa_mm=5000, ttl_ms=800, sid=1, seq=None, rseq=None, key=KEY, stop_mm=None,
                rpt_ms=0, odo_mm_per_m=1000):
        if seq is None:
            self.cmd_seq += 1
            seq = self.cmd_seq
        rseq = self.last_report()["seq"] if rseq is None else rseq
        payload = wire_zc.encode_command(key, "A", self.unit.boot_id, seq, sid, rseq, v_mmps, eoa_mm, ttl_ms, 600, 800,
                                      stop_mm, rpt_ms, odo_mm_per_m)
        self.unit.on_message(CMD, payload, self.now_ms)
        return payload


def test_no_command_means_no_motion():
    bench = Bench()
    for _ in range(50):
        bench.step()
    assert bench.motor.mode == "brake"
    assert bench.last_report()["mode"] == "idle"


def test_a_valid_command_drives_and_expiry_brakes_to_a_stop():
    bench = Bench()
    bench.step()
    bench.command()
    bench.step()
    assert bench.motor.mode == "drive" and bench.motor.duty_pct > 0
    assert bench.unit.mode == "run"
    # run for a while, renewing the command each report, then stop sending
    for _ in range(50):
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
        if bench.now_ms % 100 == 0:
            bench.command()
    assert bench.unit.v_ref_mmps > 300
    expiry = bench.unit.cmd_expiry_ms
    while bench.now_ms < expiry:
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    refs = []
    for _ in range(60):
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
        refs.append(bench.unit.v_ref_mmps)
    assert bench.unit.mode == "stop"
    assert all(b <= a for a, b in zip(refs, refs[1:])), "the speed reference only falls after expiry"
    assert refs[-1] == 0 and bench.motor.mode == "brake"
    assert "cmd_timeout" in bench.last_report()["flt"]


def test_forged_replayed_and_stale_commands_are_refused_and_counted():
    bench = Bench()
    bench.step()
    bench.command(key=b"not the real key")
    assert bench.unit.cmd is None and "authentication" in bench.unit.last_reject
    good = bench.command()
    assert bench.unit.cmd is not None
    bench.unit.cmd = None
    bench.unit.on_message(CMD, good, bench.now_ms)
    assert bench.unit.cmd is None and "replayed" in bench.unit.last_reject
    # a command based on a report that is too old
    old_seq = bench.last_report()["seq"]
    for _ in range(60):
        bench.step()
    bench.command(rseq=old_seq)
    assert bench.unit.cmd is None and "stale" in bench.unit.last_reject
    bench.command(rseq=10_000)
    assert "stale" in bench.unit.last_reject
    assert bench.unit.rejected == 4
    bench.step(ms=100)
    assert "cmd_reject" in bench.last_report()["flt"]


def test_a_new_controller_session_is_accepted_with_a_fresh_report():
    bench = Bench()
    bench.step()
    bench.command(sid=1, seq=50)
    bench.step(ms=100)
    bench.command(sid=2, seq=1)
    assert bench.unit.sid == 2 and bench.unit.cseq == 1


def test_overspeed_against_the_braking_curve_trips_the_brake():
    bench = Bench()
    bench.step()
    bench.command(v_mmps=500, eoa_mm=100)
    # the train is pushed at 600 mm/s with only 100 mm of authority left
    for _ in range(5):
        bench.step(v_mmps=600)
    assert bench.unit.mode == "trip" and bench.motor.mode == "brake"


def test_the_train_never_passes_its_end_of_authority_in_a_closed_loop():
    """Kinematic loop: the encoder follows the speed reference; the head stops before eoa."""
    bench = Bench()
    bench.step()
    bench.command(v_mmps=500, eoa_mm=1500, ttl_ms=10_000)
    for _ in range(400):
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    assert bench.unit.odo_mm <= 1500
    assert bench.unit.odo_mm > 1300, "it uses its authority"
    assert bench.motor.mode == "brake"


def test_broken_sensors_are_reported_and_never_stop_the_loop():
    bench = Bench(ips=BrokenSensor(), rfid=BrokenSensor(), encoder=BrokenSensor())
    for _ in range(20):
        bench.step()
    report = bench.last_report()
    assert bench.unit.sensor_errors >= 3 * 19
    assert {"ips_silent", "rfid_absent"} <= set(report["flt"])
    assert bench.motor.mode == "brake"


def test_unknown_config_key_is_named():
    with pytest.raises(ValueError, match="counts_per_metre"):
        obu.OnboardUnit("A", KEY, 9, FakeEncoder(), FakeIps(), FakeRfid(), FakeMotor(), print, {"counts_per_metre": 3})


def test_the_trip_curve_lies_above_the_service_curve_everywhere():
    """Riding the service curve never trips: at every distance the emergency curve (reaction time counted) plus the
    trip margin is above the service curve by more than the measured speed can lag at the service rate, with at
    least 25 mm/s left for tracking error. The speed is the mean between two edges, so it lags by the newest edge's
    age (up to an edge interval) and half their span (the speed window and up to an edge interval). The stop window
    is what keeps it so near the end: the curves cross below 3.4 mm; 5 mm leaves 11 mm/s between them and 29 mm/s
    for tracking; 4 mm would leave 19."""
    bench = Bench()
    unit = bench.unit
    cfg = unit.cfg
    window = cfg["stop_window_mm"]
    for dist_mm in range(window + 1, 3000):
        unit.eoa_mm = unit.odo_mm + dist_mm
        service = unit.braking_curve_mmps(cfg["dec_mmps2"])
        if service == 0:
            continue                         # the creep: stopped and held
        edge_ms = 1e6 / (service * cfg["counts_per_m"])
        lag_ms = edge_ms + (cfg["speed_window_ms"] + edge_ms) / 2
        room = unit.trip_curve_mmps() + cfg["trip_margin_mmps"] - service - cfg["dec_mmps2"] * lag_ms / 1000
        assert room >= 25.0, dist_mm
    # by hand at 1 m: service sqrt(2 * 800 * 995) = 1261.7 mm/s; trip 1400 (sqrt(0.06^2 + 2 * 1000 / 1400) - 0.06)
    unit.eoa_mm = unit.odo_mm + 1000
    assert unit.braking_curve_mmps(800) == pytest.approx((1600 * (1000 - window)) ** 0.5, abs=0.01)
    assert unit.trip_curve_mmps() == pytest.approx(1400 * ((0.0036 + 2000 / 1400) ** 0.5 - 0.06), abs=0.01)


def test_the_service_curve_stays_under_the_trip_curve_at_every_scale_and_distance_the_protocol_allows():
    """The stop window is in true mm, scaled to odometer mm with the decelerations: at every encoder scale a command
    may state the service curve lies under the trip curve at every distance (by 1.6 mm of stop window at the scale's
    worst distance); a window left unscaled crossed it from 1500 odometer mm per m."""
    bench = Bench()
    bench.step()
    unit = bench.unit
    for scale in range(wire.ODO_MM_PER_M_MIN, wire.ODO_MM_PER_M_MAX + 1, 50):
        bench.command(eoa_mm=10000, odo_mm_per_m=scale)
        for tenth_mm in list(range(0, 400)) + list(range(400, 50000, 97)):
            unit.eoa_mm = unit.odo_mm + tenth_mm / 10
            assert unit.braking_curve_mmps(unit.cfg["dec_mmps2"]) <= unit.trip_curve_mmps(), (scale, tenth_mm)


def test_a_stop_window_too_short_for_the_curves_and_a_fractional_encoder_scale_are_refused_at_boot():
    make = lambda config: obu.OnboardUnit("A", KEY, 9, FakeEncoder(), FakeIps(), FakeRfid(), FakeMotor(), print,
                                          config)
    with pytest.raises(ValueError, match="counts_per_m must be whole.*1043.7"):
        make({"counts_per_m": 1043.7})
    assert make({"counts_per_m": 1044.0}).cfg["counts_per_m"] == 1044
    assert isinstance(make({"counts_per_m": 1044.0}).cfg["counts_per_m"], int)
    with pytest.raises(ValueError, match="stop_window_mm"):
        make({"stop_window_mm": 3})
    with pytest.raises(ValueError, match="raise emergency_dec_mmps2 over dec_mmps2"):
        make({"emergency_dec_mmps2": 800})


@pytest.mark.parametrize("beta_s, beta_e", [(0.8, 1.4), (1.0, 1.5), (1.2, 1.3), (0.5, 0.6)])
def test_a_profiles_board_configuration_boots_with_its_stop_window_wide_enough(beta_s, beta_e):
    """The stop window follows the profile: the firmware's default where it suffices, wider where the reaction time
    would bring the service curve onto the trip curve (brisk service brakes close under the emergency rate)."""
    assert train_profile.STOP_WINDOW_MM == obu.DEFAULTS["stop_window_mm"]
    profile = TrainProfile(beta_s_mps2=beta_s, beta_e_mps2=beta_e)
    unit = obu.OnboardUnit("A", KEY, 9, FakeEncoder(), FakeIps(), FakeRfid(), FakeMotor(), print,
                           profile.obu_config())
    window_mm = unit.cfg["stop_window_mm"]
    assert (window_mm == obu.DEFAULTS["stop_window_mm"]) == ((beta_s, beta_e) == (0.8, 1.4))   # the default profile
    if window_mm > obu.DEFAULTS["stop_window_mm"]:   # widened no more than it must be
        with pytest.raises(ValueError, match="stop_window_mm"):
            obu.OnboardUnit("A", KEY, 9, FakeEncoder(), FakeIps(), FakeRfid(), FakeMotor(), print,
                            {**profile.obu_config(), "stop_window_mm": window_mm - 1})


def test_with_timed_edges_the_speed_is_exact_and_fresh():
    """An encoder that times its edges gives the speed to the mm/s at every pass, with a lag of about half the speed
    window; counts over the time between passes alone are off by up to a count per window (50 mm/s in 20 ms)."""
    timed, counted = Bench(encoder=TimedEncoder()), Bench()
    readings = {"timed": [], "counted": []}
    for _ in range(60):
        for name, bench in (("timed", timed), ("counted", counted)):
            bench.step(v_mmps=392.3)
            readings[name].append(bench.unit.v_mmps)
    assert all(abs(v - 392) <= 1 for v in readings["timed"][10:]), readings["timed"]
    assert max(readings["counted"][10:]) - min(readings["counted"][10:]) >= 40, readings["counted"]


def test_with_timed_edges_a_train_that_stops_reads_slower_at_every_pass_without_an_edge():
    """After the last edge the speed is at most a count over the time since it (it would have counted more, had it
    been faster), then 0 once no edge is left in the unit's memory of passes."""
    bench = Bench(encoder=TimedEncoder())
    for _ in range(30):
        bench.step(v_mmps=300)
    assert abs(bench.unit.v_mmps - 300) <= 1
    readings, ages = [], []
    for _ in range(12):
        bench.step()                                       # no more edges
        readings.append(bench.unit.v_mmps)
        ages.append(bench.enc.age_us)
    assert all(v <= 1e6 / age for v, age in zip(readings, ages)), (readings, ages)   # a count over the age at most
    assert all(b < a for a, b in zip(readings, readings[1:]) if a), readings
    assert readings[0] >= 40 and readings[-1] == 0


def test_with_timed_edges_a_start_after_a_long_stand_reads_no_faster_than_the_train():
    """The board's tick counter wraps after 9 min, so a standing count's age can turn to nonsense: after 10 min
    standing (past the unit's own 262 s wrap of edge times too), with the age wrapped to 0 just before the start, the
    first edges read no faster than the train goes."""
    bench = Bench(encoder=TimedEncoder())
    for _ in range(30):
        bench.step(v_mmps=300)
    for _ in range(30000):                     # 10 min standing
        bench.step()
    bench.enc.age_us = -20 * 1000
    bench.step()                               # the encoder's age has wrapped to 0 just before the train moves
    assert bench.unit.v_mmps == 0
    readings = []
    for _ in range(10):
        bench.step(v_mmps=100)
        readings.append(bench.unit.v_mmps)
    assert max(readings) <= 101, readings
    assert readings[-1] >= 95, readings


@pytest.mark.parametrize("true_scale", [0.97, 1.0, 1.03])
def test_the_curves_hold_in_true_metres_with_the_encoder_scale_the_command_states(true_scale):
    """The curves work in odometer mm; a wheel reading `true_scale` odometer mm per true mm, commanded with a low
    bound of that (what the controller sends), stops from the trip curve within the true distance to its end of
    authority, reaction time counted, and rides a service curve no steeper than the service rate in truth. A wheel
    that reads short, left unscaled (1000), would overrun its authority from the trip curve."""
    bench = Bench()
    bench.step()
    low = int(true_scale * 1000) - 5            # the controller's low bound, floored
    bench.command(eoa_mm=10000, odo_mm_per_m=low)
    unit = bench.unit
    cfg = unit.cfg
    r_s = cfg["reaction_ms"] / 1000.0
    for dist_mm in (20, 50, 100, 300, 1000, 3000):
        unit.eoa_mm = unit.odo_mm + dist_mm
        true_dist_mm = dist_mm / true_scale
        v_true = unit.trip_curve_mmps() / true_scale
        assert v_true * r_s + v_true ** 2 / (2 * cfg["emergency_dec_mmps2"]) <= true_dist_mm + 1e-9, dist_mm
        v_true = unit.braking_curve_mmps(cfg["dec_mmps2"]) / true_scale
        service_true_mm = (dist_mm - cfg["stop_window_mm"] * unit.odo_scale()) / true_scale
        assert v_true ** 2 / (2 * cfg["dec_mmps2"]) <= service_true_mm + 1e-9, dist_mm
        # and it gives away no more than the bound's slack: within 1 % of the true service rate
        assert v_true ** 2 / (2 * cfg["dec_mmps2"]) >= 0.99 * service_true_mm, dist_mm
    if true_scale < 1.0:
        bench.command(eoa_mm=10000, odo_mm_per_m=1000)
        unit.eoa_mm = unit.odo_mm + 1000
        v_true = unit.trip_curve_mmps() / true_scale
        assert v_true * r_s + v_true ** 2 / (2 * cfg["emergency_dec_mmps2"]) > 1000 / true_scale


def test_riding_the_curve_behind_a_moving_limit_is_takagi_synchronisation():
    """The end of authority advances with a leader that slows from 0.6 to 0.2 m/s at 0.3 m/s^2; the follower starts on
    its service curve at 0.6 m/s. Riding the curve, its speed follows eq. 24, dv_B/dt = -beta_s (v_B - v_A) / v_B,
    integrated alongside, and it ends at the leader's speed, still on the curve."""
    from cbtc.authority.control_laws import sync_deceleration_mps2

    bench = Bench()
    unit = bench.unit
    beta = unit.cfg["dec_mmps2"]
    window = unit.cfg["stop_window_mm"]
    bench.step()
    v_a = v_sync = 600.0
    eoa = 600.0 ** 2 / (2 * beta) + window                  # the follower stands on its curve at 600 mm/s
    unit.v_ref_mmps = 600.0
    worst = 0.0
    for _ in range(250):                                    # 5 s in 20 ms steps
        bench.command(v_mmps=600, eoa_mm=int(round(eoa)), ttl_ms=800)
        bench.step(v_mmps=unit.v_ref_mmps)
        v_sync -= sync_deceleration_mps2(v_sync / 1000, v_a / 1000, beta / 1000) * 1000 * 20e-3
        worst = max(worst, abs(unit.v_ref_mmps - v_sync))
        v_a = max(200.0, v_a - 300.0 * 20e-3)
        eoa += v_a * 20e-3
    assert worst < 20.0, "the follower left the eq. 24 trajectory by %.1f mm/s" % worst   # 3 % of 600 mm/s
    assert unit.v_ref_mmps == pytest.approx(200.0, abs=10.0)
    assert abs(unit.braking_curve_mmps(beta) - unit.v_ref_mmps) < 10.0


def _running_at(odo_mm, stop_mm=None):
    """A bench whose train runs under a 3 m authority (and `stop_mm`) until its odometer passes `odo_mm`."""
    bench = Bench()
    bench.step()
    bench.command(v_mmps=500, eoa_mm=3000, stop_mm=stop_mm, ttl_ms=10_000)
    while bench.unit.odo_mm <= odo_mm:
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    return bench


def test_a_station_stop_is_a_service_target_that_never_trips():
    """The stop target (a station) is braked to at the service rate and held; moving it back (the controller's
    position of the train was corrected at a balise) makes the train brake harder, never trip: the trip curve
    supervises the end of authority alone."""
    bench = _running_at(1200, stop_mm=1500)
    unit = bench.unit
    assert unit.v_ref_mmps > 200, "running towards the station"
    bench.command(v_mmps=500, eoa_mm=3000, stop_mm=unit.odo_mm + 30, ttl_ms=10_000)   # the station is nearer
    for _ in range(100):
        bench.step(v_mmps=int(unit.v_ref_mmps))
    assert unit.trips == 0 and unit.mode == "run"
    assert unit.v_ref_mmps == 0 and bench.motor.mode == "brake", "stopped and held at the station"
    # the same retraction of the end of authority is a safety matter: the trip curve brakes the motor
    bench = _running_at(1200)
    bench.command(v_mmps=500, eoa_mm=bench.unit.odo_mm + 30, ttl_ms=10_000)
    bench.step(v_mmps=int(bench.unit.v_mmps))
    assert bench.unit.trips == 1 and bench.motor.mode == "brake"


def test_a_train_braked_onto_a_station_mark_a_mm_short_is_held_there_not_driven_up_to_it():
    """Within 3 mm of the stop target, with the drive cut, the stop is made: the service curve is zero and the train
    holds (creeping the last mm cost a tenth of a second a stop); further off, or short of an end of authority
    rather than a station, it is driven on."""
    for stop_ahead_mm, drives in ((2, False), (3, False), (10, True)):
        bench = Bench()
        bench.step()
        unit = bench.unit
        bench.command(v_mmps=500, eoa_mm=unit.odo_mm + 3000, stop_mm=unit.odo_mm + stop_ahead_mm, ttl_ms=10_000)
        moves = []
        for _ in range(10):
            bench.step()
            moves.append(bench.motor.mode == "drive" and unit.duty_pct > 0)
        assert any(moves) == drives, (stop_ahead_mm, moves)
    bench = Bench()
    bench.step()
    bench.command(v_mmps=500, eoa_mm=bench.unit.odo_mm + bench.unit.cfg["stop_window_mm"] + 2, ttl_ms=10_000)
    bench.step()
    assert bench.unit.braking_curve_mmps(800) > 0, "an end of authority is no station: its curve is unchanged"


def test_a_train_over_its_trip_curve_within_the_margin_brakes_at_that_pass_and_goes_on():
    """The end of authority steps back under a train riding its service curve (the train ahead braked hard and its
    rollback allowance grew): at a pass where the measured speed is over the trip curve but within the trip margin,
    the board brakes rather than drive at the duty a lagging loop may still ask; it does not trip, and its reference
    stays on the curve (the run goes on once it is back under it)."""
    bench = _running_at(600)
    unit = bench.unit
    v_mmps = unit.v_mmps
    bench.command(v_mmps=500, eoa_mm=unit.odo_mm + 250, ttl_ms=10_000)
    for _ in range(40):   # the train keeps its speed until it is over the trip curve
        bench.step(v_mmps=v_mmps)
        if unit.v_mmps > unit.trip_curve_mmps():
            break
    assert unit.trip_curve_mmps() < unit.v_mmps < unit.trip_curve_mmps() + unit.cfg["trip_margin_mmps"]
    assert bench.motor.mode == "brake", "braked at the pass over the trip curve"
    assert unit.trips == 0 and unit.mode == "run" and unit.v_ref_mmps > 0


def test_a_report_names_undriven_when_a_pass_since_the_previous_one_braked_while_it_drives_now():
    """Riding a braking curve, the loop brakes for a pass and drives again between two reports: the report's duty
    alone would say driven throughout, so it names `undriven` (the controller then allows the brake's fall in speed
    over the interval); a report of a train driven at every pass, or not driven now, does not."""
    bench = _running_at(600)
    unit = bench.unit
    for _ in range(10):   # steady at the commanded speed: driven at every pass
        bench.step(v_mmps=int(unit.v_ref_mmps))
    assert unit.duty_pct > 0 and "undriven" not in bench.last_report()["flt"]
    bench.command(v_mmps=100, eoa_mm=3000, ttl_ms=10_000)   # slow down: the loop brakes at some pass
    for _ in range(50):
        reports = len(bench.sent)
        bench.step(v_mmps=int(unit.v_mmps))
        if bench.motor.mode == "brake" and len(bench.sent) == reports:   # a pass between reports
            break
    assert bench.motor.mode == "brake"
    bench.command(v_mmps=500, eoa_mm=3000, ttl_ms=10_000)
    reports = len(bench.sent)
    while len(bench.sent) == reports:   # the next report, driven by then
        bench.step(v_mmps=int(unit.v_ref_mmps))
    report = bench.last_report()
    assert report["mode"] == "run" and report["duty"] > 0 and "undriven" in report["flt"]
    for _ in range(10):
        bench.step(v_mmps=int(unit.v_ref_mmps))
    assert "undriven" not in bench.last_report()["flt"], "named for the interval it braked in only"


def test_a_report_names_undriven_when_it_brakes_at_its_own_pass_after_driving_since_the_previous_one():
    """Driven at a pass after the previous report, braked at the report's own pass: the mean duty it reports is
    above 0, so it names `undriven` too, or the controller would read a braked interval as driven at a low duty and
    take the brake's fall in speed for a sliding wheel."""
    bench = _running_at(600)
    unit = bench.unit
    reports = len(bench.sent)
    while len(bench.sent) == reports:   # steady at the commanded speed up to a report
        bench.step(v_mmps=int(unit.v_ref_mmps))
    reports = len(bench.sent)
    bench.step(v_mmps=int(unit.v_ref_mmps))   # a driven pass of the next interval
    assert unit.duty_pct > 0 and len(bench.sent) == reports
    bench.command(v_mmps=500, eoa_mm=3000, stop_mm=unit.odo_mm + 1, ttl_ms=10_000)   # a stop just ahead: it brakes
    while len(bench.sent) == reports:
        bench.step(v_mmps=int(unit.v_mmps))
    report = bench.last_report()
    assert bench.motor.mode == "brake" and report["mode"] == "run" and report["duty"] > 0
    assert "undriven" in report["flt"]


def test_a_reports_duty_is_the_mean_of_the_passes_since_the_one_before():
    """The motor answers the mean duty of an interval (it is linear in duty), so a report gives the floored mean of
    the loop's passes since the previous report, the reporting pass included, and not one pass's duty: a loop that
    slows, brakes for a pass and drives again, has duties that differ pass to pass."""
    bench = _running_at(600)
    unit = bench.unit
    bench.command(v_mmps=100, eoa_mm=3000, ttl_ms=10_000)
    duties, means, told = [], [], []
    for i in range(60):
        if i == 30:
            bench.command(v_mmps=500, eoa_mm=3000, ttl_ms=10_000)
        reports = len(bench.sent)
        bench.step(v_mmps=int(unit.v_mmps) if i < 30 else int(unit.v_ref_mmps))
        duties.append(unit.duty_pct)
        if len(bench.sent) > reports:
            means.append(sum(duties) // len(duties))
            told.append(bench.last_report()["duty"])
            duties = []
    # the first report's interval began before these passes were recorded
    assert len(told) >= 10 and told[1:] == means[1:]
    assert len(set(told)) > 5, "the duties changed over the run"


def test_a_stop_target_beyond_the_end_of_authority_stops_at_the_end_of_authority():
    bench = Bench()
    unit = bench.unit
    bench.step()
    bench.command(v_mmps=500, eoa_mm=1500, stop_mm=4000, ttl_ms=10_000)
    for _ in range(400):
        bench.step(v_mmps=int(unit.v_ref_mmps))
    assert 1400 < unit.odo_mm <= 1500 - unit.cfg["stop_window_mm"] + 1


def test_the_report_period_is_the_one_the_controller_asks_for_while_its_command_is_valid():
    bench = Bench()
    bench.step()
    bench.command(rpt_ms=20, ttl_ms=400)
    for _ in range(3):                       # the report already due at the board's own period, then the new one
        bench.step()
    first = len(bench.sent)
    for _ in range(10):                      # 200 ms at 20 ms a pass: a report every pass
        bench.step()
    assert len(bench.sent) - first == 10
    for _ in range(30):                      # the command expires: back to the board's own 50 ms
        bench.step()
    first = len(bench.sent)
    for _ in range(25):                      # 500 ms
        bench.step()
    assert len(bench.sent) - first == 10


def test_a_long_report_period_ends_with_its_command():
    """A command asking for reports every 10 s (the protocol's longest) holds for its 400 ms of validity only: the
    board reports again on the pass its command expires, at its own 50 ms after, and takes a restart command at once."""
    bench = Bench()
    bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    bench.command(rpt_ms=10000, ttl_ms=400)
    expiry = bench.unit.cmd_expiry_ms
    sent = len(bench.sent)
    while wire.wrap_diff(bench.now_ms + 20, expiry) < 0:
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    assert len(bench.sent) == sent, "silent while the command is valid"
    bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    assert bench.now_ms == expiry and len(bench.sent) == sent + 1 and "cmd_timeout" in bench.last_report()["flt"]
    for _ in range(10):
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    assert len(bench.sent) == sent + 5                       # 200 ms more at 50 ms
    bench.command(ttl_ms=800)
    bench.step(v_mmps=int(bench.unit.v_ref_mmps))
    assert bench.unit.mode == "run" and bench.unit.rejected == 0


def test_an_end_of_authority_further_ahead_than_any_line_is_refused_and_the_one_held_stays():
    bench = Bench()
    bench.step()
    bench.command(eoa_mm=5000)
    assert bench.unit.eoa_mm == 5000
    for _ in range(10):
        bench.step(v_mmps=300)
    odo_mm = bench.unit.odo_mm
    limit_mm = obu.DEFAULTS["max_authority_mm"]
    bench.command(eoa_mm=odo_mm + limit_mm + 1)              # a zone error: no line is that long
    assert bench.unit.eoa_mm == 5000 and "max_authority_mm" in bench.unit.last_reject and bench.unit.rejected == 1
    bench.command(eoa_mm=odo_mm + limit_mm)
    assert bench.unit.eoa_mm == odo_mm + limit_mm


class ScriptedRfid(FakeRfid):
    """A reader whose bus fails at the passes the test names: those passes did not poll it."""

    def __init__(self):
        super().__init__()
        self.failing = False

    def poll(self, now_ms):
        if self.failing:
            raise OSError(5, "EIO")
        return super().poll(now_ms)


def test_a_tag_read_carries_the_time_since_the_readers_previous_poll_that_answered():
    """The reader entered the tag's field somewhere in that time: the controller takes the read's lateness from it,
    whatever the loop's pace; passes whose poll failed are in it too. Time, not counts: counts in a burst are not
    travel."""
    rfid = ScriptedRfid()
    bench = Bench(rfid=rfid)
    for _ in range(5):
        bench.step(v_mmps=400)                       # 8 mm a 20 ms pass
    rfid.uid = "04A1B2C3"
    bench.step(v_mmps=400)
    for _ in range(2):
        bench.step(v_mmps=400)
    assert bench.reported_tags() == [["04A1B2C3", 48, 120, 20]]
    rfid.failing = True
    for _ in range(3):                               # three passes the reader did not answer
        bench.step(v_mmps=400)
    rfid.failing = False
    rfid.uid = "04A1B2C4"
    bench.step(v_mmps=400)
    for _ in range(3):
        bench.step(v_mmps=400)
    assert bench.reported_tags()[-1] == ["04A1B2C4", 96, 240, 80]   # since the last poll that answered: four passes
    assert obu._SPAN_MAX_MS == wire_zc.SPAN_MAX_MS   # the longest span the board sends is the longest the wire takes
