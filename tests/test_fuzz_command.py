"""`cbtc fuzz`: bad values are refused before anything starts; the campaign itself (a live zone and trains over a
real Mosquitto) runs in the long profile, `pytest -m fuzz`."""

import json
import subprocess
import sys

import pytest

from cbtc.cli import main
from mosquitto_fixture import requires_mosquitto


def cbtc(*args, timeout_s=300):
    return subprocess.run([sys.executable, "-m", "cbtc.cli", *args], capture_output=True, text=True,
                          timeout=timeout_s)


@pytest.mark.parametrize("args, says", [
    (["--payloads", "0"], "--payloads: 0 is out of range"),
    (["--seed", "-1"], "--seed: -1 is out of range"),
    (["--broker", "ftp://host"], "scheme 'ftp' is not supported"),
])
def test_bad_values_are_refused_before_anything_starts(args, says, capsys):
    assert main(["fuzz", *args]) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err


@pytest.mark.fuzz
@requires_mosquitto
def test_nothing_gets_through_and_the_zone_governs_after_the_campaign():
    out = cbtc("fuzz", "--payloads", "3000", "--seed", "7", "--json")
    assert out.returncode == 0, out.stdout + out.stderr
    result = json.loads(out.stdout)
    assert result["payloads"] == 3000 and all(n == 600 for n in result["by_class"].values())
    assert result["uncaught_exceptions"] == 0 and result["accepted_invalid"] == 0
    assert result["moved_without_authority"] == 0 and result["collisions"] == 0
    assert result["controller_alive"] and result["picture_finite"]
    assert result["reports_refused"] > 1000 and result["commands_refused_onboard"] > 500
