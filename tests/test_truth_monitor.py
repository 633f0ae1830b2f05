"""The live trains process's truth: how far a board ever moved past the end of authority it held."""

from types import SimpleNamespace

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
