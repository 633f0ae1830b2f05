"""Zone and trains that do not match refuse to run, each with one line naming the mismatch and the fix: the zone's
retained info (cbtc/zc/<zone>/info: protocol version, layout digest, a check of each train's key) read by `cbtc
trains` at start and while it runs, and the zone's own end-of-run line for boards it never could take."""

import json
import subprocess
import sys
import time

import paho.mqtt.client as mqtt
import pytest

from cbtc.cli import main
from cbtc.layout_files import load_layout
from cbtc.live.keys import train_keys
from cbtc.live.zone_match import ZoneMatch
from cbtc.protocol import wire, wire_zc, zone_info

KEYS = {"A": bytes(16), "B": bytes(range(16))}


def _info(layout="itb_square", keys=KEYS, zone="zc1"):
    lay = load_layout(layout)
    return zone_info.decode_info(wire_zc.topic_zone_info(zone),
                                 zone_info.encode_info(zone, 7, lay.name, lay.digest(), keys))


def test_the_info_says_what_the_zone_runs_and_matching_trains_find_nothing_wrong():
    info = _info()
    assert list(info) == ["v", "k", "id", "sid", "layout", "digest", "checks"]
    lay = load_layout("itb_square")
    assert zone_info.mismatches(info, lay.name, lay.digest(), KEYS, "keys file k.json") == []
    assert zone_info.mismatches(info, lay.name, lay.digest(), {"A": KEYS["A"]}, "k") == []   # a part of its fleet


def test_each_mismatch_is_one_sentence_with_its_fix():
    info, oval = _info(), load_layout("lego_oval")
    lay = load_layout("itb_square")
    [layout] = zone_info.mismatches(info, oval.name, oval.digest(), KEYS, "k")
    assert "zone zc1 runs layout 'itb_square' and these trains 'lego_oval'" in layout and "--setup DIR" in layout
    [key] = zone_info.mismatches(info, lay.name, lay.digest(), dict(KEYS, B=bytes(16)), "keys file other.json")
    assert "the key of train B (keys file other.json) is not zone zc1's" in key and "--keys FILE" in key
    [stranger] = zone_info.mismatches(info, lay.name, lay.digest(), dict(KEYS, C=bytes(16)), "k")
    assert "zone zc1 does not govern train C (its trains: A, B)" in stranger
    old = dict(info, v=wire.VERSION - 1)
    [version] = zone_info.mismatches(old, lay.name, lay.digest(), KEYS, "k")
    assert f"speaks protocol version {wire.VERSION - 1} and these trains version {wire.VERSION}" in version


def test_a_layout_digest_is_the_railways_not_the_files():
    assert load_layout("itb_square").digest() == load_layout("itb_square").digest()
    digests = {load_layout(name).digest() for name in ("itb_square", "lego_oval", "lego_long_oval")}
    assert len(digests) == 3


@pytest.mark.parametrize("payload, named", [
    (b"not json", "is not JSON"),
    (b"[1]", "not a JSON object"),
    (json.dumps({"v": wire.VERSION, "k": "rep", "id": "zc1"}).encode(), "names k 'rep'"),
    (json.dumps({"v": wire.VERSION, "k": "info", "id": "zc2"}).encode(), "names id 'zc2'"),
    (json.dumps({"v": wire.VERSION, "k": "info", "id": "zc1", "sid": 1, "layout": "x", "digest": "zz",
                 "checks": {}}).encode(), "field 'digest'"),
    (json.dumps({"v": wire.VERSION, "k": "info", "id": "zc1", "sid": 1, "layout": "x", "digest": "0" * 16,
                 "checks": {"A": "0" * 16}, "extra": 1}).encode(), "unknown field 'extra'"),
])
def test_a_malformed_info_is_named(payload, named):
    with pytest.raises(wire.WireError, match=named):
        zone_info.decode_info(wire_zc.topic_zone_info("zc1"), payload)


class _Bus:
    def __init__(self):
        self.handlers = {}

    def subscribe(self, topic_filter, callback):
        self.handlers[topic_filter] = callback


def test_trains_heed_only_an_online_zones_info_and_forget_a_cleared_one():
    bus, stops = _Bus(), []
    oval = load_layout("lego_oval")
    match = ZoneMatch(bus, oval, KEYS, "k", lambda: stops.append(1))
    lay = load_layout("itb_square")
    info = zone_info.encode_info("zc1", 7, lay.name, lay.digest(), KEYS)
    bus.handlers[zone_info.INFO_FILTER]("cbtc/zc/zc1/info", info)
    bus.handlers[zone_info.STATUS_FILTER]("cbtc/zc/zc1/status", b"offline")   # a killed zone's info: not heeded
    assert match.problems == [] and stops == []
    bus.handlers[zone_info.INFO_FILTER]("cbtc/zc/zc1/info", b"")              # cleared
    bus.handlers[zone_info.STATUS_FILTER]("cbtc/zc/zc1/status", b"online")
    assert match.problems == [] and stops == []
    bus.handlers[zone_info.INFO_FILTER]("cbtc/zc/zc1/info", info)
    assert len(match.problems) == 1 and "runs layout 'itb_square'" in match.problems[0] and stops == [1]
    bus.handlers[zone_info.INFO_FILTER]("cbtc/zc/zc2/info", b"junk")
    assert stops == [1]                                                       # said once


def test_a_zone_id_that_is_no_topic_level_is_refused(capsys):
    assert main(["zone", "--broker", "mqtt://127.0.0.1:1", "--layout", "itb_square", "--zone-id", "a/b"]) == 2
    err = capsys.readouterr().err
    assert "zone id 'a/b' has '/'" in err and err.count("\n") == 1


