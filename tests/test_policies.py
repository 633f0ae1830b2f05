"""The authority policies are functions of values: a Situation in, a frozen Authority out with the reason, nothing
changed on the way."""

import copy
import dataclasses

import pytest

from cbtc.authority.control_laws import departure_accelerations_mps2, departure_k_for
from cbtc.authority.fixed_block import FixedBlockPolicy
from cbtc.authority.moving_block import MovingBlockPolicy
from cbtc.authority.rules import (
    AuthorityParams,
    checked_gap_m,
    following_reach_m,
    horizon_m,
    moving_block_distance_m,
    rollback_allowance_m,
    scale_trusted,
    within_horizon,
)
from cbtc.authority.values import Authority, Situation, TrainPicture
from cbtc.layout_files import load_layout
from cbtc.railway.train_profile import TrainProfile

LAYOUT = load_layout("itb_square")
PROFILE = TrainProfile()


def picture(train_id, s_m, v_mps=0.3, sigma_s_m=0.01, data_t_s=10.0):
    return TrainPicture(train_id, s_m, sigma_s_m, v_mps, data_t_s, PROFILE)


def held(obj):
    """Every attribute `obj` holds that is not a method: its __dict__, or its slots in the compiled build."""
    return {name: getattr(obj, name) for name in dir(obj)
            if not name.startswith("__") and not callable(getattr(obj, name))}


def test_moving_block_runs_to_the_leaders_tail_less_margin_sigmas_and_the_rollback_of_its_data_age():
    params = AuthorityParams()
    policy = MovingBlockPolicy(params, takagi=False)
    own, leader = picture("B", 1.0), picture("A", 3.0, data_t_s=9.5)
    sit = Situation(LAYOUT, 10.0, 0.05, own, leader)
    before = copy.deepcopy(held(policy))
    auth = policy.authority(sit)
    gap_m = 3.0 - PROFILE.length_m - 1.0
    assert auth.distance_m == pytest.approx(moving_block_distance_m(gap_m, 0.01, 0.01, params, 0.5, 0.3,
                                                                    PROFILE.beta_e_mps2))
    assert auth.reason == "train A's tail" and auth.mode == "free" and auth.leader_data_t_s == 9.5
    assert auth.gap_est_m == pytest.approx(gap_m) and auth.gap_alarm is None
    assert held(policy) == before                         # the policy keeps nothing of the train
    assert policy.authority(sit) == auth                  # and the same values give the same authority
    with pytest.raises(dataclasses.FrozenInstanceError):
        auth.distance_m = 99.0


def test_the_authority_runs_from_the_front_most_head_to_the_rear_most_tail():
    """While a train's sensors disagree its estimate reaches further (ahead_m, behind_m): taken off in full."""
    policy = MovingBlockPolicy(takagi=False)
    plain = policy.authority(Situation(LAYOUT, 10.0, 0.05, picture("B", 1.0), picture("A", 3.0)))
    wide = policy.authority(Situation(LAYOUT, 10.0, 0.05, dataclasses.replace(picture("B", 1.0), ahead_m=0.2),
                                      dataclasses.replace(picture("A", 3.0), behind_m=0.3)))
    assert wide.distance_m == pytest.approx(plain.distance_m - 0.5)
    alone = policy.authority(Situation(LAYOUT, 10.0, 0.05, dataclasses.replace(picture("A", 1.0), ahead_m=0.2,
                                                                               behind_m=0.1)))
    assert alone.distance_m == pytest.approx(
        moving_block_distance_m(LAYOUT.length_m - PROFILE.length_m - 0.3, 0.01, 0.0, AuthorityParams()))


