"""Scenario files: the shipped examples run, and every mistake is named with its file, line, key and fix."""

import textwrap

import pytest

from cbtc.cli import main
from cbtc.errors import ConfigError
from cbtc.scenario_files import load_scenario, scenario_names

GOOD = """\
layout: itb_square
seed: 3
duration_s: 30
trains:
  - id: A
    start: main
    stops: [A, main]
    dwell_s: 2
    profile: {length_m: 0.25, v_max_mps: 0.5}
  - id: B
    start: {behind: A, gap_m: 0.2}
faults:
  - {name: link_loss, train: B, at_s: 10, duration_s: 1}
reference:
  source: another simulator
  mean_headway_s: 3.8
"""


def write(tmp_path, text, name="s.yaml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def test_a_scenario_file_gives_every_train_its_profile_start_stops_and_dwell(tmp_path):
    config = load_scenario(write(tmp_path, GOOD))
    a, b = config.trains
    assert (config.layout.name, config.seed, config.duration_s) == ("itb_square", 3, 30.0)
    assert a.s0_m == config.layout.station("main").s_m and a.stops == ("A", "main") and a.dwell_s == (2.0, 2.0)
    assert a.profile.length_m == 0.25 and a.profile.v_max_mps == 0.5
    assert b.s0_m == pytest.approx(a.s0_m - 0.25 - 0.2)
    assert b.stops == ("main", "A", "B") and b.dwell_s is None   # every station when none are listed
    assert [f.name for f in config.faults] == ["link_loss"] and config.faults[0].params["train"] == "B"
    assert config.reference == {"source": "another simulator", "mean_headway_s": 3.8}


def test_compare_prints_a_scenarios_reference_figures_beside_the_testbeds(capsys):
    """SUMO's case ships as a layout and a scenario file; compare sets SUMO's figures beside the same ones measured."""
    assert main(["compare", "--scenario", "sumo_case", "--laps", "1"]) == 0
    out = capsys.readouterr().out
    assert "Eclipse SUMO" in out and "mean_gap_following_m 0.593 (testbed " in out
    assert "mean_headway_s 3.8 (testbed " in out and "None" not in out.split("Eclipse SUMO")[1].splitlines()[0]


@pytest.mark.parametrize("change,line,named", [
    (("seed: 3", "sead: 3"), 2, "sead: unknown key; did you mean 'seed'?"),
    (("stops: [A, main]", "stops: [A, mian]"), 7, "trains[0].stops: no station 'mian'; did you mean 'main'?"),
    (("start: main", "start: nowhere"), 6, "trains[0].start: no station 'nowhere'"),
    (("gap_m: 0.2", "gap_m: -0.2"), 11, "trains[1].start.gap_m: must be >= 0.0"),
    (("behind: A", "behind: C"), 11, "trains[1].start.behind: must name a train listed before this one"),
    (("v_max_mps: 0.5}", "v_max_mps: fast}"), 9, "trains[0].profile.v_max_mps: must be a number, got 'fast'"),
    (("v_max_mps: 0.5}", "v_max_mps: 0.9}"), 9, "v_max_mps must not exceed v_noload_mps"),
    (("v_max_mps: 0.5}", "vmax_mps: 0.5}"), 9, "trains[0].profile.vmax_mps: unknown key; did you mean 'v_max_mps'?"),
    (("dwell_s: 2", "dwell_s: [3, 1]"), 8, "trains[0].dwell_s: must be seconds"),
    (("  - id: B", "  - id: A"), 10, "trains[1].id: train A is listed twice"),
    (("name: link_loss", "name: link_lost"), 13, "fault 'link_lost' is unknown"),
    (("train: B, at_s", "train: Z, at_s"), 13, "faults[0].train: no train 'Z' in this scenario"),
    (("duration_s: 1}", "duration_s: -1}"), 13, "duration_s must be >= 0"),
    (("duration_s: 30", "duration_s: 0"), 3, "duration_s: must be > 0.0"),
    (("layout: itb_square", "layout: itb_squar"), 1, "layout 'itb_squar' not found"),
    (("    dwell_s: 2", "    dwell_s: 2\n    dwell_s: 3"), 9, "key 'dwell_s' is given twice (first on line 8)"),
    (("seed: 3", "seed: [3"), 3, "not valid YAML"),
    (("mean_headway_s: 3.8", "mean_headway: 3.8"), 16,
     "reference.mean_headway: unknown key; did you mean 'mean_headway_s'?"),
    (("mean_headway_s: 3.8", "mean_headway_s: -1"), 16, "reference.mean_headway_s: must be >= 0"),
    (("  source: another simulator\n", ""), 14, "reference.source: missing: say where the figures come from"),
    (("  mean_headway_s: 3.8\n", ""), 14, "reference: gives no figure"),
])
def test_every_mistake_names_the_file_line_key_and_fix(tmp_path, change, line, named):
    path = write(tmp_path, GOOD.replace(*change))
    with pytest.raises(ConfigError) as err:
        load_scenario(path)
    text = str(err.value)
    assert text.startswith(f"{path}:{line}: "), text
    assert named in text, text


def test_trains_overlapping_at_the_start_and_laps_on_a_line_are_refused(tmp_path):
    with pytest.raises(ConfigError, match="trains B and A overlap or touch at the start"):
        load_scenario(write(tmp_path, GOOD.replace("gap_m: 0.2", "gap_m: 0.0").replace(
            "start: {behind: A, gap_m: 0.0}", "start: 0.5")))
    line = "layout: straight_test\nlaps: 2\ntrains:\n  - {id: A, start: 1.0}\n"
    with pytest.raises(ConfigError, match=r":2: laps: layout straight_test is an open line"):
        load_scenario(write(tmp_path, line, "line.yaml"))


def test_a_layout_beside_the_scenario_file_is_found(tmp_path):
    (tmp_path / "my_line.yaml").write_text("name: my_line\nclosed: false\nsegments:\n  - straight: {length_m: 2.0}\n"
                                           "stations:\n  - {name: end, s_m: 1.8}\n")
    config = load_scenario(write(tmp_path, "layout: my_line.yaml\ntrains:\n  - {id: A, start: 0.4, stops: [end]}\n"))
    assert config.layout.name == "my_line" and config.trains[0].stops == ("end",)


@pytest.mark.parametrize("name", scenario_names())
def test_every_shipped_scenario_runs_safely(capsys, name):
    assert main(["sim", "--scenario", name, "--duration", "10", "--json"]) == 0
    assert '"collisions": 0' in capsys.readouterr().out


def test_sim_refuses_a_bad_scenario_in_one_line_and_flags_the_file_sets(capsys, tmp_path):
    path = write(tmp_path, GOOD.replace("sead", "x").replace("seed: 3", "sead: 3"))
    assert main(["sim", "--scenario", path]) == 2
    err = capsys.readouterr().err
    assert f"argument --scenario: {path}:2: sead: unknown key" in err and err.count("\n") == 1, err
    assert main(["sim", "--scenario", "paper_itb", "--trains", "3"]) == 2
    assert "--trains: the scenario paper_itb sets it" in capsys.readouterr().err


def test_a_fixed_block_scenario_whose_trains_cannot_move_is_refused_at_its_line(tmp_path):
    text = "layout: lego_oval\npolicy: fixed_block\nblocks: 3\ntrains:\n" + "".join(
        f"  - {{id: T{k}, start: {0.8 * k}}}\n" for k in range(4))
    with pytest.raises(ConfigError, match=r":3: policy: fixed block: 4 trains on the 3 blocks"):
        load_scenario(write(tmp_path, text))
