"""Long commands show a progress bar with the time left on a terminal (a pseudo-terminal here), and none under
`--json` or when stdout is not a terminal."""

import os
import re
import select
import subprocess
import sys
import time

import pytest

from mosquitto_fixture import requires_mosquitto

BAR = re.compile(r"━+.*ETA (\d+:\d\d:\d\d)")   # rich's bar, then the time left once it can be estimated


def on_terminal(argv, stop_at=None, timeout_s=120.0):
    """(what `cbtc argv` draws on a pseudo-terminal 100 columns wide, its escape sequences removed; seconds until
    `stop_at`, a regex, was seen, or None). When `stop_at` is seen the command is stopped there."""
    import pty

    master, slave = pty.openpty()
    env = dict(os.environ, COLUMNS="100", TERM="xterm")
    proc = subprocess.Popen([sys.executable, "-m", "cbtc.cli", *argv], stdin=slave, stdout=slave, stderr=slave,
                            env=env)
    os.close(slave)
    started = time.monotonic()
    seen, deadline, found_s = "", started + timeout_s, None
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 1.0)
            if not ready:
                if proc.poll() is not None:
                    break
                continue
            try:
                chunk = os.read(master, 4096)
            except OSError:   # the terminal closed with the process
                break
            if not chunk:
                break
            seen += re.sub(r"\x1b\[[0-9;?]*[a-zA-Z]", "", chunk.decode(errors="replace"))
            if stop_at is not None and re.search(stop_at, seen):
                found_s = time.monotonic() - started
                break
    finally:
        proc.kill()
        proc.wait(timeout=30)
        os.close(master)
    return seen, found_s


CASES = {
    "sim": ["sim", "--trains", "2", "--duration", "40"],
    "compare": ["compare", "--laps", "1", "--report-ms", "", "--follow-mps", "", "--blocks", ""],
    "campaign": ["campaign", "--runs", "2", "--duration", "5", "--trains", "2", "--layouts", "itb_square",
                 "--workers", "1", "--fresh"],
    "fuzz": ["fuzz", "--payloads", "200"],
}


@pytest.mark.parametrize("name", ["sim", "compare", "campaign", pytest.param("fuzz", marks=requires_mosquitto)])
def test_a_terminal_sees_a_bar_with_the_time_left_and_json_sees_none(name, tmp_path):
    argv = CASES[name] + (["--results", str(tmp_path / "r.jsonl")] if name == "campaign" else [])
    drawn, bar_s = on_terminal(argv, stop_at=BAR.pattern)
    assert BAR.search(drawn) and name in drawn, drawn[-2000:]
    # under --json, watched for twice as long as the bar took to show its time left
    quiet, _ = on_terminal(argv + ["--json"], stop_at=r"━", timeout_s=max(4.0, 2.0 * bar_s))
    assert "━" not in quiet and "ETA" not in quiet, quiet[-2000:]


def test_no_bar_when_stdout_is_not_a_terminal():
    out = subprocess.run([sys.executable, "-m", "cbtc.cli", *CASES["sim"]], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0 and "━" not in out.stdout + out.stderr and "ETA" not in out.stderr


def test_a_run_to_a_number_of_laps_counts_laps_and_ends_at_its_whole():
    """A run that stops at its laps long before its duration cap: its bar counts laps and ends full, not at the
    share of the cap it had simulated."""
    from cbtc.layout_files import load_layout
    from cbtc.sim import progress
    from cbtc.sim.simulation import Simulation
    from cbtc.zone.config import paper_scenario

    seen = []
    config = paper_scenario(load_layout("itb_square"), laps=1, duration_s=300.0)
    with progress.reporting_to(lambda run, done, total, unit: seen.append((done, total, unit))):
        Simulation(config).run()
    assert {unit for _, _, unit in seen[:-1]} == {"laps"} and all(total == 1 for _, total, _ in seen[:-1])
    assert seen[-1] == (1.0, 1.0, "done")
