"""The command line as a whole: its version, and a reader that leaves early."""

import os
import subprocess
import sys

import pytest

from cbtc.cli import main


def test_version_names_the_installed_package(capsys):
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("cbtc ")


def test_a_reader_that_closed_its_end_of_the_pipe_ends_the_command_quietly():
    """`cbtc layout show lego_oval | head -c 1`, made certain: the pipe's read end is closed before the command starts,
    so its first write meets a closed pipe. It exits 0 with nothing on stderr (no BrokenPipeError traceback)."""
    read_fd, write_fd = os.pipe()
    os.close(read_fd)
    try:
        done = subprocess.run([sys.executable, "-m", "cbtc.cli", "layout", "show", "lego_oval"], stdout=write_fd,
                              stderr=subprocess.PIPE, timeout=120)
    finally:
        os.close(write_fd)
    assert done.returncode == 0 and done.stderr == b"", done.stderr.decode()


@pytest.mark.parametrize("argv,named", [
    (["sim", "--trains", "0"], "argument --trains: 0 is out of range"),
    (["sim", "--trains", "-2"], "argument --trains: -2 is out of range"),
    (["sim", "--seed", "-1"], "argument --seed: -1 is out of range"),
    (["sim", "--duration", "0"], "argument --duration: 0 is not a duration"),
    (["sim", "--duration", "nan"], "argument --duration: nan is not a duration"),
    (["sim", "--duration", "inf"], "argument --duration: inf is not a duration"),
    (["sim", "--duration", "-5"], "argument --duration: -5 is not a duration"),
    (["sim", "--plot", "/nonexistent-folder/x.png"], "argument --plot: /nonexistent-folder/x.png: folder"),
    (["compare", "--laps", "0"], "argument --laps: 0 is out of range"),
    (["compare", "--plot", "/nonexistent-folder/c.png"], "argument --plot"),
    (["demo", "--laps", "0"], "argument --laps: 0 is out of range"),
    (["demo", "--seed", "x"], "argument --seed: 'x' is not a whole number"),
])
def test_a_bad_value_is_refused_in_one_line_before_any_work(capsys, argv, named):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err, err
    assert err.count("\n") == 1 and "Traceback" not in err and "--help" in err, err
