"""What the boards of `cbtc trains` tell their user, at a bounded rate: the commands they refused (how many, the
newest reason, and what to do when it is a key that differs from the zone's), and a zone that has gone silent.

At most one line per train per `period_s` (10 s) for each: a flood of refused commands (a zone with other keys
answers every report) is a count, not a line each. Time is passed in.
"""

import logging
from dataclasses import dataclass

log = logging.getLogger("cbtc.trains")

PERIOD_S = 10.0


@dataclass
class _Seen:
    """What was last said of one board, and since when it has taken no command."""

    unit: object              # the OnboardUnit these counts are of (a reboot brings a new one)
    rejected_said: int        # its refused commands counted in the lines so far
    said_s: float = None      # when its last line was
    cseq: int = -1            # the newest command it took
    cseq_s: float = 0.0       # when that changed


class BoardNotes:
    """Watches `trains` (each with `.train_id` and its OnboardUnit `.obu`); `check(now_s)` logs what is due."""

    def __init__(self, trains, key_source: str, period_s: float = PERIOD_S):
        self.trains = list(trains)
        self.key_source = key_source
        self.period_s = period_s
        self._seen = {}   # train_id -> _Seen

    def check(self, now_s: float) -> None:
        for train in self.trains:
            unit = train.obu
            seen = self._seen.get(train.train_id)
            if seen is None or seen.unit is not unit:   # a (re)boot: its counters began again
                seen = self._seen[train.train_id] = _Seen(unit, unit.rejected, None, unit.cseq, now_s)
            if unit.cseq != seen.cseq:
                seen.cseq, seen.cseq_s = unit.cseq, now_s
            if seen.said_s is not None and now_s - seen.said_s < self.period_s:
                continue
            refused = unit.rejected - seen.rejected_said
            if refused:
                seen.rejected_said, seen.said_s = unit.rejected, now_s
                self._refused(train.train_id, refused, unit.last_reject or "")
            elif now_s - seen.cseq_s >= self.period_s:
                seen.said_s = now_s
                log.warning("train %s: no command taken for %.0f s while it reports: is `cbtc zone` running on this "
                            "broker, with this train's key (%s)?", train.train_id, now_s - seen.cseq_s,
                            self.key_source)

    def _refused(self, train_id, count, reason):
        advice = ""
        if "fails authentication" in reason:
            advice = (f"; the train's key (from {self.key_source}) is not the zone's: give both the same keys file "
                      f"(--keys FILE) or the same --sim-seed")
        log.warning("train %s: refused %d command%s since its last line; the newest: %s%s", train_id, count,
                    "" if count == 1 else "s", reason[:160], advice)
