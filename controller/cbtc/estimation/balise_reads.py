"""What a balise read tells against a train's filter: where it puts the head (its story), the reach it gives
(where the head may be by the wheel alone from it on), and, for a read the filter gated, whether it settles a
disagreement (arbitrate), repeats the read before it, or re-places the train."""

from math import hypot, sqrt

from cbtc.estimation.ukf_model import D, K, S, V, tag_read_model
from cbtc.estimation.ukf_params import SCALE_K_SIGMA, WHEEL_HIGHEST, WHEEL_LOWEST
from cbtc.railway.geometry import circular_offset_m

STORY_TOL_M = 0.1    # two gated balise reads in a row whose stories differ by no more (m) tell the same story
WORN_SHARE = 0.15    # ... that a wheel this far wrong (worn, dirty, slipping: of the travel) can tell
VOUCH_M = 0.3        # balise reads this much further apart than their spreads vouch for the wheel's scale
DARK_M = 0.3         # odometer metres past the newest IPS fix taken after which the IPS no longer watches the wheel


def wheel_band(vouched, ips_d_m, d_m, prior):
    """(low, high) odometer m per true m the wheel reads at odometer `d_m`: the band the balises vouched for
    (BaliseReads.vouch) while the IPS watches the wheel (a fix taken `ips_d_m` within DARK_M of travel), else joined
    with the prior band (1 -+ `prior`): a wheel may change after the reads that vouched for it (dirt, a tyre come
    off), and between balises only the IPS would show it."""
    low, high = 1.0 - prior, 1.0 + prior
    if vouched is None or vouched[3] is None:
        return low, high
    if ips_d_m is not None and abs(d_m - ips_d_m) <= DARK_M:
        return vouched[3], vouched[4]
    return min(low, vouched[3]), max(high, vouched[4])


