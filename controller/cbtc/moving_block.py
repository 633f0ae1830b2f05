"""The moving-block authority policy: how far each train may go, from the estimates of itself and the train ahead."""

from .authority import AuthorityParams, braking_curve_speed_mps, moving_block_distance_m


class MovingBlockPolicy:
    name = "moving_block"

    def __init__(self, params: AuthorityParams = None):
        self.params = params or AuthorityParams()

    def protected_m(self, layout, train_id, spans):
        """True distance (m) from `train_id`'s head to the point its authority protects: the true tail of the train
        ahead less S_M. `spans` lists (train_id, head_s, tail_s) in truth. Negative = the protected zone is entered."""
        head = next(h for t, h, _ in spans if t == train_id)
        others = [(layout.ahead_m(head, tail), tail) for t, _, tail in spans if t != train_id]
        if not others:
            return float("inf")
        return min(others)[0] - self.params.margin_m

    def authority(self, zc, state, leader, now_s):
        """(distance_m, v_cap_mps, acc_mps2, dec_mps2) for `state`'s train behind `leader` (None: alone on the track)."""
        layout = zc.layout
        profile = state.setup.profile
        own = state.estimator.estimate(state.report_t_s)
        if leader is None:
            # alone on a loop: its own tail is the train ahead; on an open line: the end of the track
            if layout.closed:
                gap_m, sigma_leader_m = layout.length_m - profile.length_m, 0.0
            else:
                gap_m, sigma_leader_m = layout.length_m - own.s_m, 0.0
        else:
            # the leader as last seen (it can only have moved on since): not extrapolated
            ahead = leader.estimator.estimate(leader.report_t_s)
            tail_s = layout.wrap(ahead.s_m - leader.setup.profile.length_m)
            gap_m = layout.ahead_m(own.s_m, tail_s)
            if layout.closed and gap_m > layout.length_m - leader.setup.profile.length_m:
                gap_m -= layout.length_m  # the estimates overlap: negative gap, no authority
            sigma_leader_m = ahead.sigma_s_m
        distance_m = moving_block_distance_m(gap_m, own.sigma_s_m, sigma_leader_m, self.params)
        dead_time_s = self.params.latency_s + profile.reaction_s + max(0.0, now_s - state.report_t_s)
        v_cap_mps = min(profile.v_max_mps,
                        braking_curve_speed_mps(distance_m, own.v_mps, profile.beta_s_mps2, dead_time_s))
        return distance_m, v_cap_mps, profile.accel_max_mps2, profile.beta_s_mps2
