"""Times and sequence numbers wrap modulo 2^30 by rule (docs/protocol.md): a board up for months reports and is
commanded as on its first day, on the board (CPython here, the unix port in test_firmware_mpy) and through the zone."""

from cbtc.estimation.estimate import BoardClock
from cbtc.layout_files import load_layout
from cbtc.protocol import wire
from cbtc.railway.train_profile import TrainProfile
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import ScenarioConfig, TrainSpec
from test_obu import Bench

PERIOD = wire.WRAP_MASK + 1


def test_wrap_diff_and_add_agree_with_modular_arithmetic():
    for a in (0, 1, 5, PERIOD // 2 - 1, PERIOD // 2, PERIOD - 2, PERIOD - 1):
        for d in (-PERIOD // 2, -1000, -1, 0, 1, 1000, PERIOD // 2 - 1):
            b = (a - d) % PERIOD
            assert wire.wrap_diff(a, b) == d
        for step in (0, 1, 20, 10000, PERIOD - 1):
            assert wire.wrap_add(a, step) == (a + step) % PERIOD


def test_a_board_across_the_wrap_is_commanded_and_stops_on_expiry_as_on_its_first_day():
    bench = Bench()
    bench.now_ms = PERIOD - 1000            # 12.4 days up: its clock wraps a second from now
    bench.unit.seq = PERIOD - 10            # and its report sequence ten reports from now
    bench.step()
    for _ in range(150):                    # 3 s of commands answering every report
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
        if bench.last_report()["seq"] != bench.unit.cseq:
            bench.command(eoa_mm=10000)
        bench.now_ms %= PERIOD              # the board's uptime is modulo 2^30 (firmware/train.py)
    assert bench.unit.rejected == 0 and bench.unit.mode == "run" and bench.unit.v_mmps > 300
    assert bench.last_report()["t_ms"] < 5000 and bench.last_report()["seq"] < 100
    for _ in range(60):                     # commands stop: it brakes when the last one expires, 0.8 s on
        bench.step(v_mmps=int(bench.unit.v_ref_mmps))
        bench.now_ms %= PERIOD
    assert bench.unit.mode == "stop" and bench.motor.mode == "brake"


def test_board_clock_unwraps_times_across_the_wrap():
    clock = BoardClock()
    clock.observe(PERIOD - 100, 50.0)
    clock.observe(20, 50.12)                # 120 ms later, after the wrap
    assert abs(clock.to_controller_s(20) - clock.to_controller_s(PERIOD - 100) - 0.12) < 1e-9
    assert abs(clock.to_controller_s(PERIOD - 50) - 50.05) < 1e-9   # a fix stamped before the wrap, read after


def test_the_zone_governs_trains_whose_clocks_wrap_mid_run():
    layout = load_layout("itb_square")
    profile = TrainProfile()
    sim = Simulation(ScenarioConfig(layout=layout, seed=4, duration_s=20.0, trains=[
        TrainSpec("A", layout.wrap(1.5 + profile.length_m), (), profile.with_changes(v_max_mps=0.4)),
        TrainSpec("B", 0.0, (), profile)]))
    for i, train in enumerate(sim.trains):   # both boards wrap 5-6 s into the run
        train.clock_offset_ms = PERIOD - 5000 - 1000 * i
    summary = sim.run().summary()
    for train in sim.trains:
        state = sim.zc.state_of(train.train_id)
        assert state.reports_rejected == 0 and state.restarts == 0 and train.obu.rejected == 0
        assert train.obu.cseq > 300 and train.travelled_m > 4.0
    assert sum(sim.recorder.collisions) == 0 and sum(sim.recorder.overruns) == 0, summary
