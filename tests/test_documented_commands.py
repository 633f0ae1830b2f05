"""Every command line written in the README, in docs/ and in a command's `--help` examples runs as written and
succeeds. Lines that need what only a user has (a board on a serial port, their broker's address, their own files or
recorded runs) are listed apart and must still be valid command lines; live examples on 127.0.0.1:1883 run against a
private Mosquitto on a free port."""

import glob
import os
import re
import shlex
import subprocess
import sys

import pytest

from cbtc.cli import build_parser, main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# a user's own things: their board's port, their broker's address, their files, placeholders
USERS_OWN = re.compile(r"HOST|PORT\b|FILE\b|<|\.\.\.|/dev/tty|192\.168\.|my_table|run\.jsonl|points\.csv|"
                       r"keys\.json --|credentials\.json|--setup |/dev/pts/N|board virtual")
# --setup: the live run (tests/test_live_setup.py); the rehearsal board runs until stopped
# (tests/test_rehearsal_board.py)
LIVE_URL = "mqtt://127.0.0.1:1883"


def _fenced_lines(path):
    """`cbtc ...` command lines in the shell blocks of a Markdown file (continuations joined, comments dropped)."""
    lines, block, kind = [], False, ""
    text = open(path, encoding="utf-8").read().replace("\\\n", " ")
    for raw in text.splitlines():
        if raw.startswith("```"):
            block, kind = not block, raw[3:].strip()
            continue
        if not block or kind not in ("", "sh"):
            continue
        line = raw.split(" # ")[0].split("  #")[0].strip()
        for part in line.split("&&"):
            part = " ".join(part.split())
            if part.startswith("cbtc ") and not re.match(r"cbtc [a-z ]+:", part):   # not a printed error
                lines.append(part)
    return lines


def documented():
    found = []
    for path in [os.path.join(ROOT, "README.md")] + sorted(glob.glob(os.path.join(ROOT, "docs", "*.md"))):
        found += [(os.path.relpath(path, ROOT), line) for line in _fenced_lines(path)]
    parser = build_parser()
    for action in parser._subparsers._group_actions:
        for name, sub in action.choices.items():
            for line in (sub.epilog or "").splitlines()[1:]:
                found.append((f"cbtc {name} --help", line.strip()))
    return found


DOCUMENTED = documented()
OFFLINE = sorted({line for _where, line in DOCUMENTED if not USERS_OWN.search(line) and "mqtt://" not in line})
LIVE = sorted({line for _where, line in DOCUMENTED if not USERS_OWN.search(line) and LIVE_URL in line})
USERS = sorted({line for _where, line in DOCUMENTED if USERS_OWN.search(line)})


def test_the_documents_and_every_command_have_examples():
    assert len(OFFLINE) >= 20 and LIVE and USERS
    helped = {where for where, _line in DOCUMENTED if where.endswith("--help")}
    assert {"cbtc sim --help", "cbtc compare --help", "cbtc demo --help", "cbtc campaign --help",
            "cbtc zone --help", "cbtc scenario --help"} <= helped


@pytest.mark.parametrize("line", OFFLINE)
def test_a_documented_command_runs_as_written(line, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    status = main(shlex.split(line)[1:])
    out = capsys.readouterr()
    assert status == 0, f"{line}\n{out.out[-1500:]}\n{out.err[-1500:]}"


@pytest.mark.mosquitto
@pytest.mark.parametrize("line", LIVE)
def test_a_documented_live_command_runs_against_a_broker(line, mosquitto, tmp_path):
    argv = shlex.split(line.replace(LIVE_URL, mosquitto.url))
    done = subprocess.run([sys.executable, "-m", "cbtc.cli", *argv[1:]], cwd=tmp_path, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, f"{line}\n{done.stdout[-1500:]}\n{done.stderr[-1500:]}"


@pytest.mark.parametrize("line", USERS)
def test_a_command_that_needs_your_board_or_files_is_still_a_valid_command_line(line, tmp_path, monkeypatch):
    """Its flags and values parse, with the files it names present (their contents are the user's)."""
    monkeypatch.chdir(tmp_path)
    for name in ("run.jsonl", "points.csv", "keys.json", "my_table.yaml"):
        (tmp_path / name).write_text("")
    (tmp_path / "broker").mkdir()
    (tmp_path / "broker" / "credentials.json").write_text("{}")
    (tmp_path / "my_table.yaml").write_text("layout: itb_square\ntrains:\n  - {id: A, start: main}\n")
    assert main(["setup", "--layout", "itb_square", "--out", str(tmp_path / "live")]) == 0   # the live run's folder
    argv = shlex.split(re.sub(r"<[^>]*>", "00112233445566778899aabbccddeeff",
                              line.replace("HOST:PORT", "127.0.0.1:1883").replace("...", "")))
    build_parser().parse_args(argv[1:])