def test_a_leader_may_roll_back_once_stopped_and_the_end_behind_it_never_steps_back_as_it_brakes():
    """Standing: it may roll back at rollback_mps over its data's age and the command's time to live. Moving, it
    first goes forward the way it takes to stop at its emergency rate: above about 0.35 m/s nothing is left. Behind a
    leader braking to a stand at its service or its emergency rate, the end of authority never steps back: a step
    under a follower riding its braking curve trips it, and the trip then steps back the end behind it (counting the
    leader's stopping time as roll time too made 125 trips in 20 s of 50 trains in a queue; without it, 33)."""
    p = AuthorityParams()
    beta_e = PROFILE.beta_e_mps2
    assert rollback_allowance_m(0.05, p, 0.0, beta_e) == pytest.approx(p.rollback_mps * (0.05 + p.ttl_s))
    assert rollback_allowance_m(0.05, p, 0.35, beta_e) == 0.0
    assert rollback_allowance_m(2.0, p, 0.4, beta_e) == pytest.approx(rollback_allowance_m(2.0, p))   # stale
    for beta_mps2 in (PROFILE.beta_s_mps2, beta_e):
        s_m, v_mps, dt_s, ends = 0.0, 0.5, 0.01, []
        while v_mps > 0.0:                                   # the leader brakes at this rate to a stand
            ends.append(s_m - rollback_allowance_m(0.05, p, v_mps, beta_e))
            v_next = max(0.0, v_mps - beta_mps2 * dt_s)
            s_m += 0.5 * (v_mps + v_next) * dt_s
            v_mps = v_next
        ends.append(s_m - rollback_allowance_m(0.05, p, 0.0, beta_e))
        assert all(b >= a - 1e-12 for a, b in zip(ends, ends[1:])), beta_mps2


def test_moving_block_alone_on_a_loop_is_limited_by_its_own_tail():
    auth = MovingBlockPolicy().authority(Situation(LAYOUT, 10.0, 0.05, picture("A", 1.0)))
    assert auth.reason == "own tail (alone on the loop)" and auth.leader_data_t_s is None
    assert auth.distance_m == pytest.approx(moving_block_distance_m(LAYOUT.length_m - PROFILE.length_m, 0.01, 0.0,
                                                                    AuthorityParams()))


def test_a_shorter_fresh_measured_gap_caps_the_authority_and_a_disagreeing_one_raises_the_alarm():
    params = AuthorityParams()
    assert checked_gap_m(1.0, 0.01, None, 10.0, params, 0.02, True) == (1.0, None)
    assert checked_gap_m(1.0, 0.01, (8.0, 0.5), 10.0, params, 0.02, True) == (1.0, None)   # stale measurement
    assert checked_gap_m(1.0, 0.01, (10.0, 0.95), 10.0, params, 0.02, True) == (0.95, False)
    assert checked_gap_m(1.0, 0.01, (10.0, 0.5), 10.0, params, 0.02, True) == (0.5, True)
    assert checked_gap_m(1.0, 0.01, (10.0, 0.5), 10.0, params, 0.02, False) == (1.0, True)
    sit = Situation(LAYOUT, 10.0, 0.05, picture("B", 1.0), picture("A", 3.0), measured_gap=(10.0, 0.5))
    auth = MovingBlockPolicy().authority(sit)
    assert auth.reason == "train A's tail (measured)" and auth.gap_alarm is True


def test_the_leader_of_a_departing_pair_takes_alpha_a_and_its_follower_alpha_b():
    policy = MovingBlockPolicy()
    slow = TrainProfile(accel_max_mps2=0.3)   # the follower's traction limits the pair
    alpha_a, alpha_b = departure_accelerations_mps2(departure_k_for(0.6, 0.3, 0.8), 0.8)
    standing = Situation(LAYOUT, 10.0, 0.05, picture("A", 3.0, v_mps=0.0), picture("C", 6.0, 0.0))
    assert policy.authority(standing).acc_mps2 == PROFILE.accel_max_mps2
    assert policy.authority(dataclasses.replace(standing, departing=(slow,))).acc_mps2 == pytest.approx(alpha_a)
    params = AuthorityParams()
    tail_s = 3.0 - PROFILE.length_m
    s_b = tail_s - params.margin_m - params.k_sigma * (2 ** 0.5) * 0.01 - 0.005   # 5 mm of authority left
    own = TrainPicture("B", s_b, 0.01, 0.0, 10.0, slow)
    follower = policy.authority(Situation(LAYOUT, 10.0, 0.05, own, picture("A", 3.0, v_mps=0.0)))
    assert follower.mode == "departure" and follower.acc_mps2 == pytest.approx(alpha_b)


