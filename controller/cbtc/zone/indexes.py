"""The zone's indexes over its trains, kept up to date so a report costs the same whatever the fleet: the located
trains in order along the track (TrainOrder), and the age of every train's newest report (ReportAges)."""

from bisect import bisect_left, bisect_right
from heapq import heappop, heappush

from cbtc.railway.ahead import ahead_index


class TrainOrder:
    def __init__(self, closed: bool):
        self.closed = closed      # a loop: the front train's leader is the rear one
        self.moved = set()        # states with a new report, or located afresh, since the order was last brought up
        self._order = []          # (s_m, rank, state) of the located trains, sorted
        self._placed = {}         # state -> its entry in _order
        self._located = []        # the states of _order, in its order (kept beside it, changed in place)

    def located(self, position_m):
        """Train states with a finite position estimate (`position_m(state)`: its head's, or None), ordered by head
        position along the track (ties in the zone's order). Only the trains whose position may have changed since
        (a report taken, located afresh) are placed again. The list is changed in place by the next call: read it at
        once, never change it."""
        if self.moved:
            moved = sorted(self.moved, key=lambda st: st.rank)
            self.moved.clear()
            for st in moved:
                old = self._placed.pop(st, None)
                if old is not None:
                    i = bisect_left(self._order, old)
                    del self._order[i]
                    del self._located[i]
                if st.report is not None and st.estimator.localized:
                    s_m = position_m(st)   # may locate it afresh (its filter failed): then None
                    if s_m is not None and st not in self.moved:
                        entry = (s_m, st.rank, st)
                        i = bisect_right(self._order, entry)
                        self._order.insert(i, entry)
                        self._located.insert(i, st)
                        self._placed[st] = entry
        return self._located

    def index_of(self, state):
        """`state`'s place in the newest `located()` list, or None when it is not in it."""
        entry = self._placed.get(state)
        return None if entry is None else bisect_left(self._order, entry)

    def leader_of(self, located, i):
        """The train ahead of `located[i]` (ordered by head position), or None: alone, or at the front of an open
        line, where the end of the track limits it."""
        j = ahead_index(len(located), i, self.closed)
        return None if j is None else located[j]


class ReportAges:
    def __init__(self, n_trains: int):
        self.unheard = n_trains   # trains that have not reported yet
        self._heard = []          # heap of (receive time, rank, state) of reports taken; entries a newer report of
        #                           its train replaced are dropped when they come to the top

    def took(self, state, recv_s):
        """`state`'s train reported at `recv_s`; called before its `report_recv_s` is set to it."""
        if state.report_recv_s is None:
            self.unheard -= 1
        if state.report_recv_s != recv_s:   # one entry a train in the heap for each receive time
            heappush(self._heard, (recv_s, state.rank, state))

    def other_stale(self, state, now_s, max_age_s):
        """True when the data of some train but `state`'s is older than `max_age_s` at `now_s`. The oldest report
        taken of another train decides: the heap has it at the top, or just below `state`."""
        if self.unheard > (state.report_recv_s is None):
            return True   # some other train has not reported at all
        heard = self._heard
        oldest = self._oldest()
        if oldest is None:
            return False
        if oldest[2] is state:
            heappop(heard)
            other = self._oldest()
            heappush(heard, oldest)
            oldest = other
        return oldest is not None and now_s - oldest[0] > max_age_s

    def _oldest(self):
        """The heap's top entry once every entry a newer report replaced is dropped from it; None when empty."""
        heard = self._heard
        while heard and heard[0][0] != heard[0][2].report_recv_s:
            heappop(heard)
        return heard[0] if heard else None
