"""Refused messages and other per-train events, counted per train and class and logged at a bounded rate, never with
the sender's text at length.

A flood of bad payloads (a broken board, a stranger) must neither drown the log nor grow the controller's memory:
each (train, class) pair logs at most once per `period_s` (10 s), with the count since it last did, and the reason
cut to REASON_CHARS; messages for trains the zone does not know share one pair, so the table never grows past the zone's
trains times the classes. Time is passed in.
"""

import logging

REASON_CHARS = 100
UNKNOWN = "?"     # the train column of messages whose topic names no train of this zone


def short(text: str, limit: int = REASON_CHARS) -> str:
    """`text` cut to `limit` characters (with '...'), and printable: a reason may carry a sender's value."""
    text = "".join(ch if ch.isprintable() else "?" for ch in text[:limit + 1])
    return text if len(text) <= limit else text[:limit - 3] + "..."


class RefusalLog:
    def __init__(self, logger: logging.Logger, period_s: float = 10.0):
        self.logger = logger
        self.period_s = period_s
        self.counts = {}          # (train, class) -> refused in all
        self._unsaid = {}         # (train, class) -> refused since the pair last logged
        self._said_s = {}         # (train, class) -> when it last logged

    def note(self, train_id: str, klass: str, reason: str, now_s: float, advice: str = "") -> None:
        """Count one refusal of `klass` for `train_id` (UNKNOWN for a train this zone does not know); log it with
        the count since the last line of the pair, unless that line is younger than `period_s`. `reason` is cut (it
        may carry a sender's value); `advice`, the zone's own words on what to do, is not."""
        key = (train_id, klass)
        self.counts[key] = self.counts.get(key, 0) + 1
        self._unsaid[key] = self._unsaid.get(key, 0) + 1
        said_s = self._said_s.get(key)
        if said_s is not None and now_s - said_s < self.period_s:
            return
        count = self._unsaid.pop(key)
        self._said_s[key] = now_s
        who = "unknown train" if train_id == UNKNOWN else "train " + train_id
        more = "" if count == 1 else f" (x{count} since this line last)"
        self.logger.warning("%s: %s%s: %s%s", who, klass, more, short(reason), advice and "; " + advice)

    def total(self, train_id: str = None) -> int:
        return sum(n for (t, _k), n in self.counts.items() if train_id is None or t == train_id)
