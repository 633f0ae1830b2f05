"""The command line as a whole: its version, and a reader that leaves early."""

import argparse
import os
import subprocess
import sys

import pytest

from cbtc.cli import build_parser, main
from cbtc.commands import arg_types


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


def _options(parser=None, prefix=()):
    """(command words, action) of every option of every command that takes a value."""
    parser = parser or build_parser()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _options(sub, prefix + (name,))
        elif action.option_strings and action.nargs != 0 and action.help != argparse.SUPPRESS:
            yield prefix, action


# free text by nature (names, passwords, addresses), or lists each command checks itself before any work
FREE_TEXT = {"--username", "--password", "--host", "--run-as", "--zone-id", "--wifi-ssid", "--wifi-password",
             "--key", "--port", "--train", "--fault", "--scheduler", "--layouts", "--report-ms", "--follow-mps",
             "--blocks", "--trains", "--broker", "--points", "--ips-modem"}
NUMERIC = {"whole number", "seed", "train count", "number", "seconds"}


def test_every_option_value_is_checked_while_the_command_line_is_parsed():
    unchecked = [(" ".join(words), a.option_strings[0]) for words, a in _options()
                 if a.choices is None and getattr(a.type, "__module__", None) != arg_types.__name__
                 and a.option_strings[0] not in FREE_TEXT]
    assert not unchecked, f"options without a shared argument type: {unchecked}"


@pytest.mark.parametrize("words,flag", sorted({(words, a.option_strings[0]) for words, a in _options()
                                               if getattr(a.type, "__name__", "") in NUMERIC}))
def test_every_number_option_refuses_text_and_nan_in_one_line(capsys, words, flag):
    for bad in ("x", "nan"):
        assert main(list(words) + [flag, bad]) == 2
        err = capsys.readouterr().err
        assert f"argument {flag}" in err and err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.parametrize("argv,named", [
    (["zone", "--count", "2"], "--count is now --trains N"),
    (["trains", "--trains", "A,B"], "name trains with --train-ids A,B"),
    (["zone", "--train-ids", "A,,A"], "duplicate train ids"),
    (["keys", "new", "--trains", "A,B"], "--trains is now --train-ids A,B"),
    (["broker", "config", "--out", "/nonexistent-folder/b"], "argument --out"),
    (["keys", "new", "--out", "/nonexistent-folder/k.json"], "argument --out"),
    (["guard", "--seeds", "x"], "argument --seeds: 'x' is not a range of seeds"),
    (["sim", "--layout", "no_such_layout"], "layout 'no_such_layout' not found"),
    (["zone", "--broker", "http://127.0.0.1:1883"], "scheme 'http' is not supported"),
    (["zone", "--keys", "/nonexistent-folder/keys.json"], "argument --keys"),
    (["zone", "--summary-json", "/nonexistent-folder/s.json"], "argument --summary-json"),
    (["campaign", "--results", "/nonexistent-folder/r.jsonl"], "argument --results"),
    (["calibrate", "encoder", "--reports", "/nonexistent-folder/run.jsonl"], "argument --reports"),
    (["zone", "--clear-track", "everything"], "argument --clear-track: 'everything' is not a stretch of track"),
    (["zone", "--clear-track", "1-1"], "FROM and TO different"),
    (["zone", "--broker", "mqtt://127.0.0.1:1", "--layout", "itb_square", "--trains", "2", "--clear-track", "0-9"],
     "--clear-track 0-9: not on layout itb_square, whose track runs from 0 to 6.81 m"),
])
def test_the_shared_vocabulary_and_paths_are_refused_in_one_line(capsys, argv, named):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert named in err and err.count("\n") == 1 and "Traceback" not in err, err


def test_trains_and_train_ids_must_agree(capsys):
    argv = ["zone", "--broker", "mqtt://127.0.0.1:1", "--layout", "itb_square", "--trains", "3", "--train-ids", "A,B"]
    assert main(argv) == 2
    assert "--trains 3 and --train-ids A,B disagree" in capsys.readouterr().err


def test_the_command_line_and_every_help_import_nothing_heavy():
    """`cbtc --help` (and any `cbtc X --help`) builds every command's parser: none of them may import numpy, scipy,
    filterpy, matplotlib, paho or yaml to do it (the run functions import what they need)."""
    heavy = ("numpy", "scipy", "filterpy", "matplotlib", "paho", "yaml")
    code = (f"import sys\nfrom cbtc.cli import build_parser\nbuild_parser()\n"
            f"print([m for m in {heavy} if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr


def test_the_zone_and_a_simulation_run_without_scipy_filterpy_or_matplotlib():
    """What `cbtc zone`, `cbtc trains` and `cbtc sim` run (the zone with its filters, virtual trains, the live loop)
    imports none of the heavy reference and plotting libraries: filterpy stays the filter's reference in tests and
    `cbtc bench fusion` only."""
    heavy = ("scipy", "filterpy", "matplotlib")
    code = ("import sys\n"
            "from cbtc.bus.paho_bus import PahoBus\nfrom cbtc.live.loop import LiveLoop\n"
            "from cbtc.sim.virtual_train import VirtualTrain\nfrom cbtc.sim.truth import TruthMonitor\n"
            "from cbtc.zone.factory import build_zone\n"
            "from cbtc.layout_files import load_layout\nfrom cbtc.sim.simulation import Simulation\n"
            "from cbtc.zone.config import paper_scenario\n"
            "Simulation(paper_scenario(load_layout('itb_square'), seed=0, laps=None, duration_s=3.0)).run()\n"
            f"print([m for m in {heavy} if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "[]", done.stdout + done.stderr


def test_every_command_has_examples_and_every_flag_says_what_it_does():
    parser = build_parser()
    silent = [(" ".join(words), a.option_strings[0]) for words, a in _options() if not a.help]
    flags = [(" ".join(words), a.option_strings[0]) for words, a in _all_flags(parser) if not a.help]
    assert not silent and not flags, silent + flags
    commands = parser._subparsers._group_actions[0].choices
    assert all(sub.epilog and sub.epilog.startswith("examples:") for sub in commands.values()), \
        [name for name, sub in commands.items() if not sub.epilog]


def _all_flags(parser, prefix=()):
    """Every option of every command, values or not (--json and other switches too)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _all_flags(sub, prefix + (name,))
        elif action.option_strings and action.dest != "help" and action.help != argparse.SUPPRESS:
            yield prefix, action


# what a command's one-line description starts with: it says what the command does, in one voice
VERBS = {"run", "simulate", "list", "print", "check", "compare", "measure", "write", "decode", "start", "copy",
         "calibrate", "find", "survey", "make", "time", "throw"}


def test_every_command_is_described_in_one_voice_by_what_it_does():
    def described(parser, prefix):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for choice in action._choices_actions:
                    yield f"{prefix} {choice.dest}", choice.help
                    yield from described(action.choices[choice.dest], f"{prefix} {choice.dest}")

    odd = [(name, text) for name, text in described(build_parser(), "cbtc") if text.split()[0] not in VERBS]
    assert not odd, odd
