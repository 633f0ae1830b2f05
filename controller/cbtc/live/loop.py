"""The wall-clock loop of a live run on a real broker, shared by `cbtc zone`, `cbtc trains` and `cbtc bench`.

A `LiveLoop` runs a `NetScheduler` in the main thread: while it waits for its next task it polls the `NetLoop` that
every `PahoBus(net=loop.net)` of the process is attached to, so a message is read and handled in this thread the
moment it arrives, never during a controller cycle or a train's loop, with no network thread and no hand-over between
threads. Ctrl-C (SIGINT) or SIGTERM ends the loop cleanly after the running task.
"""

import signal
import time

from cbtc.bus.net_loop import NetLoop
from cbtc.scheduler import RealtimeScheduler


class NetScheduler(RealtimeScheduler):
    """The wall-clock scheduler (scheduler.RealtimeScheduler, unchanged in order and timing of its tasks) that polls
    its `net` loop while waiting for the next task."""

    def __init__(self, start_s: float = 0.0):
        super().__init__(start_s)
        self.net = NetLoop()

    def _wait_until(self, t_s: float) -> None:
        while True:
            remaining_s = t_s - (time.monotonic() - self._t0)
            self.net.poll(max(0.0, remaining_s))
            if remaining_s <= 0 or self._stopped:
                return


class LiveLoop:
    """A NetScheduler and the way to run it until Ctrl-C or for a duration."""

    def __init__(self):
        self.scheduler = NetScheduler()
        self.net = self.scheduler.net
        self.stopping = False

    def now_s(self) -> float:
        return self.scheduler.now_s()

    def install_signal_handlers(self) -> None:
        """Ctrl-C and SIGTERM end `run` after the running task (no KeyboardInterrupt in the middle of a cycle)."""
        signal.signal(signal.SIGINT, self.request_stop)
        signal.signal(signal.SIGTERM, self.request_stop)

    def request_stop(self, *_signal_args) -> None:
        self.stopping = True
        self.scheduler.stop()

    def run(self, duration_s: float = None) -> None:
        """Run until stopped, or for `duration_s` seconds of wall time from now."""
        end_s = None if duration_s is None else self.now_s() + duration_s
        while not self.stopping:
            until_s = self.now_s() + 0.25
            if end_s is not None:
                if until_s >= end_s:
                    self.scheduler.run_until(end_s)
                    return
            self.scheduler.run_until(until_s)

    def pause(self, wait_s: float) -> None:
        """Keep handling messages and tasks for `wait_s` seconds, even while stopping."""
        self.stopping = False
        self.run(wait_s)
