"""Placing a train from IPS fixes without trusting any single one: pure functions.

About one IPS fix in a hundred is an outlier 0.3-1 m off (a reflection, a beacon seen through a wall). A train placed
by one such fix can be put ahead of the train in front of it and granted that train's whole gap. So a position is
taken only where several fixes agree. Fixes taken at different times are compared as anchors, the track position of
the fix less the odometer reading at its time: a train that moves between fixes keeps the same anchor.
"""

import math

from cbtc.railway.geometry import circular_offset_m


def agreeing_anchor(anchors_m, sigma_m: float, need: int, length_m: float = None, gate_sigmas: float = 3.0):
    """(anchor_m, count): the mean of the largest group of `anchors_m` that lie within `gate_sigmas` standard
    deviations of a difference of two fixes (sigma_m each) of one of them, when that group has at least `need`
    members; None otherwise. Ties go to the newest anchor (the last in the list)."""
    gate_m = gate_sigmas * math.sqrt(2.0) * sigma_m
    best = None
    for centre in anchors_m:
        offsets = [circular_offset_m(a, centre, length_m) for a in anchors_m]
        group = [d for d in offsets if abs(d) <= gate_m]
        if best is None or len(group) >= len(best[1]):
            best = (centre, group)
    if best is None or len(best[1]) < need:
        return None
    centre, group = best
    anchor_m = centre + sum(group) / len(group)
    return (anchor_m % length_m if length_m else anchor_m), len(group)
