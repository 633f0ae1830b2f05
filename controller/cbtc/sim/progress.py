"""How far the simulations of a command have run, for its progress bar.

A context-local sink (`reporting_to`), so that the experiments running several simulations (a comparison, a guard
sweep) need not carry a callback through every call: `Simulation.run` reports to whatever sink is set, and with
none set nothing is reported.
"""

from contextlib import contextmanager
from contextvars import ContextVar

_SINK = ContextVar("cbtc_sim_progress", default=None)


def report(run, done_s: float, total_s: float) -> None:
    """Simulation `run` (any object naming the run) has simulated `done_s` of its `total_s` seconds."""
    sink = _SINK.get()
    if sink is not None:
        sink(run, done_s, total_s)


@contextmanager
def reporting_to(sink):
    """Within the block, simulations report `sink(run, done_s, total_s)` about every simulated second."""
    token = _SINK.set(sink)
    try:
        yield
    finally:
        _SINK.reset(token)
