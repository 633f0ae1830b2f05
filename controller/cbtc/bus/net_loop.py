"""One network loop for every MQTT connection of a process: epoll (selectors) over the paho clients' sockets, run by
the thread that runs the controller or the trains, so a message is handled where it is read, with no thread hop.

Paho's external-loop API: `loop_read` when a socket is readable (it calls the client's callbacks, which may publish:
paho queues a publish made inside a callback, and the loop writes it as soon as the callback returns), `loop_write`
while a client has bytes queued, `loop_misc` twice a second (keepalive pings, a dead broker noticed). A connection
that is lost is opened again with exponential backoff, as paho's own thread does (`PahoBus` sets the delays).
"""

import logging
import selectors
import time

log = logging.getLogger("cbtc.net")

MISC_PERIOD_S = 0.5


class NetLoop:
    """The sockets of the `PahoBus`es attached to it; `poll(timeout_s)` waits for and handles their traffic."""

    def __init__(self):
        self._selector = selectors.DefaultSelector()
        self._buses = []
        self._sockets = {}        # bus -> the socket registered for it
        self._changed = set()     # buses whose socket may have changed (opened, lost)
        self._writing = set()     # buses with bytes queued to write
        self._misc_due_s = 0.0
        self.errors = 0           # callbacks that raised (logged, never propagated)
        self.last_error = ""

    def attach(self, bus) -> None:
        if bus not in self._buses:
            self._buses.append(bus)
        self._changed.add(bus)

    def detach(self, bus) -> None:
        if bus in self._buses:
            self._buses.remove(bus)
        self._changed.discard(bus)
        self._writing.discard(bus)
        self._forget(bus)

    def socket_changed(self, bus) -> None:
        """The bus opened or lost its connection: (un)register its socket before the next wait."""
        self._changed.add(bus)

    def wants_write(self, bus) -> None:
        """The bus has bytes queued (a publish from inside a callback, or a full kernel buffer)."""
        self._writing.add(bus)

    def callback_failed(self, fn, exc: Exception) -> None:
        self.errors += 1
        self.last_error = f"{getattr(fn, '__qualname__', fn)}: {type(exc).__name__}: {exc}"
        log.exception("callback failed")

    def poll(self, timeout_s: float) -> int:
        """Wait up to `timeout_s` for traffic on any socket, handle what came; returns the sockets that had some."""
        now_s = time.monotonic()
        if now_s >= self._misc_due_s:
            self._misc_due_s = now_s + MISC_PERIOD_S
            for bus in self._buses:
                bus.net_misc(now_s)
        while self._changed:
            bus = self._changed.pop()
            if bus in self._buses:
                self._track(bus)
        if self._writing and self._flush():
            timeout_s = min(timeout_s, 0.001)   # the kernel's buffer was full: try again soon
        if not self._sockets:
            if timeout_s > 0:
                time.sleep(min(timeout_s, MISC_PERIOD_S))
            return 0
        events = self._selector.select(max(0.0, timeout_s))
        for key, _mask in events:
            key.data.net_read()
        if self._writing:
            self._flush()
        return len(events)

    def _flush(self) -> bool:
        """Write what the clients have queued; True if some is still waiting for room."""
        writing, self._writing = self._writing, set()
        for bus in writing:
            if bus.net_wants_write():
                bus.net_write()
                if bus.net_wants_write():
                    self._writing.add(bus)
        return bool(self._writing)

    def _track(self, bus) -> None:
        """Register the bus's current socket (a reconnect opens a new one; a loss leaves none)."""
        sock = bus.net_socket()
        old = self._sockets.get(bus)
        if sock is old:
            return
        self._forget(bus)
        if sock is not None:
            self._selector.register(sock, selectors.EVENT_READ, bus)
            self._sockets[bus] = sock

    def _forget(self, bus) -> None:
        old = self._sockets.pop(bus, None)
        if old is not None:
            try:
                self._selector.unregister(old)
            except (KeyError, ValueError, OSError):
                pass   # closed already: epoll dropped it with the file descriptor
