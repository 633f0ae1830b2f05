"""The README's rehearsal, as written: a rehearsal board (`cbtc board virtual`: the real firmware under the
MicroPython unix port on a pty, its wheel pushed), flashed by `cbtc flash`, recorded by the zone over a real
Mosquitto, and `cbtc calibrate encoder` finding the wheel's true scale from the recording."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from cbtc.bus.broker_config import MosquittoProcess, mosquitto_exe
from cbtc.cli import main
from mpy_harness import requires_micropython

README = Path(__file__).resolve().parent.parent / "README.md"


def _recipe():
    block = re.search(r"<!-- rehearsal -->\n```sh\n(.*?)```\n<!-- /rehearsal -->", README.read_text(), re.S).group(1)
    return [shlex.split(line.split("#", 1)[0]) for line in block.splitlines() if line.strip()]


def _cbtc(words, port, pts=None):
    assert words[0] == "cbtc", words
    text = [w.replace("127.0.0.1:1883", f"127.0.0.1:{port}") for w in words[1:]]
    if pts is not None:
        text = [pts if w == "/dev/pts/N" else w for w in text]
    return [sys.executable, "-m", "cbtc.cli", *text]


@requires_micropython
@pytest.mark.mosquitto
@pytest.mark.skipif(not mosquitto_exe(), reason="mosquitto is not installed")
def test_the_readmes_rehearsal_flashes_records_and_calibrates_as_written(tmp_path):
    keys, broker, board, flash, zone, calibrate = _recipe()
    assert broker == ["mosquitto", "-p", "1883"] and board[:3] == ["cbtc", "board", "virtual"]
    mosquitto = MosquittoProcess.open_broker(str(tmp_path / "broker")).start()
    port = mosquitto.port
    board_proc = None
    try:
        assert subprocess.run(_cbtc(keys, port), cwd=tmp_path, timeout=60).returncode == 0
        board_proc = subprocess.Popen(_cbtc(board, port) + ["--duration", "90"], cwd=tmp_path,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        first = board_proc.stdout.readline()
        pts = re.search(r"on (/dev/pts/\d+)", first)
        assert pts, (first, board_proc.stderr.read() if board_proc.poll() is not None else "")
        flashed = subprocess.run(_cbtc(flash, port, pts.group(1)), cwd=tmp_path, capture_output=True, text=True,
                                 timeout=120)
        assert flashed.returncode == 0 and "booted firmware" in flashed.stdout, flashed.stderr
        recorded = subprocess.run(_cbtc(zone, port), cwd=tmp_path, capture_output=True, text=True, timeout=120)
        assert recorded.returncode == 0, recorded.stderr
        calibrated = subprocess.run(_cbtc(calibrate, port), cwd=tmp_path, capture_output=True, text=True,
                                    timeout=60)
    finally:
        if board_proc is not None:
            board_proc.terminate()
            out, _err = board_proc.communicate(timeout=30)
        mosquitto.kill()
    assert calibrated.returncode == 0, calibrated.stderr
    assert "counts_per_m = 1040" in calibrated.stdout, calibrated.stdout
    assert "pushed 1.000 m (1040 counts)" in out, out      # the board said how far, for --distance-m


def test_a_rehearsal_board_with_no_terminal_to_press_enter_on_is_refused(capsys, monkeypatch):
    import io

    monkeypatch.setattr(sys, "stdin", io.StringIO(""))
    monkeypatch.setattr("shutil.which", lambda name: "/bin/true")
    assert main(["board", "virtual"]) == 2
    err = capsys.readouterr().err
    assert "--push-after-s: stdin is not a terminal" in err and err.count("\n") == 1


def test_a_push_past_the_boards_reach_is_refused_before_anything_starts(capsys):
    assert main(["board", "virtual", "--push-mps", "5", "--push-after-s", "1"]) == 2
    err = capsys.readouterr().err
    assert "--push-mps" in err and err.count("\n") == 1
