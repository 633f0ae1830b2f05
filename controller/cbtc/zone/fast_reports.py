"""Fast reports: which trains report at the fast rate, within the report rate the controller is sized for.

A train whose follower is held by it is asked for fast reports for a while (`want`): its follower's authority rests
on the age of that data. The controller grants them (`granted`) to at most `slots` trains at once, those whose
followers have the least authority left first.
"""

from bisect import bisect_left, insort

from cbtc.firmware import obu


def fast_report_slots(report_budget_hz: float, n_trains: int, params) -> int:
    """How many trains may report fast at once within `report_budget_hz`, the reports a second the controller is
    sized for (`cbtc bench latency` measures what it takes): every train reports at the board's own rate, and what is
    left pays for fast reports, each fast train costing the difference."""
    base_hz = 1000.0 / obu.DEFAULTS["report_ms"]
    extra_hz = 1000.0 / params.fast_report_ms - base_hz
    spare_hz = report_budget_hz - base_hz * n_trains
    return max(0, int(spare_hz // extra_hz)) if extra_hz > 0 else n_trains


class FastReports:
    def __init__(self, slots: int, hold_s: float):
        self.slots = slots        # trains that may report fast at once
        self.hold_s = hold_s      # a train asked is asked for this long (AuthorityParams.fast_hold_s)
        self._wanting = {}        # train id -> state, trains asked for fast reports (some may have lapsed)
        self._lapse_s = 0.0       # none of them lapses before then (so they need no sweep for lapsed ones)
        self._ranked = []         # (authority left to the follower m, train id) of each of them, sorted

    def granted(self, state, now_s) -> bool:
        """True when `state`'s train is to report fast: a train behind is held by it, and it is among the `slots`
        trains whose followers have the least authority left."""
        if now_s >= state.fast_until_s or not self.slots:
            return False
        wanting = self._wanting
        if len(wanting) <= self.slots:   # it is among them: no more of them than slots
            return True
        if now_s >= self._lapse_s:
            for st in [st for st in wanting.values() if now_s >= st.fast_until_s]:
                del wanting[st.train_id]
                self._unrank(st)
            # a train's time only grows, and one asked from now on is asked until now + hold_s at least
            self._lapse_s = min([st.fast_until_s for st in wanting.values()] + [now_s + self.hold_s])
            if len(wanting) <= self.slots:
                return True
        # its place among them, least authority left first (ties by id)
        return bisect_left(self._ranked, (state.fast_need_m, state.train_id)) < self.slots

    def want(self, state, need_m, now_s):
        """`state`'s follower is held by it with `need_m` of authority left: ask it for fast reports for a while."""
        state.fast_until_s = now_s + self.hold_s
        if state.train_id in self._wanting:
            if state.fast_need_m == need_m:
                return
            self._unrank(state)
        else:
            self._wanting[state.train_id] = state
        state.fast_need_m = need_m
        insort(self._ranked, (need_m, state.train_id))

    def _unrank(self, state):
        ranked = self._ranked
        del ranked[bisect_left(ranked, (state.fast_need_m, state.train_id))]
