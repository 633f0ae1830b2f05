"""The README's live run, as written: `cbtc setup`, then the broker, the zone and the trains from its folder, over a
real Mosquitto on a free port; the trains run and nothing collides. And what --setup refuses."""

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from cbtc.bus.broker_config import MosquittoProcess, free_port
from cbtc.cli import main

README = Path(__file__).resolve().parent.parent / "README.md"


def _recipe():
    block = re.search(r"<!-- live-run -->\n```sh\n(.*?)```\n<!-- /live-run -->", README.read_text(), re.S).group(1)
    return [shlex.split(line.split("#", 1)[0]) for line in block.splitlines() if line.strip()]


def _cbtc(words):
    assert words[0] == "cbtc", words
    return [sys.executable, "-m", "cbtc.cli", *words[1:]]


@pytest.mark.mosquitto
def test_the_readmes_live_run_runs_as_written(tmp_path):
    setup, broker, zone, trains = _recipe()
    assert broker[0] == "mosquitto" and zone[:2] == ["cbtc", "zone"] and trains[:2] == ["cbtc", "trains"]
    port = free_port()
    as_root = ["--run-as", "root"] if hasattr(os, "geteuid") and os.geteuid() == 0 else []
    done = subprocess.run(_cbtc(setup) + ["--port", str(port)] + as_root, cwd=tmp_path, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    mosquitto = MosquittoProcess(str(tmp_path / broker[2]), port).start()
    try:
        zone_proc = subprocess.Popen(_cbtc(zone) + ["--duration", "16", "--quiet", "--summary-json", "zone.json"],
                                     cwd=tmp_path, stderr=subprocess.PIPE, text=True)
        ran = subprocess.run(_cbtc(trains) + ["--duration", "12", "--quiet", "--summary-json", "trains.json"],
                             cwd=tmp_path, capture_output=True, text=True, timeout=90)
        _, zone_err = zone_proc.communicate(timeout=60)
    finally:
        mosquitto.kill()
    assert ran.returncode == 0 and zone_proc.returncode == 0, (ran.stderr, zone_err)
    summary = json.loads((tmp_path / "trains.json").read_text())
    assert summary["collisions"] == 0
    assert all(t["distance_m"] > 0.5 for t in summary["trains"]), summary["trains"]
    assert json.loads((tmp_path / "zone.json").read_text())["invalid_reports"] == 0


def test_setup_refuses_what_it_would_contradict(tmp_path, capsys):
    assert main(["setup", "--layout", "itb_square", "--out", str(tmp_path / "live")]) == 0
    capsys.readouterr()
    for argv, named in [
        (["zone", "--setup", str(tmp_path / "live"), "--layout", "lego_oval"], "--layout: --setup"),
        (["trains", "--setup", str(tmp_path / "live"), "--broker", "mqtt://127.0.0.1:1"], "--broker: --setup"),
        (["trains", "--setup", str(tmp_path)], "holds no live.json"),
        (["setup", "--layout", "itb_square", "--out", str(tmp_path / "live")], "exists"),
        (["trains", "--layout", "itb_square"], "--broker: give the broker"),
    ]:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert named in err and err.count("\n") == 1 and "Traceback" not in err, err


@pytest.mark.mosquitto
def test_trains_from_a_setup_refuse_a_zone_with_other_keys_in_one_line(tmp_path):
    """The zone runs with keys of its own, the trains with the setup's: the trains read the zone's key checks and
    refuse at start, in one line naming the keys and the fix (tests/test_zone_match.py: every mismatch)."""
    port = free_port()
    as_root = ["--run-as", "root"] if hasattr(os, "geteuid") and os.geteuid() == 0 else []
    assert main(["setup", "--layout", "itb_square", "--port", str(port), "--out", str(tmp_path / "live"),
                 *as_root]) == 0
    assert main(["keys", "new", "--train-ids", "A,B", "--out", str(tmp_path / "other.json")]) == 0
    mosquitto = MosquittoProcess(str(tmp_path / "live" / "mosquitto.conf"), port).start()
    try:
        zone = subprocess.Popen(_cbtc(["cbtc", "zone", "--broker", f"mqtt://127.0.0.1:{port}", "--layout",
                                       "itb_square", "--train-ids", "A,B", "--keys", str(tmp_path / "other.json"),
                                       "--credentials", str(tmp_path / "live" / "credentials.json"),
                                       "--duration", "8", "--quiet"]),
                                stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        assert zone.stdout.readline().startswith("zone zc1:")   # online, its info out
        trains = subprocess.run(_cbtc(["cbtc", "trains", "--setup", str(tmp_path / "live"), "--duration", "4",
                                       "--quiet"]), capture_output=True, text=True, timeout=60)
        zone.terminate()
        _, zone_err = zone.communicate(timeout=60)
    finally:
        mosquitto.kill()
    assert trains.returncode == 2, trains.stderr
    lines = [line for line in trains.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and "the keys of trains A, B (keys file" in lines[0] and "is not zone zc1's" not in \
        lines[0] and "are not zone zc1's" in lines[0] and "Traceback" not in trains.stderr, trains.stderr
