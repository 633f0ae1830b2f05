"""The live trains process's truth: how far a board ever moved past the end of authority it held."""

from types import SimpleNamespace

import pytest

from cbtc.authority.fixed_block import FixedBlockPolicy
from cbtc.authority.moving_block import MovingBlockPolicy
from cbtc.layout_files import load_layout
from cbtc.sim.truth import TruthMonitor


def _train(odo_mm, eoa_mm):
    return SimpleNamespace(obu=SimpleNamespace(odo_mm=odo_mm, eoa_mm=eoa_mm))


def test_moving_past_the_end_of_authority_is_counted_and_a_limit_set_behind_a_standing_train_is_not():
    train = _train(0, 100)
    monitor = TruthMonitor(layout=None, trains=[train])
    for odo_mm in (40, 90, 98):                 # runs up to its limit
        train.obu.odo_mm = odo_mm
        monitor.sample()
    assert monitor.moved_past_eoa_mm == [0]
    train.obu.eoa_mm = 90                       # an estimate correction puts the limit 8 mm behind the standing train
    monitor.sample()
    monitor.sample()
    assert monitor.moved_past_eoa_mm == [0]
    train.obu.odo_mm = 101                      # then it moves 3 mm: all of them past the limit
    monitor.sample()
    train.obu.eoa_mm, train.obu.odo_mm = 200, 150   # a new limit, and it runs on inside it
    monitor.sample()
    assert monitor.moved_past_eoa_mm == [3]
    train.obu.eoa_mm, train.obu.odo_mm = 160, 165   # past a limit it held while moving: the 5 mm beyond it
    monitor.sample()
    assert monitor.moved_past_eoa_mm == [8]


def test_on_a_line_the_front_train_has_no_train_ahead_and_a_head_behind_a_tail_is_no_collision():
    from cbtc.layout_files import load_layout
    from cbtc.sim.truth import head_inside, train_ahead

    line, loop = load_layout("straight_test"), load_layout("itb_square")
    assert not line.closed and loop.closed
    assert train_ahead(line, [0.5, 2.0]) == {0: 1}                 # the front train has none ahead on a line
    assert train_ahead(loop, [0.5, 2.0]) == {0: 1, 1: 0}           # on a loop the front train follows the rear one
    # a follower's head 1 m behind the leader's tail (0.3 m long): a gap, not a collision
    assert not head_inside(line, 1.0, 2.0, 0.3)
    assert head_inside(line, 2.1, 2.0, 0.3)                        # its head inside the leader's span
    assert not head_inside(line, 2.4, 2.0, 0.3)                    # past the leader's head: not inside its span


def test_the_protected_point_is_the_true_tail_ahead_or_the_first_truly_occupied_block_less_the_margin():
    layout = load_layout("itb_square")
    spans = [("B", 1.0, 0.7), ("A", 2.5, 2.2)]
    moving = MovingBlockPolicy()
    assert moving.protected_m(layout, "B", spans) == pytest.approx(1.2 - moving.params.margin_m)
    assert moving.protected_m(layout, "B", spans[:1]) == float("inf")
    fixed = FixedBlockPolicy(blocks=8)
    size_m = layout.length_m / 8
    entry_m = fixed.index_at(fixed.blocks(layout), layout, 2.2) * size_m   # A's tail's block starts here
    assert fixed.protected_m(layout, "B", spans) == pytest.approx(entry_m - 1.0 - fixed.params.margin_m)
    inside = [("B", 1.0, 0.7), ("A", 1.35, 1.05)]                           # A's tail in B's own block, ahead of B
    assert fixed.index_at(fixed.blocks(layout), layout, 1.05) == fixed.index_at(fixed.blocks(layout), layout, 1.0)
    assert fixed.protected_m(layout, "B", inside) == pytest.approx(0.05 - fixed.params.margin_m)


def test_every_trains_protected_room_at_once_equals_one_at_a_time():
    """The recorder asks for every train's protected room each sample (sorted tails on a loop): the same figures as
    `protected_m` train by train, on random fleets with touching and overlapping trains, under both policies."""
    import random


    rng = random.Random(1)
    for name, policy in (("lego_oval", MovingBlockPolicy()), ("straight_test", MovingBlockPolicy()),
                         ("itb_square", FixedBlockPolicy(blocks=8))):
        layout = load_layout(name)
        for _ in range(300):
            spans = []
            for i in range(rng.randint(1, 10)):
                head = spans[-1][1] if spans and rng.random() < 0.1 else layout.wrap(rng.uniform(0, layout.length_m))
                spans.append((f"T{i}", head, layout.wrap(head - rng.choice([0.2, 0.3, 0.5]))))
            assert policy.protected_all_m(layout, spans) == [policy.protected_m(layout, t, spans)
                                                             for t, _h, _tl in spans]
