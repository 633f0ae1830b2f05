"""The simulated train-to-train ranging driver: the true gap to the train ahead, through the RangingSensor model.

Same duck type as a board's ranging driver (`poll(now_ms) -> gap_mm | None`), read by the OnboardUnit's collision guard.
A new averaged measurement (cbtc.ranging.transponder.RangingSensor: 100 ms running mean of coded two-way exchanges) is
ready every `period_ms`; between them `poll` returns None. The gap is measured from the truth, so the guard sees where
the leader really is, whatever the zone controller believes.
"""

from cbtc.ranging.transponder import RangingSensor


def true_gap_m(layout, follower, others):
    """True distance (m) from `follower`'s head to the nearest tail ahead among `others` (virtual trains); negative
    when the head is inside another train; None when there is no other train."""
    best = None
    head = follower.head_s
    for other in others:
        if other is follower:
            continue
        tail = other.tail_s
        if layout.ahead_m(tail, head) <= other.length_m and (layout.closed or head >= tail):
            gap = -layout.ahead_m(tail, head)
        else:
            gap = layout.ahead_m(head, tail)
            if not layout.closed and gap < 0:
                continue
        if best is None or gap < best:
            best = gap
    return best


class SimRanging:
    """Ranging from one virtual train to the train ahead; `trains` is the list it searches (may fill in later)."""

    def __init__(self, layout, trains, index, sensor: RangingSensor, rng, period_ms=100):
        self._layout = layout
        self._trains = trains
        self._index = index
        self.sensor = sensor
        self._rng = rng
        self.period_ms = period_ms
        self._next_ms = None
        self.measurements = 0
        self.dropped = 0

    def poll(self, now_ms):
        if self._next_ms is None:
            self._next_ms = now_ms + self.period_ms
            return None
        if now_ms < self._next_ms:
            return None
        while self._next_ms <= now_ms:
            self._next_ms += self.period_ms
        me = self._trains[self._index]
        gap_m = true_gap_m(self._layout, me, self._trains)
        measured, _quality = self.sensor.measure(gap_m, self._rng)
        if measured is None:
            self.dropped += 1
            return None
        self.measurements += 1
        return int(round(measured * 1000))
