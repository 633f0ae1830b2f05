"""The moving-block authority policy: how far each train may go, and how it follows (Takagi control).

Authority: the train ahead's tail as last estimated (not extrapolated: brick wall), less S_M and k sigma of both
estimates, less what the leader may have rolled back since (it may stop and roll before the command expires;
stale data shrinks the authority further: cbtc.authority.rules.rollback_allowance_m). Control on top of it (paper
eqs. 24-26, cbtc.authority.control_laws):
- synchronisation: once the usable gap has shrunk to the braking distance of the follower, its deceleration is
  commanded by eq. 24 from both speeds, which holds the gap at S_min(v_B) as both move;
- departure: when a train stands at minimum distance behind a standing train, the pair departs together with
  alpha_A = k beta_s and alpha_B = beta_s(-1 + sqrt(1 + 4k))/2 (eqs. 25-26), so the follower stays at S_min(v_B).
The onboard braking curve to the end of authority stays the safety net under both.
"""

import functools
from bisect import bisect_left

from cbtc.authority.control_laws import (
    departure_accelerations_mps2,
    departure_k_for,
    sync_deceleration_mps2,
)
from cbtc.authority.policy import MOVING_BLOCK
from cbtc.authority.rules import (
    AuthorityParams,
    checked_gap_m,
    combined_sigma_m,
    minimum_gap_m,
    moving_block_distance_m,
)
from cbtc.authority.values import Authority, Situation

_STANDING_MPS = 0.02


