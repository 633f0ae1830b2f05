"""Whole scenarios through the command line and the experiment runners: the issue's acceptance figures, seeded."""

import json

import pytest

from cbtc.cli import main as cbtc_main
from cbtc.headway import reductions, run_paper_systems, steady_following
from cbtc.layout import load_layout


def run_json(capsys, argv):
    rc = cbtc_main(argv)
    return rc, json.loads(capsys.readouterr().out)


def test_demo_json_is_reproducible_and_safe(capsys, tmp_path):
    argv = ["demo", "--json", "--laps", "2", "--seed", "11", "--plot", str(tmp_path / "d.png")]
    rc, first = run_json(capsys, argv)
    _, second = run_json(capsys, argv)
    assert rc == 0 and first == second
    assert first["collisions"] == 0 and first["authority_overruns"] == 0
    assert all(t["laps"] >= 2 and t["station_stops"] >= 2 for t in first["trains"])
    assert (tmp_path / "d.png").stat().st_size > 10_000


def test_sim_three_trains_on_a_lego_layout(capsys):
    rc, result = run_json(capsys, ["sim", "--layout", "lego_oval", "--trains", "3", "--duration", "90", "--seed", "2",
                                   "--json"])
    assert rc == 0 and result["collisions"] == 0 and result["authority_overruns"] == 0
    assert all(t["distance_m"] > 10 for t in result["trains"])


def test_too_many_trains_is_a_clear_error(capsys):
    assert cbtc_main(["sim", "--layout", "lego_oval", "--trains", "40", "--duration", "5"]) == 2
    assert "do not fit" in capsys.readouterr().err


@pytest.mark.parametrize("argv,named", [(["--report-ms", "50,x"], "--report-ms: 'x'"),
                                        (["--blocks", "1"], "--blocks: '1'"),
                                        (["--code-ber", "0.7"], "--code-ber")])
def test_compare_names_a_bad_setting_before_running(capsys, argv, named):
    assert cbtc_main(["compare"] + argv) == 2
    assert named in capsys.readouterr().err


def test_moving_block_beats_fixed_block_in_the_paper_scenario():
    systems, _ = run_paper_systems(load_layout("itb_square"), seed=0, laps=3)
    moving, fixed = systems["moving_block"], systems["fixed_block"]
    for figures in (moving, fixed):
        assert figures["collisions"] == 0 and figures["authority_overruns"] == 0
    cuts = reductions(moving, fixed)
    assert cuts["gap_reduction_pct"] > 20 and cuts["lap_reduction_pct"] > 5
    assert moving["trains_per_hour"] > fixed["trains_per_hour"]


def test_steady_following_keeps_a_safe_gap_near_the_theoretical_minimum():
    result = steady_following(load_layout("itb_square"), seed=0, duration_s=45.0, settle_s=20.0)
    assert result["collisions"] == 0 and result["authority_overruns"] == 0
    assert 1.0 <= result["achieved_over_theoretical"] < 1.6
