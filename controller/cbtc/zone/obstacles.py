"""What is on the track that the zone cannot command or vouch for: an obstacle to every train behind it.

A board reporting under an id the zone does not know, the second of two boards reporting under one id, the place a
train stood before its board restarted: each is an Obstacle. Its head was seen within a span of track at some times
(IPS fixes, balise reads: `see`); it may have moved since at up to `v_mps` either way, and it is `length_m` long, so
the track it may occupy grows with the age of what was seen. Never seen, it may be anywhere: every train is held.
Pure: positions and times in, spans out.
"""

from collections import deque

SEEN_KEPT_S = 2.0   # sightings older than the newest by more than this are dropped: the newest ones bound it
HULL_OF = 3         # the newest sightings whose hull bounds it


class Obstacle:
    def __init__(self, name: str, length_m: float, v_mps: float, owner: str = None, lapse_s: float = None):
        self.name = name          # says what it is, in a hold's reason and the alarm
        self.length_m = length_m  # head to tail, as long as the longest train it may be
        self.v_mps = v_mps        # how fast it may move, either way, since it was seen
        self.owner = owner        # a train id whose own authority it does not limit (its own old place)
        self.lapse_s = lapse_s    # not seen for this long, it is gone (None: it stays until the zone restarts)
        self._seen = deque()      # (t_s, low_s_m, high_s_m): the head within [low, high] (unwrapped) at t_s
        self.heard_s = None       # when it was last heard of, with a position or not

    def see(self, t_s: float, low_s_m: float, high_s_m: float) -> None:
        """Its head was within [low_s_m, high_s_m] (track positions, low <= high, on a loop possibly past its end)
        at controller time `t_s`."""
        self.hear(t_s)
        seen = self._seen
        seen.append((t_s, low_s_m, high_s_m))
        newest_s = max(t for t, _l, _h in seen)
        while len(seen) > 1 and seen[0][0] < newest_s - SEEN_KEPT_S:
            seen.popleft()

    @property
    def seen(self) -> bool:
        return bool(self._seen)

    def hear(self, t_s: float) -> None:
        """It was heard of at `t_s` (a report, with a position or not)."""
        if self.heard_s is None or t_s > self.heard_s:
            self.heard_s = t_s

    def lapsed(self, now_s: float) -> bool:
        """True once a lapsing obstacle has not been heard of for `lapse_s`."""
        return self.lapse_s is not None and self.heard_s is not None and now_s - self.heard_s > self.lapse_s

    def span(self, layout, now_s: float):
        """(tail_s_m, head_s_m, extent_m): the track it may occupy at `now_s`, from its rear-most tail forward over
        `extent_m` (on a loop wrapped; extent_m may reach the whole loop); None while never seen (anywhere). It is
        within the hull of its HULL_OF newest sightings, each widened by how far it may have moved since: one of them
        an outlier (an IPS fix a metre off) widens it, never moves it off the train."""
        newest = sorted(self._seen)[-HULL_OF:]
        if not newest:
            return None
        ring_m = layout.loop_length_m
        t0_s, low0_m, _high0 = newest[-1]
        low = high = None
        for t_s, low_m, high_m in newest:
            grown_m = self.v_mps * max(0.0, now_s - t_s)
            shift_m = 0.0 if ring_m is None else round((low0_m - low_m) / ring_m) * ring_m   # the same side of a seam
            lo, hi = low_m + shift_m - grown_m, high_m + shift_m + grown_m
            low, high = (lo, hi) if low is None else (min(low, lo), max(high, hi))
        extent_m = high - low + self.length_m
        if layout.closed:
            extent_m = min(extent_m, layout.length_m)
        return layout.wrap(low - self.length_m), layout.wrap(high), extent_m


def room_m(layout, front_s_m: float, span) -> float:
    """How far (m) a train whose front-most head is at `front_s_m` may go before it meets an obstacle occupying
    `span` (Obstacle.span): 0 when it is inside the span already; inf when the span is behind it on an open line."""
    tail_s, _head_s, extent_m = span
    if layout.closed:
        if extent_m >= layout.length_m:
            return 0.0
        to_tail_m = layout.ahead_m(front_s_m, tail_s)
        return 0.0 if to_tail_m > layout.length_m - extent_m else to_tail_m
    to_tail_m = tail_s - front_s_m
    if to_tail_m >= 0.0:
        return to_tail_m
    return 0.0 if front_s_m <= tail_s + extent_m else float("inf")
