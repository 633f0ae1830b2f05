"""The wall-clock loop of a live run on a real broker, shared by `cbtc zone`, `cbtc trains` and `cbtc bench`.

A `LiveLoop` runs an `InboxScheduler` in the main thread: messages that paho receives on its thread are queued in the
bus `Inbox`, which wakes the scheduler; the scheduler runs them while it waits for its next task, so they are handled
at once, in the scheduler's thread, never during a controller cycle or a train's loop. Ctrl-C (SIGINT) or SIGTERM
ends the loop cleanly after the running task.
"""

import signal
import sys
import threading
import time

from cbtc.bus.paho_bus import Inbox
from cbtc.scheduler import RealtimeScheduler


class InboxScheduler(RealtimeScheduler):
    """The wall-clock scheduler (scheduler.RealtimeScheduler, unchanged in order and timing of its tasks) that,
    while waiting for the next task, runs the calls other threads put in its `inbox`, woken by each put."""

    def __init__(self, start_s: float = 0.0):
        super().__init__(start_s)
        self._woken = threading.Event()
        self.inbox = Inbox(notify=self._woken.set)

    def _wait_until(self, t_s: float) -> None:
        while True:
            self._woken.clear()
            self.inbox.drain()
            remaining_s = t_s - (time.monotonic() - self._t0)
            if remaining_s <= 0 or self._stopped:
                return
            self._woken.wait(remaining_s)


class LiveLoop:
    """An InboxScheduler and the way to run it until Ctrl-C or for a duration."""

    def __init__(self, gil_switch_s: float = 0.0005):
        # paho's network threads must get the GIL soon after a publish from this thread (default 5 ms is a
        # whole extra latency budget); a shorter switch interval costs little in a process that mostly waits
        sys.setswitchinterval(gil_switch_s)
        self.scheduler = InboxScheduler()
        self.inbox = self.scheduler.inbox
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
