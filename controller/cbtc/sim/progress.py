"""How far the simulations of a command have run, for its progress bar.

A context-local sink (`reporting_to`), so that the experiments running several simulations (a comparison, a guard
sweep) need not carry a callback through every call: `Simulation.run` reports to whatever sink is set, and with
none set nothing is reported.
"""

from contextlib import contextmanager
from contextvars import ContextVar

_SINK = ContextVar("cbtc_sim_progress", default=None)


def report(run, done: float, total: float, unit: str = "s") -> None:
    """Simulation `run` (any object naming the run) has made `done` of its `total`: simulated seconds, laps, or
    ("done") the whole of it."""
    sink = _SINK.get()
    if sink is not None:
        sink(run, done, total, unit)


@contextmanager
def reporting_to(sink):
    """Within the block, simulations report `sink(run, done, total, unit)` about every simulated second."""
    token = _SINK.set(sink)
    try:
        yield
    finally:
        _SINK.reset(token)
