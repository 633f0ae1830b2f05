"""Each train's estimator: fed with the train's accepted reports, or started afresh when what it rests on is lost (an
encoder failed, an odometer jumped, a filter raised or turned non-finite)."""

import hashlib
import logging

from cbtc.estimation.estimate import span_offsets_m
from cbtc.zone import plausibility
from cbtc.zone.handover import declare_handed
from cbtc.zone.refusals import short

log = logging.getLogger("cbtc.zone")
ENCODER_FAULTS = frozenset(("enc_fail", "enc_stall"))   # its odometer cannot be trusted: locate the train afresh


class Estimators:
    def __init__(self, layout, params, refusals, factory):
        self.layout = layout
        self.params = params
        self.refusals = refusals
        self.factory = factory   # (layout, profile) -> a fresh estimator
        self.facing = None       # on a line trains reverse on: cbtc.zone.turns.Turns, which faces a train first seen

    def fresh(self, state):
        """A new estimator for `state`'s train, knowing nothing."""
        return self.factory(state.sensor_frame, state.setup.profile)

    def feed(self, state, report, previous, payload, recv_s):
        """Hand an accepted report to the train's estimator, unless its encoder failed or its odometer jumped (then
        the train is located afresh); the report as taken (its tags dropped when the odometer's frame changed)."""
        if not state.faced:   # on a line: which way the train faces
            self.facing.face(state, report)
        faults = ENCODER_FAULTS.intersection(report["flt"])
        jump_mm = 0 if previous is None else plausibility.odometer_jump_mm(report, previous,
                                                                           state.setup.profile.v_noload_mps)
        if faults:
            # the board has tripped and its odometer may be anywhere: a fresh estimator, fed from the first healthy
            # report on, locates the train again before it gets authority
            if not state.encoder_failed:
                state.encoder_failed = True
                state.encoder_failures += 1
                self.refusals.note(state.train_id, "encoder failed", f"{', '.join(sorted(faults))}: no authority "
                                   f"until it reports healthy and is located again; meanwhile every train is held (it "
                                   f"brakes to a stop within the authority it holds)", recv_s)
            self.relocate_wheel_lost(state)
            state.estimator.distrust_wheel()   # what the wheel read before says nothing of how it reads now
        else:
            state.encoder_failed = False
            if jump_mm:
                # an odometer the train cannot have travelled: its frame starts again with this report
                state.odometer_jumps += 1
                self.refusals.note(state.train_id, "odometer jump", f"{jump_mm} mm further than the train can travel: "
                                   f"locating it afresh", recv_s)
                self.relocate_wheel_lost(state)
                if report["tags"]:   # stamped with an odometer of either frame: none places the fresh estimate
                    state.measurements_dropped += len(report["tags"])
                    report = dict(report, tags=[])
            if state.handed is not None:
                declare_handed(state, report)
            state.estimator.on_report(report, state.clock)
            if state.estimator.localized and not state.estimator.doubt_kept:
                state.doubt_span = None   # a balise has confirmed where it is
            if not self._filter_healthy(state):
                self.train_failed(state, ValueError("its filter turned non-finite or lost positive definiteness"),
                                   "updating its filter", payload, recv_s)
        return report

    def relocate_wheel_lost(self, state):
        """Start the train's estimator afresh (its odometer is lost). When its sensors disagreed just before (an IPS
        off by a metre, or the wheel), either may be the one that is wrong: the fresh estimator is handed where the
        estimate covered the train (UkfEstimator.keep_doubt), so fixes alone do not place it, nor its follower's
        authority, outside that; the span is kept, not widened again, over further restarts until a balise confirms
        the position."""
        if state.report is not None and state.estimator.localized:
            est = state.newest_estimate()
            if est is not None:
                widen_m = self.params.k_sigma * est.sigma_s_m
                if state.doubt_span is None:
                    if est.ahead_m or est.behind_m:   # its sensors disagreed: either may be the one that is wrong
                        state.doubt_span = (est.s_m - est.behind_m - widen_m, est.s_m + est.ahead_m + widen_m)
                else:   # still unconfirmed: the span kept, and where it was placed since (not widened again)
                    behind_m, ahead_m = span_offsets_m(state.frame, state.doubt_span, est.s_m)
                    state.doubt_span = (est.s_m + min(behind_m, -est.behind_m, -widen_m),
                                        est.s_m + max(ahead_m, est.ahead_m, widen_m))
        state.relocate(self.fresh(state))
        if state.doubt_span is not None:
            state.estimator.keep_doubt(*state.doubt_span)

    @staticmethod
    def _filter_healthy(state):
        healthy = getattr(state.estimator, "healthy", None)
        return healthy is None or healthy()

    def train_failed(self, state, exc, where, payload, now_s):
        """An exception in one train's handling: said once per kind with the payload's digest, never the payload;
        the train is located afresh (its filter may hold anything) and gets no authority until it is."""
        state.failures += 1
        kind = type(exc).__name__
        if kind not in state.failures_said:
            state.failures_said.add(kind)
            data = payload if isinstance(payload, (bytes, bytearray)) else repr(payload).encode()
            log.error("train %s: %s raised %s (%s; payload sha256 %s): locating it afresh, no authority until then",
                      state.train_id, where, kind, short(str(exc)), hashlib.sha256(data).hexdigest()[:16])
        state.relocate(self.fresh(state))