class MovingBlockPolicy:
    """An AuthorityPolicy (cbtc.authority.policy): the train ahead's rear-most plausible tail bounds the authority."""
    name = MOVING_BLOCK
    title = "moving block"
    fast_reports = True   # the authority rests on the train ahead's reports: ask it for fast ones when followed
    needs_spans = False   # the train ahead alone limits the authority
    uses_blocks = False

    def __init__(self, params: AuthorityParams = None, sync_tolerance_m: float = 0.01, takagi: bool = True):
        self.params = params or AuthorityParams()
        self.sync_tolerance_m = sync_tolerance_m
        self.takagi = takagi

    def usable_gap(self, sit: Situation):
        """(distance_m, leader_v_mps, the Authority's fields that say what the distance rests on: reason,
        leader_data_t_s, sigma_m, gap_est_m, gap_alarm)."""
        layout, own, leader = sit.layout, sit.own, sit.leader
        if leader is None:
            # alone: its own tail is the train ahead on a loop; the end of the track on an open line
            gap_m = layout.length_m - own.profile.length_m - own.behind_m if layout.closed \
                else layout.length_m - own.s_m
            gap_m -= own.ahead_m
            why = ("own tail (alone on the loop)" if layout.closed else "end of the line", None, own.sigma_s_m, None,
                   None)
            return moving_block_distance_m(gap_m, own.sigma_s_m, 0.0, self.params), None, why
        # the train's front-most plausible head to the leader's rear-most plausible tail
        tail_s = layout.wrap(leader.s_m - leader.profile.length_m - leader.behind_m)
        gap_m = layout.ahead_m(layout.wrap(own.s_m + own.ahead_m), tail_s)
        if layout.closed and gap_m > layout.length_m - leader.profile.length_m - leader.behind_m - own.ahead_m:
            gap_m -= layout.length_m  # the estimates overlap: negative gap, no authority
        sigma_m = combined_sigma_m(own.sigma_s_m, leader.sigma_s_m)
        # the follower's own ranging to the leader, when it has one, caps the gap and checks the picture
        used_m, alarm = checked_gap_m(gap_m, sigma_m, sit.measured_gap, sit.now_s, self.params,
                                      sit.ranging_sigma_m, sit.use_measured_gap)
        # the leader where it was last seen (brick wall: it may have stopped dead since, so its position is not
        # extrapolated); the older that is, the more it may have rolled back: stale data shrinks the authority (and
        # the zone controller stops extending it at all after max_leader_age_s)
        age_s = sit.now_s - leader.data_t_s
        why = (f"train {leader.train_id}'s tail" + (" (measured)" if used_m < gap_m else ""), leader.data_t_s,
               sigma_m, gap_m, alarm)
        return (moving_block_distance_m(used_m, own.sigma_s_m, leader.sigma_s_m, self.params, age_s, leader.v_mps,
                                        leader.profile.beta_e_mps2), leader.v_mps, why)

    def authority(self, sit: Situation) -> Authority:
        """The Authority of `sit.own`'s train behind `sit.leader` (None: alone)."""
        own = sit.own
        profile = own.profile
        beta_s = profile.beta_s_mps2
        distance_m, v_leader, why = self.usable_gap(sit)
        # The braking curve to the end of authority is supervised on board, against the exact odometer, with the
        # reaction time counted; the end of authority is a fixed point of that odometer, so communication latency
        # and the follower's data age do not move it, and the command expires `ttl_s` after the report it answers.
        # So the controller commands the line speed and the end of authority; the board rides the curve.
        v_cap = profile.v_max_mps
        acc, dec = profile.accel_max_mps2, beta_s
        mode = "free"
        if self.takagi and sit.leader is not None:
            v_b = max(0.0, own.v_mps)
            window_m = profile.stop_window_mm() / 1000.0   # the onboard service curve ends this short of the limit
            if v_b > _STANDING_MPS and distance_m <= minimum_gap_m(v_b, beta_s, 0.0) + window_m + self.sync_tolerance_m:
                mode = "sync"
                beta_b = sync_deceleration_mps2(v_b, max(0.0, v_leader), beta_s)
                horizon_s = sit.cycle_s + self.params.latency_s
                if beta_b > 0:
                    v_cap = min(v_cap, max(0.0, v_b - beta_b * horizon_s))
                    dec = min(beta_s, max(0.05 * beta_s, beta_b))
            elif v_b <= _STANDING_MPS and abs(v_leader) <= _STANDING_MPS and distance_m <= self.sync_tolerance_m:
                mode = "departure"
        if self.takagi:
            acc = self._departure_acc(sit, mode, acc)
        return Authority(distance_m, v_cap, acc, dec, mode, *why)

    @staticmethod
    def signal(sit: Situation) -> Situation:
        return sit   # nothing goes through the wayside

    @staticmethod
    def blocks(_layout) -> tuple:
        return ()

    def protected_m(self, layout, train_id, spans) -> float:
        """In truth: to the tail of the train ahead (on a line, of a train further on, or the end of the track), less
        the safety margin; infinite for a train alone on a loop."""
        head = next(h for t, h, _ in spans if t == train_id)
        ahead = [layout.ahead_m(head, tail) for t, h, tail in spans if t != train_id and (layout.closed or h > head)]
        if not layout.closed:
            ahead.append(layout.length_m - head)
        return min(ahead) - self.params.margin_m if ahead else float("inf")

    def protected_all_m(self, layout, spans) -> list:
        """protected_m of every train; on a loop each train's nearest tail ahead is found in the tails sorted once
        (the same minimum, in n log n rather than n^2 a sample)."""
        if not layout.closed or len(spans) < 2:
            return [self.protected_m(layout, train_id, spans) for train_id, _h, _t in spans]
        tails = sorted((tail, i) for i, (_id, _h, tail) in enumerate(spans))
        keys = [tail for tail, _i in tails]
        margin_m = self.params.margin_m
        out = []
        for i, (_id, head, _tail) in enumerate(spans):
            k = bisect_left(keys, head)
            if tails[k % len(tails)][1] == i:   # its own tail: the next one round
                k += 1
            out.append(layout.ahead_m(head, tails[k % len(tails)][0]) - margin_m)
        return out

    @staticmethod
    def stuck(_layout, _spans):
        return None   # a train behind another always gets the room up to it

    @staticmethod
    def _departure_acc(sit, mode, acc):
        """Eqs. 25-26: the follower of a departing pair accelerates at alpha_B, its leader at alpha_A = k beta_s."""
        profile = sit.own.profile
        if mode == "departure" and sit.leader is not None:
            return _departure_pair(sit.leader.profile.accel_max_mps2, profile.accel_max_mps2, profile.beta_s_mps2)[1]
        # am I the leader of a pair standing at minimum distance?
        if sit.departing and sit.own.v_mps <= 0.5 * profile.v_max_mps:
            return _departure_pair(profile.accel_max_mps2, sit.departing[0].accel_max_mps2, profile.beta_s_mps2)[0]
        return acc


@functools.lru_cache(maxsize=256)
def _departure_pair(accel_max_leader_mps2, accel_max_follower_mps2, beta_s_mps2):
    """(alpha_A, alpha_B) of a pair departing together (eqs. 25-26): a few profiles, asked on every authority."""
    k = departure_k_for(accel_max_leader_mps2, accel_max_follower_mps2, beta_s_mps2)
    return departure_accelerations_mps2(k, beta_s_mps2)
