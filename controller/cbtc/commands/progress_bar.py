"""Progress bars with the time left, one look for every command (rich): drawn on stderr, and only on a terminal.

None under `--json`, nor when stdout or stderr is not a terminal (a pipe, a file, CI): figures stay clean there.
Log lines and warnings printed while a bar is up appear above it instead of tearing it.
"""

import logging
import sys
import weakref
from contextlib import contextmanager


def shown(args) -> bool:
    """A bar is drawn for this command line: no `--json`, and both stdout and stderr are terminals."""
    return not getattr(args, "json", False) and sys.stdout.isatty() and sys.stderr.isatty()


def _quiet(*_args, **_fields):
    pass


@contextmanager
def bar(label: str, total: float, show: bool, quiet_between: bool = False):
    """A bar named `label` towards `total`; yields `update(completed, text="")` (`text`: what has been done, in the
    command's own words). With `show` False nothing is drawn and `update` does nothing. `quiet_between`: redrawn
    only at each update, with no drawing thread (a benchmark's timings stay its own)."""
    if not show:
        yield _quiet
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    columns = (TextColumn(label), BarColumn(), TextColumn("{task.fields[text]}"), TimeElapsedColumn(),
               TextColumn("ETA"), TimeRemainingColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True, auto_refresh=not quiet_between) \
            as progress, _logs_above():
        task = progress.add_task(label, total=total, text="")

        def update(completed, text=""):
            progress.update(task, completed=completed, text=text, refresh=quiet_between)
        yield update


@contextmanager
def steps(label: str, count: int, show: bool):
    """A bar over `count` measures made one after the other (redrawn only between them); yields
    `step(name, measure, *args)`, which names the measure on the bar, makes it and returns what it gives."""
    with bar(label, count, show, quiet_between=True) as update:
        done = [0]

        def step(name, measure, *args):
            update(done[0], f"{name} ({done[0] + 1}/{count})")
            found = measure(*args)
            done[0] += 1
            return found
        yield step
        update(count, "done")


@contextmanager
def _logs_above():
    """Route the root logger's stderr handlers through the bar's stderr proxy (rich puts each line above the bar)
    while it is drawn."""
    moved = [h for h in logging.getLogger().handlers
             if isinstance(h, logging.StreamHandler) and h.stream is sys.__stderr__]
    for handler in moved:
        handler.setStream(sys.stderr)
    try:
        yield
    finally:
        for handler in moved:
            handler.setStream(sys.__stderr__)


@contextmanager
def simulation_bar(label: str, runs: int, show: bool):
    """A bar over the `runs` simulations the block makes (cbtc.sim.progress): each counts one, the one running by
    the share of its simulated time done; a single run shows its simulated seconds."""
    from cbtc.sim import progress

    with bar(label, runs, show) as update:
        if not show:
            yield
            return
        state = {"run": None, "finished": -1}

        def sink(run, done, total, unit):
            current = state["run"]() if state["run"] is not None else None
            if current is not run:   # a new run: the one before it is complete
                state["run"] = weakref.ref(run)
                state["finished"] += 1
            share = min(1.0, done / total) if total > 0 else 1.0
            words = {"s": "s simulated", "laps": "laps"}
            text = f"{done:.0f}/{total:.0f} {words[unit]}" if runs == 1 and unit in words else \
                "done" if runs == 1 else f"run {min(runs, state['finished'] + 1)}/{runs}"
            update(state["finished"] + share, text)

        with progress.reporting_to(sink):
            yield