def test_fixed_block_names_the_occupied_block_or_the_train_in_its_own_block():
    policy = FixedBlockPolicy(blocks=8)
    blocks = policy.blocks(LAYOUT)
    size_m = LAYOUT.length_m / 8
    own = picture("B", 0.5 * size_m)
    spans = (("B", 0.5 * size_m, 0.5 * size_m - 0.3), ("A", 3.6 * size_m, 3.6 * size_m - 0.3))
    auth = policy.authority(Situation(LAYOUT, 10.0, 0.05, own, spans=spans))
    assert isinstance(auth, Authority) and auth.reason == f"block {blocks[3].name} occupied"
    assert auth.distance_m == pytest.approx(3 * size_m - 0.5 * size_m - policy.params.margin_m
                                            - policy.params.k_sigma * 0.01)
    spans = (("B", 0.5 * size_m, 0.5 * size_m - 0.3), ("A", 0.95 * size_m + 0.3, 0.95 * size_m))
    auth = policy.authority(Situation(LAYOUT, 10.0, 0.05, own, spans=spans))
    assert auth.reason == "train A in its own block" and auth.distance_m < 0


def test_fixed_block_holds_two_trains_in_one_block_and_a_span_that_covers_the_head():
    """Start-up: A 0.10 m ahead of B in one block. A is not alone on the loop: it may go round to its own block's
    entry, short of B. B stays. And a span widened by uncertainty whose tail reaches back past B's head holds B."""
    policy = FixedBlockPolicy(blocks=4)
    blocks = policy.blocks(LAYOUT)
    size_m = LAYOUT.length_m / 4
    a_head, b_head = 0.5 * size_m + 0.35, 0.5 * size_m
    spans = (("A", a_head, a_head - 0.25), ("B", b_head, b_head - 0.25))
    front = policy.authority(Situation(LAYOUT, 10.0, 0.05, picture("A", a_head), spans=spans))
    assert front.reason == f"block {blocks[0].name} occupied"
    assert front.distance_m == pytest.approx(LAYOUT.length_m - a_head - policy.params.margin_m
                                             - policy.params.k_sigma * 0.01)
    behind = policy.authority(Situation(LAYOUT, 10.0, 0.05, picture("B", b_head), spans=spans))
    assert behind.reason == "train A in its own block" and behind.distance_m < 0
    widened = (("A", 1.1 * size_m, b_head - 0.02), ("B", b_head, b_head - 0.25))   # A's tail 2 cm behind B's head
    held = policy.authority(Situation(LAYOUT, 10.0, 0.05, picture("B", b_head), spans=widened))
    assert held.reason == "train A in its own block" and held.distance_m < 0


def test_an_encoder_scale_is_trusted_only_within_the_band_a_wheel_can_have():
    assert scale_trusted(1.02, 0.5, 2.0) and scale_trusted(0.5, 0.5, 2.0)
    assert not any(scale_trusted(x, 0.5, 2.0) for x in (-0.4, 0.0, 0.49, 2.01, float("nan"), float("inf")))


def test_an_authority_reaches_no_further_than_the_horizon_and_says_so():
    params = AuthorityParams()
    reach_m = horizon_m(PROFILE, params)
    assert reach_m == pytest.approx(following_reach_m(PROFILE) + PROFILE.v_max_mps * params.ttl_s)
    short = Authority(0.3, PROFILE.v_max_mps, 0.5, 1.0, "free", "train A's tail")
    assert within_horizon(short, reach_m) is short
    long = dataclasses.replace(short, distance_m=4.0)
    cut = within_horizon(long, reach_m)
    assert cut.distance_m == reach_m and cut.reason == "horizon (train A's tail further)"
    assert long.distance_m == 4.0


def test_cutting_an_authority_keeps_every_other_field():
    values = {f.name: f"value {i}" for i, f in enumerate(dataclasses.fields(Authority))}
    auth = Authority(**values)
    assert auth.cut_to(1.5, "horizon") == dataclasses.replace(auth, distance_m=1.5, reason="horizon")
