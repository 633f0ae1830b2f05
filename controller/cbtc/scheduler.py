"""Event schedulers: one interface, virtual time (as fast as the CPU allows, reproducible) or wall-clock time.

Both run callbacks at their due time in due order; ties break by insertion order (a counter), so a virtual run is
deterministic. Code that is scheduled never reads a clock: it is handed `now_s`.
"""

import itertools
import time
from heapq import heappop, heappush


class VirtualScheduler:
    """Discrete-event scheduler on a virtual clock that starts at `start_s` (seconds)."""

    def __init__(self, start_s: float = 0.0):
        self._now_s = float(start_s)
        self._queue = []
        self._counter = itertools.count()
        self._stopped = False

    def now_s(self) -> float:
        """Current time in seconds."""
        return self._now_s

    def call_at(self, t_s: float, fn, *args):
        """Run `fn(*args)` at time `t_s` (never earlier than now). Returns a handle for `cancel`."""
        entry = [max(float(t_s), self._now_s), next(self._counter), fn, args]
        heappush(self._queue, entry)
        return entry

    def call_later(self, delay_s: float, fn, *args):
        """Run `fn(*args)` after `delay_s` seconds."""
        return self.call_at(self._now_s + delay_s, fn, *args)

    def call_every(self, period_s: float, fn, start_s: float = None):
        """Run `fn(now_s)` every `period_s` seconds from `start_s` (default now) until cancelled.

        Returns a handle whose `cancel()` stops the repetition. Drift-free: the k-th call is due at start + k*period.
        """
        if period_s <= 0:
            raise ValueError(f"call_every: period_s must be > 0, got {period_s}")
        return _Periodic(self, period_s, fn, self._now_s if start_s is None else start_s)

    @staticmethod
    def cancel(handle) -> None:
        """Cancel a pending call returned by call_at/call_later (a no-op if it already ran)."""
        handle[2] = None

    def stop(self) -> None:
        """Make the current `run_until` return after the callback that is running."""
        self._stopped = True

    def run_until(self, end_s: float) -> None:
        """Run every callback due up to and including `end_s`, then set the clock to `end_s`."""
        self._stopped = False
        queue, pop = self._queue, heappop
        # virtual time waits for nothing: no call per event unless a subclass's `_wait_until` does wait
        wait = self._wait_until if type(self)._wait_until is not VirtualScheduler._wait_until else None
        while queue and queue[0][0] <= end_s and not self._stopped:
            t_s, _, fn, args = pop(queue)
            if fn is None:
                continue
            if wait is not None:
                wait(t_s)
            self._now_s = t_s
            fn(*args)
        if not self._stopped:
            self._wait_until(end_s)
            self._now_s = max(self._now_s, end_s)

    def _wait_until(self, t_s: float) -> None:
        """Virtual time does not wait; the real-time scheduler overrides this."""


class RealtimeScheduler(VirtualScheduler):
    """The same scheduler on the wall clock: each callback runs when its time has come (time.monotonic based).

    `wake()` may be called from another thread to make a sleeping scheduler look at its queue again.
    """

    def __init__(self, start_s: float = 0.0, poll_s: float = 0.002):
        super().__init__(start_s)
        self._t0 = time.monotonic() - start_s
        self._poll_s = poll_s

    def now_s(self) -> float:
        self._now_s = time.monotonic() - self._t0
        return self._now_s

    def call_at(self, t_s, fn, *args):
        self.now_s()
        return super().call_at(t_s, fn, *args)

    def _wait_until(self, t_s: float) -> None:
        while True:
            remaining_s = t_s - (time.monotonic() - self._t0)
            if remaining_s <= 0 or self._stopped:
                return
            time.sleep(min(remaining_s, self._poll_s))


class _Periodic:
    def __init__(self, scheduler, period_s, fn, start_s):
        self._scheduler = scheduler
        self._period_s = period_s
        self._fn = fn
        self._k = 0
        self._start_s = start_s
        self._handle = scheduler.call_at(start_s, self._fire)

    def _fire(self):
        now_s = self._start_s + self._k * self._period_s
        self._k += 1
        self._handle = self._scheduler.call_at(self._start_s + self._k * self._period_s, self._fire)
        self._fn(now_s)

    def cancel(self):
        self._scheduler.cancel(self._handle)
