"""Whether the IPS agrees with a train's filter: the bias of its newest fixes, the consensus of the fixes the filter
gated, and the disagreement they make (how far behind or ahead of the filter the IPS may put the train)."""

import statistics
from math import sqrt

from cbtc.estimation.fix_consensus import agreeing_anchor
from cbtc.railway.geometry import circular_offset_m


class IpsAgreement:
    def __init__(self, layout, profile, params):
        self.layout = layout
        self.profile = profile   # its ips_sigma_m
        self.params = params     # UkfParams: relocate_after, locate_fixes

    def disagreement(self, consensus, innovations):
        """(low_m, high_m) that the IPS may put the train behind or ahead of the filter's position: from the gated
        fixes that agree, and from a bias of the newest fixes, gated or not (their median, beyond 4 sigma of a
        median); None when they agree with it."""
        low = high = 0.0
        if consensus is not None:
            low, high = min(0.0, consensus[0]), max(0.0, consensus[1])
        bias = self.bias(innovations)
        if bias is not None and abs(bias[0]) > 4.0 * bias[1]:
            bias_m, sigma_m = bias
            low, high = min(low, bias_m - 3.0 * sigma_m), max(high, bias_m + 3.0 * sigma_m)
        if low == high == 0.0:
            return None
        return low, high

    def refutes(self, innovations, offset_m) -> bool:
        """The newest IPS fixes agree with the filter (their median within 2 sigma of it) and not with a balise read
        `offset_m` away (beyond 4 sigma): the read was wrong."""
        bias = self.bias(innovations)
        if bias is None:
            return False
        bias_m, sigma_m = bias
        return abs(bias_m) <= 2.0 * sigma_m and abs(bias_m - offset_m) > 4.0 * sigma_m

    def bias(self, innovations):
        """(median, its 1-sigma) of the newest IPS fixes' innovations (m, up to bias_fixes of them); None while fewer
        than relocate_after."""
        if len(innovations) < self.params.relocate_after:
            return None
        return (statistics.median(innovations),
                1.25 * self.profile.ips_sigma_m / sqrt(len(innovations)))   # sigma of a median of normals

    def consensus(self, s_m, d_m, anchors_m):
        """(low_m, high_m, anchor_m, sigma_m) where `locate_fixes` of the gated IPS `anchors_m` agree: the span of
        their offsets from the filter's position `s_m` (odometer `d_m`), widened by three sigma of their consensus;
        None when too few agree."""
        placed = self.agreeing(anchors_m)
        if placed is None:
            return None
        anchor_m, sigma_m = placed
        ring_m = self.layout.loop_length_m
        gate_m = 3.0 * sqrt(2.0) * self.profile.ips_sigma_m
        offsets = [circular_offset_m(a + d_m, s_m, ring_m) for a in anchors_m
                   if abs(circular_offset_m(a, anchor_m, ring_m)) <= gate_m]
        return min(offsets) - 3.0 * sigma_m, max(offsets) + 3.0 * sigma_m, anchor_m, sigma_m

    def agreeing(self, anchors_m):
        """(anchor_m, sigma_m) where at least `locate_fixes` of the IPS anchors agree, sigma twice the IPS sigma over
        the root of their number; None when they do not."""
        found = agreeing_anchor(anchors_m, self.profile.ips_sigma_m, self.params.locate_fixes,
                                self.layout.loop_length_m)
        if found is None:
            return None
        return found[0], 2.0 * self.profile.ips_sigma_m / sqrt(found[1])
