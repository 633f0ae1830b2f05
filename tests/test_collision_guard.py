"""The onboard collision guard: brakes on a short measured gap whatever the commands say; saves the faulty-leader
case."""

from cbtc.firmware import obu
from cbtc.protocol import wire_zc
from fake_drivers import FakeEncoder, FakeIps, FakeMotor, FakeRfid

KEY = b"0123456789abcdef"
CMD = "cbtc/train/B/cmd"


class FakeRanging:
    def __init__(self):
        self.gap_mm = None

    def poll(self, now_ms):
        gap, self.gap_mm = self.gap_mm, None
        return gap


class Bench:
    def __init__(self):
        self.sent = []
        self.enc = FakeEncoder()
        self.motor = FakeMotor()
        self.ranging = FakeRanging()
        self.unit = obu.OnboardUnit("B", KEY, 9, self.enc, FakeIps(), FakeRfid(), self.motor,
                                    lambda topic, payload: self.sent.append((topic, payload)),
                                    {"counts_per_m": 1000, "emergency_dec_mmps2": 1400, "reaction_ms": 60,
                                     "report_ms": 100},
                                    ranging=self.ranging)
        self.now_ms = 0
        self.seq = 0

    def step(self, v_mmps=0):
        self.now_ms += 20
        self.enc.counts += v_mmps * 20 // 1000
        self.unit.step(self.now_ms)

    def command(self):
        self.seq += 1
        rseq = wire_zc.decode_report(KEY, self.sent[-1][0], self.sent[-1][1])["seq"]
        payload = wire_zc.encode_command(KEY, "B", self.unit.boot_id, self.seq, 1, rseq, 600, 10000, 800, 600, 800)
        self.unit.on_message(CMD, payload, self.now_ms)

    def cruise(self, v_mmps, steps):
        for _ in range(steps):
            self.step(v_mmps)
            if self.now_ms % 100 == 0:
                self.command()


def test_guard_limit_is_emergency_braking_plus_reaction_plus_margin():
    bench = Bench()
    bench.step()
    bench.command()
    bench.cruise(500, 20)
    assert bench.unit.v_mmps == 500
    # 500^2 / (2 * 1400) + 500 * 0.060 + 100 = 89.3 + 30 + 100 mm
    assert abs(bench.unit.guard_limit_mm() - 219.29) < 0.01


def test_short_gap_brakes_despite_a_valid_command_and_reports_the_fault():
    bench = Bench()
    bench.step()
    bench.command()
    bench.cruise(500, 20)
    assert bench.motor.mode == "drive"
    bench.ranging.gap_mm = 200                        # below the 219 mm limit at 500 mm/s
    bench.step(500)
    assert bench.motor.mode == "brake" and bench.unit.mode == "trip"
    bench.cruise(500, 4)                              # commands keep coming: still braked while the gap is fresh
    assert bench.motor.mode == "brake"
    report = wire_zc.decode_report(KEY, bench.sent[-1][0], bench.sent[-1][1])
    assert "guard" in report["flt"] and report["rng"][1] == 200


def test_long_or_stale_gap_leaves_the_train_alone():
    bench = Bench()
    bench.step()
    bench.command()
    bench.cruise(500, 20)
    bench.ranging.gap_mm = 400                        # above the limit
    bench.step(500)
    assert bench.motor.mode == "drive" and not bench.unit.guard_on
    # a short gap measured 320 ms ago is stale (limit 300 ms): ignored
    bench.unit.gap_mm, bench.unit.gap_t_ms = 150, bench.now_ms - 320
    bench.step(500)
    assert bench.motor.mode == "drive"


def test_faulty_leader_guard_prevents_the_collision_that_happens_without_it():
    from cbtc.experiments.guard import run_guard_case
    from cbtc.layout_files import load_layout
    layout = load_layout("itb_square")
    for seed in range(2):   # `cbtc guard --seeds 0-19` runs more, and longer (the leader fails within 20 s)
        off = run_guard_case(layout, seed, guard=False, duration_s=20.0)
        on = run_guard_case(layout, seed, guard=True, duration_s=20.0)
        assert off["follower_collisions"] > 0, off
        assert on["collisions"] == 0 and on["guard_trips"] > 0, on
        assert on["min_gap_m"] > 0.0


def test_the_controller_takes_the_shorter_of_estimated_and_measured_gap_and_raises_the_alarm():
    from cbtc.authority import rules
    from cbtc.authority.moving_block import MovingBlockPolicy
    from cbtc.layout_files import load_layout
    from cbtc.zone.controller import ZoneController
    from cbtc.zone.train_notes import note_gap
    from cbtc.zone.train_state import TrainSetup

    class Quiet:
        def publish(self, *a, **k):
            pass

        def subscribe(self, *a, **k):
            pass

    zc = ZoneController(load_layout("itb_square"), [TrainSetup("A", b"k" * 16), TrainSetup("B", b"j" * 16)], Quiet(),
                        lambda: 10.0, MovingBlockPolicy())
    state = zc.state_of("B")

    def checked_gap_m(state, gap_est_m, sigma_m, now_s):   # as the moving block policy and the zone take it
        gap_m, alarm = rules.checked_gap_m(gap_est_m, sigma_m, state.rng_gap, now_s, zc.params, zc.ranging_sigma_m,
                                           zc.use_measured_gap)
        note_gap(state, alarm, gap_est_m, zc.use_measured_gap)
        return gap_m
    # no measurement: the estimate stands, no alarm
    assert checked_gap_m(state, 1.0, 0.01, 10.0) == 1.0 and not state.gap_alarm
    # a fresh measurement that agrees within 3 (sigma + ranging sigma): the shorter is used, no alarm
    state.rng_gap = (9.9, 0.95)
    assert checked_gap_m(state, 1.0, 0.01, 10.0) == 0.95 and not state.gap_alarm
    # the picture is wrong: the train ahead is much closer than estimated
    state.rng_gap = (9.9, 0.40)
    assert checked_gap_m(state, 1.0, 0.01, 10.0) == 0.40
    assert state.gap_alarm and state.gap_alarms == 1
    # a stale measurement is not used
    assert checked_gap_m(state, 1.0, 0.01, 12.0) == 1.0 and not state.gap_alarm
    # alarm only: the measurement does not shorten the authority
    zc.use_measured_gap = False
    state.rng_gap = (9.9, 0.40)
    assert checked_gap_m(state, 1.0, 0.01, 10.0) == 1.0 and state.gap_alarm
