"""A train is located on two independent references: what placed it (the IPS, a tag, an operator's declaration) and a
second one that agrees. Until then its estimate covers the placement's lasting bias, it runs at restricted speed,
and a balise that disagrees places it afresh instead of being turned away."""

import pytest

from cbtc.estimation.ukf_estimator import UkfEstimator
from cbtc.estimation.ukf_params import UkfParams
from cbtc.layout_files import load_layout
from cbtc.railway import balise
from cbtc.railway.train_profile import TrainProfile
from cbtc.sim.runs import sim_config
from cbtc.sim.simulation import Simulation
from test_ukf import _standing_reports, along_error_m, controller_s, feed

BIAS_M = UkfParams().ips_bias_m


@pytest.fixture(scope="module")
def loop():
    return load_layout("itb_square")


def _placed_by_biased_fixes(loop, profile, true_s_m, bias_m):
    """An estimator and the reports of a train standing at `true_s_m` whose IPS puts it `bias_m` ahead (multipath)."""
    x, y = (float(c) for c in loop.xy(loop.wrap(true_s_m + bias_m)))
    est = UkfEstimator(loop, profile)
    standing = _standing_reports(loop, true_s_m, [(x + 0.01, y), (x - 0.01, y), (x, y + 0.01)])
    feed(est, standing)
    return est, standing


def _tag_report(loop, after, tag_s_m, uid="0a0b0c0d", odo_mm=0):
    data = balise.image(77, float(loop.wrap(tag_s_m))).hex()
    return dict(after, seq=after["seq"] + 1, t_ms=after["t_ms"] + 125, odo_mm=odo_mm,
                tags=[[uid, odo_mm, after["t_ms"] + 100, 0, data]], ips=None)


def test_an_ips_placement_covers_its_bias_until_a_balise_confirms_it(loop):
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    est, standing = _placed_by_biased_fixes(loop, profile, 1.0, 0.0)
    placed = est.estimate(controller_s(standing[-1]["t_ms"]))
    assert est.localized and not est.confirmed
    assert placed.ahead_m >= BIAS_M and placed.behind_m >= BIAS_M
    tag = _tag_report(loop, standing[-1], 1.0 + profile.rfid_range_m)
    feed(est, [tag])
    confirmed = est.estimate(controller_s(tag["t_ms"]))
    assert est.confirmed and confirmed.ahead_m < 0.01 and confirmed.behind_m < 0.01


def test_a_balise_that_disagrees_with_an_ips_placement_places_the_train_instead_of_being_rejected(loop):
    """Three fixes 0.25 m ahead place the train there; the balise under its reader says where it is: the train is
    placed at the balise, and the estimate still covers the fixes' story until a second reference agrees."""
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    est, standing = _placed_by_biased_fixes(loop, profile, 1.0, 0.25)
    placed = est.estimate(controller_s(standing[-1]["t_ms"]))
    assert abs(along_error_m(loop, placed.s_m, 1.25)) < 0.05 and placed.behind_m >= 0.25 - 0.05
    tag = _tag_report(loop, standing[-1], 1.0 + profile.rfid_range_m)
    feed(est, [tag])
    moved = est.estimate(controller_s(tag["t_ms"]))
    assert abs(along_error_m(loop, moved.s_m, 1.0)) < 0.02, moved
    assert not est.confirmed and moved.ahead_m >= 0.2, "the fixes' story is covered until a second reference"
    assert est.counters()["tags_used"] == 1 and est.counters()["tags_rejected"] == 0


def test_a_single_tag_placement_awaits_a_second_reference(loop):
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    x, y = (float(c) for c in loop.xy(1.0))
    standing = _standing_reports(loop, 1.0, [(x + 0.01, y), (x - 0.01, y), (x, y + 0.01), (x, y - 0.01)])
    est = UkfEstimator(loop, profile)
    first = _tag_report(loop, dict(standing[0], seq=-1, t_ms=standing[0]["t_ms"] - 125), 1.0 + profile.rfid_range_m)
    feed(est, [first])
    tagged = est.estimate(controller_s(first["t_ms"]))
    assert est.localized and not est.confirmed and tagged.ahead_m == tagged.behind_m == UkfParams().tag_bias_m
    feed(est, standing)   # the IPS, independent of the tag, agrees: confirmed
    assert est.confirmed


def test_a_declared_start_that_agrees_confirms_the_placement_and_one_that_does_not_leaves_it_pending(loop):
    profile = TrainProfile().with_changes(ips_outlier=0.0)
    x, y = (float(c) for c in loop.xy(1.0))
    fixes = [(x + 0.01, y), (x - 0.01, y), (x, y + 0.01)]
    agreed = UkfEstimator(loop, profile)
    agreed.declare_position(1.0, 0.05)
    standing = _standing_reports(loop, 1.0, fixes)
    feed(agreed, standing)
    est = agreed.estimate(controller_s(standing[-1]["t_ms"]))
    assert agreed.confirmed and est.ahead_m < 0.1 and est.behind_m < 0.1
    moved = UkfEstimator(loop, profile)
    moved.declare_position(1.6, 0.05)   # the train was put down 0.6 m from where the operator says
    feed(moved, _standing_reports(loop, 1.0, fixes))
    assert moved.localized and not moved.confirmed


def test_an_unconfirmed_train_runs_at_restricted_speed():
    """After a controller restart no train is declared: each runs at restricted speed until a balise confirms it."""
    config = sim_config("itb_square", 2, 3, 14.0, fault_texts=("controller_restart:at_s=3,duration_s=0.5",))
    sim = Simulation(config)
    caps = {}

    def watch(sent):
        if sent.t_s > 3.5:
            caps.setdefault(sent.confirmed, []).append(sent.command.v_mmps)

    sim.scheduler.call_at(3.6, lambda: sim.zc.commands.subscribe(watch))
    sim.run()
    restricted_mmps = int(sim.zc.params.restricted_mps * 1000)
    assert caps.get(False), "the new zone placed the trains on the IPS alone first"
    assert max(caps[False]) <= restricted_mmps
    assert caps.get(True) and max(caps[True]) > restricted_mmps, "a balise confirmed them and they run on"


@pytest.mark.parametrize("seed", [0, 7])
def test_a_restart_during_multipath_ends_in_no_collision(seed):
    """The review's case (cbtc sim --layout itb_square --trains 3 --duration 60 --fault controller_restart:... --fault
    ips_offset:...): the restarted zone placed T3 on 0.3 m of multipath and it ran into its leader."""
    config = sim_config("itb_square", 3, seed, 60.0, fault_texts=(
        "controller_restart:at_s=20,duration_s=1", "ips_offset:train=T3,at_s=18,duration_s=15,offset_m=0.3"))
    summary = Simulation(config).run().summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0, summary


def test_a_layout_without_tags_is_named_in_a_warning(caplog):
    import logging

    from cbtc.railway.layout_dict import layout_from_dict
    layout = layout_from_dict({"name": "bare", "closed": False, "segments": [{"straight": {"length_m": 4.0}}]})
    with caplog.at_level(logging.WARNING, logger="cbtc.zone"):
        Simulation(sim_config(layout, 2, 0, 5.0))
    assert any("layout bare has no RFID tags" in r.getMessage() and "restricted speed" in r.getMessage()
               for r in caplog.records)
