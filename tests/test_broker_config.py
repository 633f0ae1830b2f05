"""The Mosquitto configuration generator and the keys file: formats checked against mosquitto's own tools."""

import base64
import json
import os
import shutil
import stat
import subprocess
import sys

import pytest

from cbtc.bus.broker_config import acl_text, config_text, new_password, password_hash, write_config
from cbtc.cli import main
from cbtc.errors import ConfigError
from cbtc.live.keys import load_keys, train_keys
from cbtc.zone.config import train_key

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.skipif(not shutil.which("mosquitto_passwd"), reason="mosquitto_passwd is not installed")
def test_password_hash_equals_mosquitto_passwd(tmp_path):
    path = tmp_path / "pw"
    subprocess.run(["mosquitto_passwd", "-c", "-b", str(path), "zc", "s3cret pass"], check=True)
    user, hashed = path.read_text().strip().split(":", 1)
    salt = base64.b64decode(hashed.split("$")[3])
    assert user == "zc"
    assert password_hash("s3cret pass", salt) == hashed


def test_password_hash_format():
    hashed = password_hash("x")
    _, kind, rounds, salt, digest = hashed.split("$")
    assert (kind, rounds) == ("7", "101")
    assert len(base64.b64decode(salt)) == 12 and len(base64.b64decode(digest)) == 64
    assert password_hash("x") != hashed   # a fresh salt each time


def test_acl_gives_each_train_only_its_own_topics():
    blocks = [b.strip().splitlines() for b in acl_text(["A", "B2"]).split("\n\n") if b.strip()]
    assert blocks[0][1:] == ["user zc", "topic read cbtc/train/+/report", "topic read cbtc/train/+/status",
                             "topic write cbtc/train/+/cmd", "topic write cbtc/zc/#"]
    zones = ["topic read cbtc/zc/+/status", "topic read cbtc/zc/+/info"]   # what the zones run, read-only
    assert blocks[1] == ["user train-A", "topic write cbtc/train/A/report", "topic write cbtc/train/A/status",
                         "topic read cbtc/train/A/cmd"] + zones
    assert blocks[2][0] == "user train-B2" and all("/B2/" in line for line in blocks[2][1:-2])


def test_config_text_is_closed_loopback_nodelay_stderr():
    lines = config_text(18830, "/etc/cbtc").splitlines()
    for expected in ("listener 18830 127.0.0.1", "allow_anonymous false", "set_tcp_nodelay true", "log_dest stderr",
                     "max_packet_size 1152", "use_username_as_clientid true",
                     "password_file /etc/cbtc/passwd", "acl_file /etc/cbtc/acl"):
        assert expected in lines
    assert "user root" in config_text(1, "/x", run_as="root").splitlines()


def test_write_config_files_and_modes(tmp_path):
    paths = write_config(str(tmp_path / "b"), ["A", "B"], port=1999, credentials={"zc": "given"})
    creds = json.loads(open(paths["credentials.json"]).read())
    assert sorted(creds) == ["train-A", "train-B", "zc"] and creds["zc"] == "given"
    assert stat.S_IMODE(os.stat(paths["credentials.json"]).st_mode) == 0o600
    assert stat.S_IMODE(os.stat(paths["passwd"]).st_mode) == 0o644
    users = [line.split(":")[0] for line in open(paths["passwd"]).read().splitlines()]
    assert users == ["zc", "train-A", "train-B"]
    with pytest.raises(ConfigError, match="duplicate"):
        write_config(str(tmp_path / "c"), ["A", "A"])
    with pytest.raises(ConfigError, match="train id"):
        write_config(str(tmp_path / "c"), ["A/B"])


def test_cli_and_tool_write_the_config(tmp_path, capsys):
    assert main(["broker", "config", "--train-ids", "A,B", "--out", str(tmp_path / "cli"), "--port", "1884"]) == 0
    assert "listener 1884 127.0.0.1" in (tmp_path / "cli" / "mosquitto.conf").read_text()
    # run again: the passwords on the boards are never replaced without being asked
    before = (tmp_path / "cli" / "credentials.json").read_text()
    assert main(["broker", "config", "--train-ids", "A,B", "--out", str(tmp_path / "cli")]) == 2
    assert "--keep-passwords" in capsys.readouterr().err
    assert (tmp_path / "cli" / "credentials.json").read_text() == before
    assert main(["broker", "config", "--train-ids", "A,B,C", "--out", str(tmp_path / "cli"), "--keep-passwords"]) == 0
    kept = json.loads((tmp_path / "cli" / "credentials.json").read_text())
    assert {u: kept[u] for u in json.loads(before)} == json.loads(before) and "train-C" in kept
    assert main(["broker", "config", "--train-ids", "A,B", "--out", str(tmp_path / "cli"), "--force"]) == 0
    assert json.loads((tmp_path / "cli" / "credentials.json").read_text())["zc"] != kept["zc"]
    assert main(["broker", "config", "--train-ids", "A,,A", "--out", str(tmp_path / "bad")]) == 2
    assert "duplicate train ids" in capsys.readouterr().err
    out = subprocess.run([sys.executable, os.path.join(ROOT, "tools", "make_broker_config.py"), "--train-ids", "T1",
                          "--out", str(tmp_path / "tool")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "user train-T1" in (tmp_path / "tool" / "acl").read_text()


def test_keys_new_and_load(tmp_path, capsys):
    path = tmp_path / "keys.json"
    assert main(["keys", "new", "--train-ids", "A,B", "--out", str(path)]) == 0
    keys = load_keys(str(path))
    assert sorted(keys) == ["A", "B"] and all(len(k) == 16 for k in keys.values()) and keys["A"] != keys["B"]
    assert stat.S_IMODE(os.stat(path).st_mode) == 0o600
    assert main(["keys", "new", "--train-ids", "A", "--out", str(path)]) == 2   # never overwrites by accident
    assert "--force" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="no key for trains \\['C'\\]"):
        train_keys(["A", "C"], str(path))
    path.write_text('{"A": "abcd"}')
    with pytest.raises(ConfigError, match="32 hex characters"):
        load_keys(str(path))
    assert train_keys(["A"], None, sim_seed=3) == {"A": train_key(3, "A")}


def test_generated_passwords_pass_as_command_line_values():
    """A password that began with '-' would be read as an option by `cbtc flash --password X`."""
    for _ in range(200):
        password = new_password()
        assert len(password) == 36 and set(password) <= set("0123456789abcdef")
