"""A live command that cannot use its broker says why within a second or two, one line with the fix: nothing
listening, an unknown host, a login refused (naming the credentials file it came from)."""

import json
import socket
import subprocess
import sys
import time

import pytest


def _cbtc(*argv, timeout_s=30):
    started = time.monotonic()
    done = subprocess.run([sys.executable, "-m", "cbtc.cli", *argv], capture_output=True, text=True,
                          timeout=timeout_s)
    return done, time.monotonic() - started


def _closed_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("command", ["zone", "trains"])
def test_nothing_listening_is_said_within_seconds(command):
    port = _closed_port()
    done, took_s = _cbtc(command, "--broker", f"mqtt://127.0.0.1:{port}", "--layout", "itb_square", "--trains", "2",
                         "--duration", "5")
    assert done.returncode == 2, done.stderr
    assert f"nothing listens at 127.0.0.1:{port} (connection refused)" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1, done.stderr
    assert took_s < 8.0   # the interpreter's start and imports included


def test_an_unknown_host_is_said_at_once():
    done, _ = _cbtc("zone", "--broker", "mqtt://no-such-broker.invalid:1883", "--layout", "itb_square", "--trains",
                    "2", "--duration", "5")
    assert done.returncode == 2 and "unknown host 'no-such-broker.invalid'" in done.stderr, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr


@pytest.mark.mosquitto
def test_a_login_refused_names_the_credentials_file(secured_mosquitto, tmp_path):
    broker, creds = secured_mosquitto(["A", "B"])
    wrong = tmp_path / "credentials.json"
    wrong.write_text(json.dumps({user: "not-the-password" for user in creds}))
    done, _ = _cbtc("zone", "--broker", broker.url, "--credentials", str(wrong), "--layout", "itb_square",
                    "--train-ids", "A,B", "--duration", "5")
    assert done.returncode == 2, done.stderr
    assert "refused the login" in done.stderr and f"the credentials file {wrong} (user zc)" in done.stderr, \
        done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
