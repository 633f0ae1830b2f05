"""The UKF estimator's history: each measurement as an event at its own board time, and the filter's state after
it with the counters that depend on which measurements were used (cbtc.estimation.ukf_estimator replays them)."""

from math import isfinite

from numpy.linalg import LinAlgError

from cbtc.estimation.track_ukf import cholesky_upper
from cbtc.railway.geometry import circular_offset_m

_KIND_RANK = {"roll": 0, "step": 1, "odo": 2, "tag": 3, "ips": 4, "range": 5}


class FilterEvent:
    """One measurement at board time `t_s`. Events sort by time, then kind and value, never by arrival, so the same
    measurements give the same filter whatever order they came in."""

    __slots__ = ("t_s", "kind", "data", "sort_key")

    def __init__(self, t_s, kind, data):
        self.t_s = t_s
        self.kind = kind      # "odo": (d_m, v_mps); "ips": (x_m, y_m); "tag": (tag_s_m, d_m, in_field, span_s);
        #                       "roll": (step_m, run_m: the roll's steps before, d_m); "range": (radio_x_m, radio_y_m,
        #                       range_m, sigma_m); "step": (the step's share of the newest travel m, scale sigma)
        self.data = data
        self.sort_key = (t_s, _KIND_RANK[kind], data)


class FilterState:
    """The filter after an event, with the counters that depend on which measurements were used."""

    __slots__ = ("snap", "ips_used", "ips_rejected", "tags_used", "tags_rejected", "gated", "relocations",
                 "consensus", "innovations", "disagree", "disagreements", "tag_offset", "speed_steps", "doubt",
                 "pending", "agreeing", "reach", "tag_story", "vouched", "ips_d_m")

    def __init__(self, snap, ips_used=0, ips_rejected=0, tags_used=0, tags_rejected=0, gated=(), relocations=0,
                 consensus=None, innovations=(), disagree=None, disagreements=0, tag_offset=None, speed_steps=0,
                 doubt=None, pending=None, agreeing=0, reach=None, tag_story=None, vouched=None,
                 ips_d_m=None):
        self.snap = snap
        self.ips_used = ips_used
        self.ips_rejected = ips_rejected
        self.tags_used = tags_used
        self.tags_rejected = tags_rejected
        self.gated = gated             # anchors (fix s - odometer, m) of the current run of gated IPS fixes
        self.relocations = relocations
        self.consensus = consensus     # (low_m, high_m, anchor_m, sigma_m): where the agreeing gated fixes put the
        #                                train, as offsets from the filter's position, and their anchor; or None
        self.innovations = innovations  # along-track innovations (m) of the newest IPS fixes, gated or not
        self.disagree = disagree       # (low_m, high_m): how far behind (<= 0) and ahead (>= 0) of the filter's
        #                                position the IPS may put the train; None while they agree
        self.disagreements = disagreements   # runs of disagreement begun
        self.tag_offset = tag_offset   # where the newest gated balise read puts the train, less the filter's position
        #                                (m); None while no read disagrees, or once the IPS has shown it wrong
        self.speed_steps = speed_steps  # reported speeds that changed faster than the train can: the wheel slipped
        self.doubt = doubt             # (low_m, high_m): where the train may be, behind (<= 0) and ahead (>= 0) of the
        #                                filter's position, from before it was located afresh; None once a balise
        #                                read has confirmed the position (keep_doubt), or while the placement awaits
        #                                its second reference (`pending`)
        self.pending = pending         # what placed the train, "ips" or "tag", while no second, independent reference
        #                                has confirmed it (a balise; after a tag, a second tag or the IPS); None: both
        self.agreeing = agreeing       # IPS fixes in a row the filter took since a tag placed the train
        self.reach = reach             # (low_s_m, high_s_m, d_m, ref_d_m): where the head may be when the odometer
        #                                read d_m, from the last balise (or placement, at odometer ref_d_m) on by the
        #                                wheel alone, at the lowest and highest scale the filter allows: what no IPS
        #                                bias can move (dead reckoning)
        self.tag_story = tag_story     # where the newest balise read, gated, put the train less the filter's
        #                                position (m); None once a read is taken, or when the IPS shows it wrong
        self.vouched = vouched         # (d0_m, s0_m, spread0_m, low, high): the first balise read taken since the
        #                                wheel was last in doubt (odometer, head, its spread) and the scale band the
        #                                travel from it to the newest read allows (None until long enough): what the
        #                                balises, not the IPS, say of the wheel (BaliseReads.vouch); None: no read yet
        self.ips_d_m = ips_d_m         # the odometer (m) at the newest IPS fix the filter took; None: none yet

    def healthy(self) -> bool:
        """Its filter is finite and its covariance positive definite."""
        _t, x, P = self.snap
        if not isfinite(sum(x) + sum(map(sum, P))):   # a NaN or an infinity anywhere
            return False
        try:
            cholesky_upper(P)
        except LinAlgError:
            return False
        return True

    def covered(self, s_m, sigma_s_m, ring_m):
        """(ahead_m, behind_m) the estimate at `s_m` (1-sigma `sigma_s_m`) covers beyond its position: where the IPS
        or a balise may put the train, the doubt kept, and where the wheel alone from the last balise puts the head
        beyond 3 sigma (whatever the IPS has pulled the filter to)."""
        ahead_m = behind_m = 0.0
        if self.disagree is not None:
            ahead_m, behind_m = max(0.0, self.disagree[1]), max(0.0, -self.disagree[0])
        if self.tag_offset is not None:
            ahead_m, behind_m = max(ahead_m, self.tag_offset), max(behind_m, -self.tag_offset)
        if self.doubt is not None:
            ahead_m, behind_m = max(ahead_m, self.doubt[1]), max(behind_m, -self.doubt[0])
        reach = self.reach
        if reach is not None:
            low_m = circular_offset_m(reach[0], s_m, ring_m) + 3.0 * sigma_s_m
            high_m = circular_offset_m(reach[1], s_m, ring_m) - 3.0 * sigma_s_m
            if low_m < -behind_m:
                behind_m = -low_m
            if high_m > ahead_m:
                ahead_m = high_m
        return ahead_m, behind_m

    def copy_with(self, snap):
        return FilterState(snap, self.ips_used, self.ips_rejected, self.tags_used, self.tags_rejected, self.gated,
                      self.relocations, self.consensus, self.innovations, self.disagree, self.disagreements,
                      self.tag_offset, self.speed_steps, self.doubt, self.pending, self.agreeing, self.reach,
                      self.tag_story, self.vouched, self.ips_d_m)