class BaliseReads:
    def __init__(self, layout, noise, params):
        self.layout = layout
        self.noise = noise     # NoiseModel: the tag read's model
        self.params = params   # UkfParams: scale_sigma, tag_bias_m

    def arbitrate(self, f, consensus, tag_s_m, d_m, in_field, span_s):
        """A balise read the filter gated, while the IPS disagrees with it: when the read agrees with the IPS (within
        three sigma of both), the wheel was wrong: the position restarts at the balise. True when it did."""
        _low, _high, anchor_m, sigma_m = consensus
        offset_m, var_m2 = tag_read_model(self.noise, float(f.mean[V]) * span_s, in_field)
        read_s_m = tag_s_m - offset_m
        tag_sigma_m = sqrt(var_m2)
        ring_m = self.layout.loop_length_m
        if abs(circular_offset_m(anchor_m + d_m, read_s_m, ring_m)) > 3.0 * hypot(sigma_m, tag_sigma_m):
            return False
        f.relocate(self.layout.wrap(read_s_m + float(f.mean[D]) - d_m), tag_sigma_m)
        if f.n > K:   # the wheel was wrong: its scale is learnt afresh from the fixes that follow
            f.reopen_scale(3.0 * self.params.scale_sigma)
        return True

    def reckon(self, f, reach, d_m, scale_sigma0, vouched=None, ips_d_m=None):
        """`reach` carried to odometer `d_m` by the wheel alone, at the lowest and highest scale the filter (`f`)
        allows (3 sigma; `scale_sigma0`: the scale's sigma while it is not in the state) or the balises (wheel_band
        of `vouched` and `ips_d_m`, the newest IPS fix's odometer), within the band a wheel can have: a scale the IPS
        taught the filter (a biased IPS teaches a wrong one) never narrows what the balises allow."""
        if reach is None:
            return None
        low_s_m, high_s_m, d0_m, ref_d_m = reach
        run_m = d_m - d0_m
        if run_m == 0.0:
            return reach
        if f.n > K:
            k, sd = float(f.mean[K]), sqrt(max(f.cov[K][K], 0.0))
        else:
            k, sd = 0.0, scale_sigma0
        prior = SCALE_K_SIGMA * max(self.params.scale_sigma, scale_sigma0)
        band_low, band_high = wheel_band(vouched, ips_d_m, d_m, prior)
        low = min(max(min(1.0 + k - SCALE_K_SIGMA * sd, band_low), WHEEL_LOWEST), WHEEL_HIGHEST)
        high = min(max(max(1.0 + k + SCALE_K_SIGMA * sd, band_high), WHEEL_LOWEST), WHEEL_HIGHEST)
        if run_m < 0.0:
            low, high = high, low
        wrap = self.layout.wrap
        return wrap(low_s_m + run_m / high), wrap(high_s_m + run_m / low), d_m, ref_d_m

    def vouch(self, f, vouched, tag_s_m, d_m, in_field, span_s):
        """`vouched` (FilterState.vouched; None: begin afresh) after a balise read the filter took: the first read
        since the wheel was last in doubt stays the reference; once this one lies VOUCH_M beyond both reads' spreads
        (3 sigma and the tag's bias each) from it, the least and most odometer metres per true metre between them."""
        offset_m, var_m2 = tag_read_model(self.noise, float(f.mean[V]) * span_s, in_field)
        s_m, spread_m = tag_s_m - offset_m, 3.0 * sqrt(var_m2) + self.params.tag_bias_m
        if vouched is None or vouched[0] is None:   # the first read; a band brought along (carry_wheel) stays
            return (d_m, s_m, spread_m) + ((None, None) if vouched is None else vouched[3:])
        d0_m, s0_m, spread0_m, low, high = vouched
        run_m, moved_m, room_m = d_m - d0_m, s_m - s0_m, spread_m + spread0_m
        ring_m = self.layout.loop_length_m
        if ring_m:   # the whole laps between the reads, from the odometer's travel
            k = float(f.mean[K]) if f.n > K else 0.0
            moved_m += ring_m * round((run_m / (1.0 + k) - moved_m) / ring_m)
        if run_m > 0.0 and moved_m - room_m >= VOUCH_M:
            new_low, new_high = run_m / (moved_m + room_m), run_m / (moved_m - room_m)
            if low is not None and max(low, new_low) <= min(high, new_high):   # both bound the same wheel
                new_low, new_high = max(low, new_low), min(high, new_high)
            low, high = new_low, new_high
        return d0_m, s0_m, spread0_m, low, high

    @staticmethod
    def widen_reach(reach, by_m):
        """`reach` widened `by_m` either way (travel of unknown sign: a roll, a speed step's share)."""
        if reach is None:
            return None
        return reach[0] - by_m, reach[1] + by_m, reach[2], reach[3]

    def reach_at_tag(self, f, tag_s_m, d_m, in_field, span_s):
        """The reach a balise read gives: where the read puts the head, 3 sigma of the read (the tag's placement
        as surveyed, `tag_sigma_m`, and the reader's field and poll) either way, at odometer `d_m`."""
        offset_m, var_m2 = tag_read_model(self.noise, float(f.mean[V]) * span_s, in_field)
        return self.reach_around(tag_s_m - offset_m, 3.0 * sqrt(var_m2), d_m)

    def read_story(self, f, tag_s_m, d_m, in_field, span_s):
        """Where a balise read puts the head at the filter's time, as an offset from the filter's position (m, the
        short way round), and the read's variance (m^2)."""
        offset_m, var_m2 = tag_read_model(self.noise, float(f.mean[V]) * span_s, in_field)
        here_m = tag_s_m - offset_m + float(f.mean[D]) - d_m
        return circular_offset_m(here_m, float(f.mean[S]), self.layout.loop_length_m), var_m2

    def reach_around(self, s_m, half_m, d_m):
        wrap = self.layout.wrap
        return wrap(s_m - half_m), wrap(s_m + half_m), d_m, d_m

    def within_doubt(self, f, doubt, tag_s_m, d_m, in_field, span_s):
        """True when a balise read puts the head within `doubt` (the pending placement's bound, as offsets from the
        filter's position), widened by 3 sigma of the filter and of the read and the tag's bias."""
        story_m, var_m2 = self.read_story(f, tag_s_m, d_m, in_field, span_s)
        low_m, high_m = doubt if doubt is not None else (0.0, 0.0)
        spread_m = 3.0 * (sqrt(max(f.cov[S][S], 0.0)) + sqrt(var_m2)) + self.params.tag_bias_m
        return low_m - spread_m <= story_m <= high_m + spread_m

    def story_repeats(self, f, reach, story_m, tag_s_m, d_m, in_field, span_s):
        """True when a balise read the filter gates tells the story the one before told (`story_m`, the newest gated
        read's position less the filter's), to within STORY_TOL_M or a quarter of it, the same way, and no further
        off than a wheel WORN_SHARE wrong could have taken the filter since its last reference (`reach`): two
        balises in a row, the most accurate reference, agree with each other and not with the filter. Reads of other
        tags (misplaced, swapped, misread) put the train at random places, most a tag spacing or more away: they do
        not repeat."""
        if story_m is None or reach is None:
            return False
        now_m, _var = self.read_story(f, tag_s_m, d_m, in_field, span_s)
        worn_m = WORN_SHARE * abs(d_m - reach[3]) + STORY_TOL_M
        return now_m * story_m > 0.0 and abs(now_m - story_m) <= max(STORY_TOL_M, 0.25 * abs(story_m)) \
            and abs(now_m) <= worn_m

    def replace_at_tag(self, f, doubt, tag_s_m, d_m, in_field, span_s):
        """Restart the position at a balise read the filter gated and return the doubt (behind <= 0, ahead >= 0 of
        the new position) that covers the position before it (3 sigma and its own doubt) and the tag's bias."""
        offset_m, var_m2 = tag_read_model(self.noise, float(f.mean[V]) * span_s, in_field)
        old_s_m, spread_m = float(f.mean[S]), 3.0 * sqrt(max(f.cov[S][S], 0.0))
        low_m, high_m = doubt if doubt is not None else (0.0, 0.0)
        s_m = self.layout.wrap(tag_s_m - offset_m + float(f.mean[D]) - d_m)
        f.relocate(s_m, sqrt(var_m2))
        ring_m = self.layout.loop_length_m
        behind_m, ahead_m = (circular_offset_m(self.layout.wrap(old_s_m + x), s_m, ring_m)
                             for x in (low_m - spread_m, high_m + spread_m))
        bias_m = self.params.tag_bias_m
        return min(-bias_m, behind_m), max(bias_m, ahead_m)
