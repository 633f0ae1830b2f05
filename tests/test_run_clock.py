"""Log lines carry a simulation's own time while it runs, and one kind of warning said again and again is held back
and counted, on the run's clock."""

import io
import logging

from cbtc import run_clock


def _logger():
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(run_clock.RunClockFormatter("%(asctime)s %(name)s: %(levelname)s: %(message)s"))
    handler.addFilter(run_clock.RepeatLimit())
    log = logging.getLogger("cbtc.test_run_clock")
    log.handlers[:] = [handler]
    log.propagate = False
    log.setLevel(logging.WARNING)
    return log, stream


def test_a_simulations_lines_carry_its_time_and_repeats_are_counted_once_the_window_has_passed():
    log, stream = _logger()
    clock = {"t": 12.5}
    with run_clock.simulated(lambda: clock["t"]):
        for _ in range(10):                       # ten in one window: three said, seven held back
            log.warning("train %s overran station %s", "B", "north")
        log.warning("train %s overran station %s", "A", "north")   # another train: said
        clock["t"] = 23.0
        log.warning("train %s overran station %s", "B", "north")
    lines = stream.getvalue().splitlines()
    assert len(lines) == 5, lines
    assert lines[0].startswith("sim 12.500 s cbtc.test_run_clock: WARNING: train B overran")
    assert "train A" in lines[3]
    assert lines[4].startswith("sim 23.000 s") and "(7 more like this held back in the 10 s before)" in lines[4]


def test_outside_a_simulation_the_wall_clock_stamps_the_line():
    log, stream = _logger()
    log.warning("no broker")
    stamp = stream.getvalue().split(" ")[0]
    assert len(stamp) == len("13:05:10.123") and stamp[2] == ":" and stamp[8] == "."
    assert run_clock.now_s() is None
