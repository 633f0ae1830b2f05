"""`cbtc flash` against a test board: the MicroPython unix port on a pseudo-terminal (cbtc.board.virtual_board).

The deployed firmware must boot there (its boot message is what flash waits for) and report over a real Mosquitto.
Failures are BoardErrors that name the port: no such port, a port nobody answers on, a copy that cannot land.
"""

import json
import os
import pty
import time

import pytest

from cbtc.board.flash import flash, parse_broker, train_config_source
from cbtc.board.virtual_board import PtyBoard
from cbtc.cli import main as cli_main
from cbtc.errors import BoardError, ConfigError
from mpy_harness import build_host_only, requires_micropython, requires_umqtt
from test_board_mqtt import KEY, Controller, Mosquitto, free_port

pytestmark = [requires_micropython, requires_umqtt]


@pytest.fixture
def board(tmp_path):
    fs_dir = tmp_path / "fs"
    fs_dir.mkdir()
    host = build_host_only(str(tmp_path / "host"))
    bench = PtyBoard(str(fs_dir), host).start()
    yield bench
    bench.stop()


def test_flash_deploys_verifies_and_the_board_reports(board, tmp_path):
    broker = Mosquitto(str(tmp_path), free_port())
    broker.start()
    zc = Controller(broker.port)
    try:
        rc = cli_main(["flash", "--port", board.port, "--train", "A", "--broker", "mqtt://127.0.0.1:%d" % broker.port,
                       "--wifi-ssid", "lab", "--wifi-password", "pw", "--key", KEY.hex()])
        assert rc == 0
        files = sorted(os.listdir(board.fs_dir))
        assert "main.py" in files and "obu.mpy" in files and "train_config.py" in files
        assert os.path.exists(os.path.join(board.fs_dir, "drivers", "mfrc522.mpy"))
        report = zc.wait(lambda r: True, 10, "a report from the flashed board")
        assert report["id"] == "A" and report["mode"] == "idle"
        assert board.boots >= 2            # it was reset after the copy and booted the firmware
    finally:
        zc.close()
        broker.stop()


def test_flash_with_credentials_logs_the_board_in_to_a_secured_broker(board, secured_mosquitto, tmp_path, capsys):
    """The broker `cbtc broker config` writes refuses anonymous clients: the board logs in as train-A with the
    password from credentials.json, and its reports arrive. A credentials file without the train is refused before
    the board is touched."""
    broker, creds = secured_mosquitto(["A"])
    creds_path = tmp_path / "credentials.json"
    creds_path.write_text(json.dumps(creds))
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"zc": "x"}))
    argv = ["flash", "--port", board.port, "--train", "A", "--broker", "mqtt://127.0.0.1:%d" % broker.port,
            "--key", KEY.hex()]
    assert cli_main(argv + ["--credentials", str(other)]) == 2
    assert "has no user train-A" in capsys.readouterr().err and os.listdir(board.fs_dir) == []
    zc = Controller(broker.port, login=("zc", creds["zc"]))
    try:
        assert cli_main(argv + ["--credentials", str(creds_path)]) == 0
        report = zc.wait(lambda r: True, 10, "a report from the board logged in to the secured broker")
        assert report["id"] == "A"
    finally:
        zc.close()


def test_flash_takes_the_key_from_the_keys_file_and_a_user_and_password(board, secured_mosquitto, tmp_path):
    """The same keys file the zone controller reads gives the board its key; --username/--password log it in."""
    broker, creds = secured_mosquitto(["A"])
    keys = tmp_path / "keys.json"
    keys.write_text(json.dumps({"A": KEY.hex(), "B": "00" * 16}))
    zc = Controller(broker.port, login=("zc", creds["zc"]))
    try:
        assert cli_main(["flash", "--port", board.port, "--train", "A", "--broker", "mqtt://127.0.0.1:%d" % broker.port,
                         "--keys", str(keys), "--username", "train-A", "--password", creds["train-A"]]) == 0
        report = zc.wait(lambda r: True, 10, "a report sealed with the key from the keys file")
        assert report["id"] == "A"
    finally:
        zc.close()


def test_flash_errors_name_the_port(board, tmp_path):
    with pytest.raises(BoardError, match="/dev/nonexistent-port.*does not exist"):
        flash("/dev/nonexistent-port", "A", KEY.hex(), "mqtt://127.0.0.1")
    master, slave = pty.openpty()              # a port with nothing behind it
    try:
        start = time.monotonic()
        with pytest.raises(BoardError, match=os.ttyname(slave) + ".*did not answer"):
            flash(os.ttyname(slave), "A", KEY.hex(), "mqtt://127.0.0.1", timeout_s=3)
        assert time.monotonic() - start < 10
    finally:
        os.close(master)
        os.close(slave)
    os.mkdir(os.path.join(board.fs_dir, "wire.mpy"))   # a folder in the way: the copy cannot land
    with pytest.raises(BoardError, match=board.port):
        flash(board.port, "A", KEY.hex(), "mqtt://127.0.0.1", timeout_s=20)


def test_flash_refuses_bad_settings_before_touching_the_board(board, capsys):
    with pytest.raises(ConfigError, match="32 hex digits"):
        train_config_source("A", "abcd", "h", 1883)
    with pytest.raises(ConfigError, match="train id"):
        train_config_source("no spaces", KEY.hex(), "h", 1883)
    assert parse_broker("mqtt://10.0.0.2:1884") == ("10.0.0.2", 1884)
    assert parse_broker("broker.local") == ("broker.local", 1883)
    assert cli_main(["flash", "--port", board.port, "--train", "A", "--broker", "https://x", "--key", KEY.hex()]) == 2
    assert "argument --broker" in capsys.readouterr().err
    assert os.listdir(board.fs_dir) == []
