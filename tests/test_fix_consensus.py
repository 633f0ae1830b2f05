"""Placing a train only where IPS fixes agree: the consensus of anchors, by hand."""

import pytest

from cbtc.estimation.fix_consensus import agreeing_anchor, circular_offset_m


def test_offsets_take_the_short_way_round_a_loop():
    assert circular_offset_m(0.02, 6.79, 6.81) == pytest.approx(0.04)
    assert circular_offset_m(6.79, 0.02, 6.81) == pytest.approx(-0.04)
    assert circular_offset_m(6.79, 0.02) == pytest.approx(6.77)     # an open line


def test_three_agreeing_fixes_outvote_an_outlier():
    # sigma 5 cm: two fixes of one place differ by 3 * sqrt(2) * 5 = 21 cm at most; the outlier is 0.7 m off
    anchor, count = agreeing_anchor([1.70, 1.02, 0.99, 1.03], 0.05, 3)
    assert count == 3 and anchor == pytest.approx(1.0133, abs=1e-4)
    assert agreeing_anchor([1.70, 1.02, 0.99], 0.05, 3) is None, "two agree: not enough"
    assert agreeing_anchor([], 0.05, 3) is None


def test_agreement_across_the_seam_of_a_loop():
    anchor, count = agreeing_anchor([6.80, 0.01, 6.79], 0.05, 3, length_m=6.81)
    assert count == 3 and anchor == pytest.approx((6.80 + 6.82 + 6.79) / 3, abs=1e-9)   # 0.01 is 6.82
