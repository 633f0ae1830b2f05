"""The clock a run's log lines are stamped with, and how often one kind of warning is said.

A simulation sets its own clock while it runs (`simulated`), so that its warnings say when in the run they happened,
not when on the wall; the command line's log handler reads `now_s` and holds back a warning said more than
`SAID_PER_WINDOW` times in `WINDOW_S` of that clock, counting what it held back."""

import logging
import time
from contextlib import contextmanager
from contextvars import ContextVar

_CLOCK = ContextVar("cbtc_run_clock", default=None)
WINDOW_S = 10.0        # of the run's clock
SAID_PER_WINDOW = 3    # lines of one kind (logger, message, first argument) said in a window; the rest counted


def now_s():
    """The simulated time of the run in progress, or None outside a simulation (the wall clock is the run's)."""
    clock = _CLOCK.get()
    return None if clock is None else clock()


@contextmanager
def simulated(clock):
    """Within the block, log lines carry `clock()` (simulated seconds) as their time."""
    token = _CLOCK.set(clock)
    try:
        yield
    finally:
        _CLOCK.reset(token)


class RunClockFormatter(logging.Formatter):
    """Stamps a line with the simulated time while a simulation runs, else the wall clock to the millisecond."""

    def formatTime(self, record, datefmt=None):
        sim_s = now_s()
        if sim_s is not None:
            return f"sim {sim_s:.3f} s"
        return time.strftime("%H:%M:%S", self.converter(record.created)) + f".{int(record.msecs):03d}"


class RepeatLimit(logging.Filter):
    """Holds back a warning said SAID_PER_WINDOW times already in the current WINDOW_S of the run's clock; the next
    one said after the window says how many were held back."""

    def __init__(self):
        super().__init__()
        self._kinds = {}   # kind -> [window start, said in it, held back]

    def filter(self, record):
        if record.levelno < logging.WARNING or record.levelno >= logging.ERROR:
            return True
        t_s = now_s()
        t_s = time.monotonic() if t_s is None else t_s
        first = record.args[0] if isinstance(record.args, tuple) and record.args else None
        kind = (record.name, record.msg, first if isinstance(first, (str, int)) else None)
        seen = self._kinds.get(kind)
        if seen is None or t_s - seen[0] >= WINDOW_S or t_s < seen[0]:
            held = 0 if seen is None else seen[2]
            self._kinds[kind] = [t_s, 1, 0]
            if held:
                record.msg = f"{record.msg} ({held} more like this held back in the {WINDOW_S:g} s before)"
            return True
        if seen[1] < SAID_PER_WINDOW:
            seen[1] += 1
            return True
        seen[2] += 1
        return False
