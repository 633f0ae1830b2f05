"""The track the zone can vouch for: cleared by an operator (or a simulation from its truth) or swept by a train.

At its start and after a restart a zone knows nothing of the track between its trains: a train with no board, or one
put down while the zone was down, may stand anywhere on it. So every stretch is unknown, and occupied, until it is
cleared (`clear`) or a located train has covered it (the zone calls `clear` with the track the train's body has
certainly passed over: `sweep`). Track positions in, distances out.
"""

import logging
from math import inf, isfinite

from cbtc.errors import ConfigError

log = logging.getLogger("cbtc.zone")


class SweptTrack:
    def __init__(self, layout):
        self.layout = layout
        self.length_m = layout.length_m
        self._spans = []         # sorted, disjoint [low, high] within [0, length_m]: the track vouched for
        self.complete = False    # every metre vouched for: nothing left to look up

    @property
    def spans(self) -> list:
        """The stretches vouched for, as (low_m, high_m) track positions in order."""
        return [tuple(span) for span in self._spans]

    def vouch(self, spans, by: str) -> None:
        """`by` vouches that no vehicle but the zone's trains stands on `spans` ((from_m, to_m) track positions, each
        forward from `from_m`; None: the whole track). Track neither cleared nor swept by a located train is occupied:
        no authority reaches into it."""
        if spans is None:
            self.clear_all()
            log.info("%s cleared the whole track", by)
            return
        for from_m, to_m in spans:
            if not (isfinite(from_m) and isfinite(to_m)):
                raise ConfigError(f"track cleared by {by}: {from_m}-{to_m} m is not a stretch of track")
            self.clear(from_m, to_m if to_m > from_m or not self.layout.closed else to_m + self.layout.length_m)
        log.info("%s cleared %s of the track", by, ", ".join(f"{a:.2f}-{b:.2f} m" for a, b in spans) or "none")

    def clear_all(self) -> None:
        self._spans = [[0.0, self.length_m]]
        self.complete = True

    def clear(self, low_m: float, high_m: float) -> None:
        """Vouch for the track from `low_m` forward to `high_m` (track positions; on a loop it may run past the
        origin, `high_m` then being the further one unwrapped). A stretch of a loop's length or more is all of it."""
        if self.complete or not high_m > low_m:
            return
        length_m = self.length_m
        if self.layout.closed:
            if high_m - low_m >= length_m:
                self.clear_all()
                return
            low_w = low_m % length_m
            high_w = low_w + (high_m - low_m)
            if high_w > length_m:
                self._add(low_w, length_m)
                self._add(0.0, high_w - length_m)
            else:
                self._add(low_w, high_w)
        else:
            self._add(max(0.0, low_m), min(length_m, high_m))
        spans = self._spans
        self.complete = len(spans) == 1 and spans[0][0] <= 0.0 and spans[0][1] >= length_m

    def _add(self, low_m, high_m):
        if not high_m > low_m:
            return
        kept = []
        for span in self._spans:
            if span[1] < low_m or span[0] > high_m:
                kept.append(span)
            else:   # overlapping or touching: merged into the new one
                low_m, high_m = min(low_m, span[0]), max(high_m, span[1])
        kept.append([low_m, high_m])
        kept.sort()
        self._spans = kept

    def known_ahead_m(self, s_m: float) -> float:
        """How far (m) from track position `s_m` forward the track is vouched for: 0 when `s_m` is on unknown
        track; inf when all of it ahead is (on an open line, to its end)."""
        if self.complete:
            return inf
        length_m = self.length_m
        closed = self.layout.closed
        if closed:
            s_m %= length_m
        spans = self._spans
        for i, (low_m, high_m) in enumerate(spans):
            if low_m <= s_m <= high_m:
                if high_m < length_m:
                    return high_m - s_m
                if not closed:
                    return inf
                # runs to the origin: on across it into the span that starts there, if one does
                first = spans[0]
                if first[0] > 0.0 or i == 0:
                    return high_m - s_m
                return high_m - s_m + first[1]
        return 0.0

    def sweep(self, state, k_sigma):
        """Vouch for the track `state`'s train has certainly covered since its previous located report: from the
        front-most place its tail could have been then to the rear-most place its head can be now. Only a confirmed
        train sweeps (an unconfirmed one may be a lasting bias off), and not one whose train line opened (its tail car
        may be gone); one configured longer than it is would vouch for track behind its real tail."""
        est = state.newest_estimate()
        if est is None or not state.estimator.confirmed or "split" in state.report["flt"]:
            state.swept_from_m = None
            return
        k_m = k_sigma * est.sigma_s_m
        head_low_m = est.s_m - est.behind_m - k_m
        tail_high_m = est.s_m + est.ahead_m + k_m - state.setup.profile.length_m
        from_m = tail_high_m if state.swept_from_m is None else state.swept_from_m
        covered_m = head_low_m - from_m
        if self.layout.closed:   # the short way round: a train covers far less than a loop between two reports
            covered_m = (covered_m + 0.5 * self.layout.length_m) % self.layout.length_m - 0.5 * self.layout.length_m
        if covered_m > 0.0:
            self.clear(from_m, from_m + covered_m)
        state.swept_from_m = tail_high_m

    def clear_of(self, state, auth, k_sigma, margin_m):
        """`auth` cut short of the first track ahead of `state`'s front-most head that is neither cleared nor swept
        (its margin off)."""
        est = state.newest_estimate()
        front_s = self.layout.wrap(est.s_m + est.ahead_m + k_sigma * est.sigma_s_m)
        distance_m = self.known_ahead_m(front_s) - margin_m
        if distance_m < auth.distance_m:
            auth = auth.cut_to(max(0.0, distance_m), "track not swept or cleared ahead")
        return auth
