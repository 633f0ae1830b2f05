"""What a newcomer gives the commands by mistake: each is refused in one line naming the input and the fix, exit 2, no
traceback, nothing written and nothing run."""

import os

import pytest

from cbtc.cli import main
from cbtc.commands import arg_types


def _refused(capsys, argv, named):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err, err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("flag_argv", [
    ["sim", "--trains", "3", "--duration", "5", "--plot"],
    ["demo", "--plot"],
    ["compare", "--plot"],
    ["fusion", "--plot"],
    ["layout", "show", "lego_oval", "--plot"],
])
def test_a_plot_in_a_format_matplotlib_cannot_write_is_refused_before_the_run(capsys, tmp_path, flag_argv):
    out = tmp_path / "x.txt"
    err = _refused(capsys, flag_argv + [str(out)], "a plot is written as png")
    assert "x.png" in err and not out.exists()


def test_a_plot_without_an_extension_is_refused_with_one_that_works(capsys, tmp_path):
    _refused(capsys, ["sim", "--duration", "1", "--plot", str(tmp_path / "run")], f"{tmp_path / 'run'}.png")


def test_the_plot_formats_offered_are_ones_matplotlib_writes():
    from matplotlib.figure import Figure
    supported = set(Figure().canvas.get_supported_filetypes())
    assert set(arg_types.PLOT_FORMATS) <= supported, set(arg_types.PLOT_FORMATS) - supported


@pytest.mark.parametrize("argv", [
    ["calibrate", "encoder", "--distance-m", "2", "--reports"],
    ["calibrate", "tags", "--reports"],
    ["calibrate", "ips", "--points"],
])
def test_a_binary_file_given_for_recorded_data_is_named(capsys, tmp_path, argv):
    data = tmp_path / "run.bin"
    data.write_bytes(bytes(range(256)) * 8)
    _refused(capsys, argv + [str(data)], f"{data} is not UTF-8 text")


def test_trains_that_would_touch_at_the_start_are_refused(capsys):
    _refused(capsys, ["sim", "--trains", "3", "--start-gap", "0"], "argument --start-gap: 0")


def test_the_demos_json_writes_no_picture(tmp_path, capsys):
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        assert main(["demo", "--laps", "1", "--json"]) == 0
    finally:
        os.chdir(cwd)
    assert os.listdir(tmp_path) == [], os.listdir(tmp_path)
    assert capsys.readouterr().out.lstrip().startswith("{")


SCENARIO = """\
name: newcomer
layout: {layout}
duration_s: 10
trains:
{trains}
"""


@pytest.mark.parametrize("layout,trains,named", [
    ("lego_oval", "  - {id: A, start: 99.0}", "past the loop's end"),
    ("lego_oval", "  - {id: A, start: 1.0}\n  - {id: B, start: {behind: A, gap_m: 0}}", "would touch A"),
    ("lego_oval", "  - {id: A, start: 1.0}\n  - {id: B, start: 0.7}", "overlap or touch at the start"),
    ("lego_oval", "  - {id: A, start: 1.0, profile: {length_m: 40.0}}", "does not fit on"),
])
def test_a_scenario_that_cannot_make_sense_is_refused_with_the_fix(capsys, tmp_path, layout, trains, named):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO.format(layout=layout, trains=trains))
    _refused(capsys, ["sim", "--scenario", str(path)], named)


def test_the_scenario_list_says_each_first_sentence_whole(capsys):
    assert main(["scenario", "list"]) == 0
    out = capsys.readouterr().out
    assert all(line.count("`") % 2 == 0 for line in out.splitlines()), out   # no `command` cut across lines
    assert "300 s." in out and "five laps." in out


def test_a_flag_the_command_does_not_take_is_named_by_the_command_with_the_nearest_it_has(capsys, tmp_path):
    (tmp_path / "r").write_text("{}\n")
    for argv, said in ((["zone", "--brokr", "x"], "cbtc zone: error: unrecognized arguments: --brokr x; did you mean "
                                                  "--broker? (see cbtc zone --help)"),
                       (["calibrate", "encoder", "--reports", str(tmp_path / "r"), "--distance-m", "1",
                         "--train-id", "A"],
                        "cbtc calibrate encoder: error: unrecognized arguments: --train-id A; did you mean --train?")):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert said in err and err.count("\n") == 1, err


def test_a_device_given_for_a_file_is_named_as_not_a_file(capsys):
    assert main(["calibrate", "encoder", "--reports", "/dev/null", "--distance-m", "1"]) == 2
    assert "/dev/null is not a regular file" in capsys.readouterr().err