# --- over a real Mosquitto ---------------------------------------------------------------------------------------

def _cbtc(*words):
    return [sys.executable, "-m", "cbtc.cli", *words]


def _zone(url, *more, duration="8"):
    """A zone started and online: its first line printed (its info is out)."""
    proc = subprocess.Popen(_cbtc("zone", "--broker", url, "--duration", duration, "--quiet", *more),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.startswith("zone zc1:"), (line, proc.stderr.read() if proc.poll() is not None else "")
    return proc


def _trains(url, *more, duration="3"):
    return subprocess.run(_cbtc("trains", "--broker", url, "--duration", duration, "--quiet", *more),
                          capture_output=True, text=True, timeout=60)


def _errors(stderr):
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert "Traceback" not in stderr and all(line.startswith("cbtc trains: error: ") for line in lines), stderr
    return lines


@pytest.mark.mosquitto
def test_trains_refuse_a_running_zone_of_another_layout_or_keys(mosquitto, tmp_path):
    url = mosquitto.url
    assert main(["keys", "new", "--train-ids", "A,B", "--out", str(tmp_path / "keys.json")]) == 0
    zone = _zone(url, "--layout", "itb_square", "--train-ids", "A,B", "--keys", str(tmp_path / "keys.json"))
    try:
        started = time.monotonic()
        other_layout = _trains(url, "--layout", "lego_oval", "--train-ids", "A,B", "--keys",
                               str(tmp_path / "keys.json"))
        other_keys = _trains(url, "--layout", "itb_square", "--train-ids", "A,B")
        refused_s = time.monotonic() - started
    finally:
        zone.terminate()
        zone.communicate(timeout=30)
    assert other_layout.returncode == 2 and other_keys.returncode == 2
    [line] = _errors(other_layout.stderr)
    assert "zone zc1 runs layout 'itb_square' and these trains 'lego_oval'" in line
    [line] = _errors(other_keys.stderr)
    assert "the keys of trains A, B (--sim-seed 0) are not zone zc1's" in line
    assert "trains:" not in other_layout.stdout        # refused before a train ran
    assert refused_s < 12, refused_s                   # at start, not at the end of their 3 s


@pytest.mark.mosquitto
def test_trains_already_running_stop_when_a_zone_of_another_layout_comes_online(mosquitto):
    url = mosquitto.url
    trains = subprocess.Popen(_cbtc("trains", "--broker", url, "--layout", "lego_oval", "--train-ids", "A,B",
                                    "--duration", "30", "--quiet"),
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert trains.stdout.readline().startswith("trains:")
    zone = _zone(url, "--layout", "itb_square", "--train-ids", "A,B")
    try:
        _out, err = trains.communicate(timeout=20)     # long before its 30 s
    finally:
        zone.terminate()
        zone.communicate(timeout=30)
    assert trains.returncode == 2
    [line] = _errors(err)
    assert "runs layout 'itb_square'" in line


@pytest.mark.mosquitto
def test_trains_refuse_a_zone_of_another_protocol_version(mosquitto):
    """A zone of another version (its info as such a zone writes it, online): the trains name both versions."""
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="old-zone")
    client.connect("127.0.0.1", mosquitto.port)
    client.loop_start()
    old = {"v": wire.VERSION - 1, "k": "info", "id": "zc9", "layout": "itb_square"}
    client.publish(wire_zc.topic_zone_info("zc9"), json.dumps(old), qos=1, retain=True).wait_for_publish(5)
    client.publish(wire_zc.topic_zone_status("zc9"), b"online", qos=1, retain=True).wait_for_publish(5)
    client.loop_stop()
    client.disconnect()
    ran = _trains(mosquitto.url, "--layout", "itb_square")
    assert ran.returncode == 2
    [line] = _errors(ran.stderr)
    assert f"zone zc9 speaks protocol version {wire.VERSION - 1} and these trains version {wire.VERSION}" in line


@pytest.mark.mosquitto
def test_the_zone_names_boards_of_other_keys_or_another_version_at_its_end(mosquitto):
    """Boards the zone cannot take (a board does not read the zone's info): one of another key, one of another
    version (sealed with the zone's key); the zone runs on, then ends with a line for each and exit 1."""
    url = mosquitto.url
    zone = _zone(url, "--layout", "itb_square", "--train-ids", "A,B", "--sim-seed", "3", duration="4")
    keys = train_keys(["A", "B"], None, 3)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="boards")
    client.connect("127.0.0.1", mosquitto.port)
    client.loop_start()
    for seq in range(1, 11):
        client.publish(wire.topic_report("A"), wire.encode_report(bytes(16), "A", 5, seq, 50 * seq, 0, 0, 0, "idle",
                                                                 -1, -1, None, [], []))
        payload = wire.encode_report(keys["B"], "B", 5, seq, 50 * seq, 0, 0, 0, "idle", -1, -1, None, [], [])
        body = dict(json.loads(payload[:payload.rindex(b"#")]), v=wire.VERSION + 1)
        client.publish(wire.topic_report("B"), wire.seal(keys["B"], wire.topic_report("B"),
                                                         json.dumps(body).encode()))
        time.sleep(0.05)
    client.loop_stop()
    client.disconnect()
    _out, err = zone.communicate(timeout=30)
    assert zone.returncode == 1, err
    lines = [line for line in err.splitlines() if "error" in line]
    assert len(lines) == 2 and "train A reported, but never with a report this zone could authenticate" in lines[0]
    assert f"train B reported, but in another protocol version than this zone's ({wire.VERSION})" in lines[1]
