"""End to end over a real Mosquitto: `cbtc zone` and `cbtc trains` as separate processes, and the faults.

The trains process writes the trains' truth (positions, speeds, onboard mode, end of authority, rejected commands,
collisions) to a JSON file every 0.2 s; the zone controller writes its figures at exit. Oracles: the truth-based
collision count (as scenario.Recorder counts it), a train at rest (v = 0) with its head not past its end of
authority (odometer <= eoa), the reject counters of the OnboardUnit and of the controller.
"""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from cbtc.bus.paho_bus import PahoBus
from cbtc.errors import BusError
from cbtc.protocol import wire, wire_zc

pytestmark = pytest.mark.mosquitto

LAYOUT = "itb_square"
SIM_SEED = 0
EOA_TOLERANCE_MM = 5       # the odometer is read in whole mm
STOP_WAIT_S = 3.0          # command ttl 0.8 s + braking from 0.6 m/s at 0.8 m/s^2 (0.75 s) + slack


def cbtc(*args):
    return [sys.executable, "-m", "cbtc.cli", *args]


class Fleet:
    """A zone controller process and a trains process on one broker, with their files in `folder`."""

    def __init__(self, broker, folder):
        self.broker = broker
        self.folder = folder
        self.status_path = os.path.join(folder, "trains-status.json")
        self.trains_summary = os.path.join(folder, "trains-summary.json")
        self.zones = []
        self.trains = None

    def start_zone(self, tag="zone"):
        out = open(os.path.join(self.folder, tag + ".out"), "w")
        err_path = os.path.join(self.folder, tag + ".err")
        proc = subprocess.Popen(cbtc("zone", "--broker", self.broker.url, "--layout", LAYOUT, "--train-ids", "A,B",
                                     "--clear-track", "all", "--sim-seed", str(SIM_SEED), "--summary-json",
                                     os.path.join(self.folder, tag + "-summary.json"), "--status-period", "0.2",
                                     "--status-json", os.path.join(self.folder, tag + "-status.json")),
                                stdout=out, stderr=open(err_path, "w"))
        self.zones.append((proc, tag))
        return proc

    def start_trains(self, duration_s):
        self.trains = subprocess.Popen(
            cbtc("trains", "--broker", self.broker.url, "--layout", LAYOUT, "--trains", "2", "--sim-seed",
                 str(SIM_SEED), "--duration", str(duration_s), "--status-period", "0.2", "--status-json",
                 self.status_path, "--summary-json", self.trains_summary, "--quiet"),
            stdout=open(os.path.join(self.folder, "trains.out"), "w"),
            stderr=open(os.path.join(self.folder, "trains.err"), "w"))

    def status(self):
        try:
            with open(self.status_path) as fh:
                return json.load(fh)
        except (OSError, ValueError):
            return None

    def zone_file(self, tag, kind):
        """The zone's `kind` ("status" or "summary") JSON file, or None while it is not there yet."""
        try:
            with open(os.path.join(self.folder, f"{tag}-{kind}.json")) as fh:
                return json.load(fh)
        except (OSError, ValueError):
            return None

    def wait(self, predicate, timeout_s, what):
        deadline = time.monotonic() + timeout_s
        status = None
        while time.monotonic() < deadline:
            status = self.status()
            if status is not None and predicate(status):
                return status
            time.sleep(0.1)
        raise AssertionError(f"timed out after {timeout_s} s waiting for {what}; trains: {status}\n{self.logs()}")

    def logs(self):
        text = []
        for name in sorted(os.listdir(self.folder)):
            if name.endswith((".err", ".out")):
                with open(os.path.join(self.folder, name)) as fh:
                    text.append(f"--- {name}\n{fh.read()[-1500:]}")
        return "\n".join(text)

    def stop_zone(self, proc, tag):
        proc.send_signal(signal.SIGINT)
        assert proc.wait(15) == 0, self.logs()
        with open(os.path.join(self.folder, tag + "-summary.json")) as fh:
            return json.load(fh)

    def close(self):
        for proc, _tag in self.zones:
            if proc.poll() is None:
                proc.kill()
                proc.wait(5)
        if self.trains is not None and self.trains.poll() is None:
            self.trains.kill()
            self.trains.wait(5)


@pytest.fixture
def fleet(mosquitto, tmp_path):
    f = Fleet(mosquitto, str(tmp_path))
    yield f
    f.close()


def moving(status, v_mps=0.2):
    return any(t["v_mps"] > v_mps for t in status["trains"])


def within_authority(train):
    """The board's odometer never moved past the end of authority it held at the time (counted by the trains
    process at every loop, so an end of authority extended afterwards hides nothing); one set behind a standing
    train, when the controller corrects an estimate by a few mm, is no overrun unless the train then moves."""
    return train["moved_past_eoa_mm"] <= EOA_TOLERANCE_MM


def at_rest_within_authority(status):
    return all(t["v_mps"] == 0.0 and within_authority(t) for t in status["trains"])


def braked_after_expiry(status):
    """Every command expired: the OnboardUnit holds the train braked ('stop'), at rest within its authority."""
    return at_rest_within_authority(status) and all(t["mode"] == "stop" for t in status["trains"])


def watch_status(url):
    seen = {}
    bus = PahoBus(url, "watcher").start()
    bus.subscribe("cbtc/#", lambda topic, payload: seen.__setitem__(topic, payload) if topic.endswith("/status")
                  else None)
    return bus, seen


def test_paper_scenario_zone_and_trains_as_processes(fleet):
    """Station stops and start positions of the paper scenario over the broker; Ctrl-C stops the trains first."""
    zone = fleet.start_zone()
    fleet.start_trains(duration_s=24)

    def stopped_and_ran_on(status):
        zone_summary = fleet.zone_file("zone", "summary")
        return zone_summary is not None and all(t["distance_m"] > 2.5 for t in status["trains"]) \
            and all(row["station_stops"] >= 1 for row in zone_summary["trains"].values())

    fleet.wait(stopped_and_ran_on, 30, "a station stop and 2.5 m run by each train")
    summary = fleet.stop_zone(zone, "zone")          # Ctrl-C: stop commands, then offline
    fleet.wait(lambda s: all(t["v_mps"] == 0.0 for t in s["trains"]), 10, "the trains to stand")
    fleet.trains.send_signal(signal.SIGINT)
    assert fleet.trains.wait(20) == 0, fleet.logs()  # exit code 0: no collision
    with open(fleet.trains_summary) as fh:
        trains = json.load(fh)
    assert trains["collisions"] == 0
    for train in trains["trains"]:
        assert train["distance_m"] > 2.0                 # ran most of a side of the square and more
        assert train["commands_rejected_onboard"] == 0
        assert train["sid"] == summary["session_id"]
        assert train["v_mps"] == 0.0 and within_authority(train), train  # stopped at Ctrl-C
    for train_id, row in summary["trains"].items():
        assert row["station_stops"] >= 1, (train_id, row)
        assert row["reports_rejected"] == 0
    assert summary["invalid_reports"] == 0 and summary["unknown_reports"] == 0
    watcher, seen = watch_status(fleet.broker.url)
    try:
        deadline = time.monotonic() + 3
        while len(seen) < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        watcher.disconnect()
    assert seen == {"cbtc/zc/zc1/status": b"offline", "cbtc/train/A/status": b"offline",
                    "cbtc/train/B/status": b"offline"}


def test_forged_and_replayed_commands_and_bad_reports_are_ignored(fleet):
    zone = fleet.start_zone()
    fleet.start_trains(duration_s=30)
    attacker = PahoBus(fleet.broker.url, "attacker").start()
    commands, reports = [], []
    attacker.subscribe("cbtc/train/A/cmd", lambda t, p: commands.append(p))
    attacker.subscribe("cbtc/train/A/report", lambda t, p: reports.append(p))
    try:
        fleet.wait(lambda s: s["trains"][0]["cseq"] > 20, 20, "train A to take commands")
        replay = commands[0]
        body = json.loads(reports[-1][:reports[-1].rfind(b"#")])
        real = json.loads(commands[-1][:commands[-1].rfind(b"#")])
        before = fleet.status()["trains"][0]
        forged_eoa_mm = body["odo_mm"] + 100000
        attacker.publish("cbtc/train/A/cmd", wire_zc.encode_command(
            b"wrong key 16 byt", "A", body["boot"], real["seq"] + 1000, real["sid"], body["seq"], 600, forged_eoa_mm,
            800, 600, 800))
        attacker.publish("cbtc/train/A/cmd", replay)
        attacker.publish("cbtc/train/A/report", reports[-1][:-4] + b"0000")                  # MAC broken
        attacker.publish("cbtc/train/Z/report", wire.encode_report(
            b"0123456789abcdef", "Z", 1, 1, 1000, 0, 0, 0, "idle", -1, -1, None, [], []))             # unknown train
        after = fleet.wait(lambda s: s["trains"][0]["commands_rejected_onboard"] >= before[
            "commands_rejected_onboard"] + 2, 5, "two rejections on board")
        a = after["trains"][0]
        assert a["eoa_mm"] < forged_eoa_mm - 50000
        assert within_authority(a)
        assert a["sid"] == real["sid"]
        assert a["last_reject"].startswith(("replayed command", "stale command"))
        summary = fleet.stop_zone(zone, "zone")
    finally:
        attacker.disconnect()
    assert summary["unknown_reports"] >= 1 and summary["invalid_reports"] >= 1
    assert summary["trains"]["A"]["last_reject"] == "its reports fail authentication"
    with open(os.path.join(fleet.folder, "zone.err")) as fh:
        log = fh.read()
    assert "a board reports as train Z, which is not in this zone" in log and "train A: wrong key" in log


def test_broker_killed_trains_stop_within_authority_then_resume(fleet):
    fleet.start_zone()
    fleet.start_trains(duration_s=30)
    fleet.wait(moving, 15, "a train to move")
    fleet.broker.kill()
    killed_at = time.monotonic()
    rest = fleet.wait(braked_after_expiry, STOP_WAIT_S + 2,
                      "every train braked within its authority")
    assert time.monotonic() - killed_at < STOP_WAIT_S + 2
    # the zone hears nothing now: it marks its data stale and keeps the trains where they were last heard of
    first = fleet.zone_file("zone", "status")
    assert first is not None and not first["broker_connected"], first
    assert all(row["stale"] and row["data_age_s"] > 1.0 for row in first["trains"].values()), first
    time.sleep(1.0)
    later = fleet.zone_file("zone", "status")
    assert later["t_s"] > first["t_s"]
    for train_id, row in later["trains"].items():
        assert row["stale"] and row["data_age_s"] > first["trains"][train_id]["data_age_s"]
        assert row["s_m"] == first["trains"][train_id]["s_m"], (train_id, first, later)   # not extrapolated
    distance_m = {t["train"]: t["distance_m"] for t in rest["trains"]}
    time.sleep(1.0)
    still = fleet.status()
    assert all(t["distance_m"] == distance_m[t["train"]] for t in still["trains"])   # and they stay there
    fleet.broker.start()
    resumed = fleet.wait(lambda s: any(t["distance_m"] > distance_m[t["train"]] + 0.2 for t in s["trains"]), 12,
                         "a train to move again after the broker is back")
    assert resumed["collisions"] == 0


def test_zone_controller_killed_trains_stop_then_a_new_session_resumes(fleet):
    first = fleet.start_zone("zone1")
    fleet.start_trains(duration_s=30)
    running = fleet.wait(moving, 15, "a train to move")
    old_sid = running["trains"][0]["sid"]
    fleet.wait(lambda s: s["t_s"] >= running["t_s"] + 0.5, 5, "another status period")
    first.kill()                                   # no goodbye: the trains only see commands stop coming
    summary = fleet.zone_file("zone1", "summary")  # kept current while it ran: there after a kill
    assert summary is not None and summary["cycles"] > 0 and summary["session_id"] == old_sid, summary
    rest = fleet.wait(braked_after_expiry, STOP_WAIT_S + 2,
                      "every train braked within its authority")
    distance_m = {t["train"]: t["distance_m"] for t in rest["trains"]}
    fleet.start_zone("zone2")
    resumed = fleet.wait(lambda s: any(t["distance_m"] > distance_m[t["train"]] + 0.2 for t in s["trains"]), 15,
                         "a train to move under the new controller")
    assert all(t["sid"] != old_sid for t in resumed["trains"])
    fleet.wait(lambda s: s["t_s"] >= resumed["t_s"] + 2.0, 5, "two more seconds")
    assert fleet.status()["collisions"] == 0


def test_acl_only_the_controller_commands_a_train(secured_mosquitto):
    broker, creds = secured_mosquitto(["A", "B"])
    with pytest.raises(BusError, match="refused"):
        PahoBus(broker.url, "anonymous").start(timeout_s=3)
    with pytest.raises(BusError, match="refused"):
        PahoBus(broker.url, "liar", username="train-A", password="guess").start(timeout_s=3)
    zc = PahoBus(broker.url, "zc", username="zc", password=creds["zc"]).start()
    a = PahoBus(broker.url, "train-A", username="train-A", password=creds["train-A"]).start()
    b = PahoBus(broker.url, "train-B", username="train-B", password=creds["train-B"]).start()
    try:
        to_a, b_reads, zc_reports = [], [], []
        a.subscribe("cbtc/train/A/cmd", lambda t, p: to_a.append(p))
        b.subscribe("cbtc/train/A/cmd", lambda t, p: b_reads.append(p))         # not allowed to read it
        zc.subscribe("cbtc/train/+/report", lambda t, p: zc_reports.append((t, p)))
        time.sleep(0.3)
        b.publish("cbtc/train/A/cmd", b"from B")                                # not allowed to write it
        b.publish("cbtc/train/A/report", b"B speaking for A")                   # nor this
        zc.publish("cbtc/train/A/cmd", b"from zc")
        a.publish("cbtc/train/A/report", b"A itself")
        deadline = time.monotonic() + 3
        while (not to_a or not zc_reports) and time.monotonic() < deadline:
            time.sleep(0.02)
        time.sleep(0.3)
        assert to_a == [b"from zc"]
        assert b_reads == []
        assert zc_reports == [("cbtc/train/A/report", b"A itself")]
        # nothing can be left on a command topic by a train, and nothing over the protocol's size reaches a board
        b.publish("cbtc/train/A/cmd", b"stored by B", retain=True)
        zc.publish("cbtc/train/A/cmd", b"x" * 65536)
        time.sleep(0.3)
        stored = []
        a.subscribe("cbtc/train/A/cmd", lambda t, p: stored.append(p))   # retained messages come with a subscribe
        time.sleep(0.5)
        assert stored == [] and to_a == [b"from zc"]
    finally:
        for bus in (zc, a, b):
            bus.disconnect()


def test_a_train_reusing_the_controllers_client_id_takes_over_nothing(secured_mosquitto):
    """Client ids are bound to users: train A's credentials with the controller's client id (or train B's) connect
    as train A and disconnect neither the controller nor B, which keep hearing each other."""
    broker, creds = secured_mosquitto(["A", "B"])
    zc = PahoBus(broker.url, "zc-zc1", username="zc", password=creds["zc"]).start()
    b = PahoBus(broker.url, "train-B", username="train-B", password=creds["train-B"]).start()
    intruders = []
    try:
        heard = []
        zc.subscribe("cbtc/train/+/report", lambda t, p: heard.append(t))
        time.sleep(0.3)
        for victim in ("zc-zc1", "train-B"):
            intruders.append(PahoBus(broker.url, victim, username="train-A", password=creds["train-A"]).start())
        time.sleep(1.0)
        assert zc.losses == 0 and b.losses == 0 and zc.connects == 1 and b.connects == 1
        b.publish("cbtc/train/B/report", b"still here")
        deadline = time.monotonic() + 3
        while not heard and time.monotonic() < deadline:
            time.sleep(0.02)
        assert heard == ["cbtc/train/B/report"]
    finally:
        for bus in [zc, b] + intruders:
            bus.disconnect()


def test_bench_latency_answers_every_report_within_a_cycle(mosquitto):
    out = subprocess.run(cbtc("bench", "latency", "--broker", mosquitto.url, "--trains", "3", "--train-procs", "1",
                              "--warmup", "1.5", "--duration", "2", "--json"),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    figures = json.loads(out.stdout)
    assert figures["reports_published"] >= 3 * 10 * 2 - 3            # 3 trains at 10 Hz for 2 s
    assert figures["reports_received"] == figures["reports_published"]  # loopback, QoS 0: nothing lost
    assert figures["reports_answered"] >= figures["reports_published"] - 3
    assert figures["answer_wait_ms"]["max"] <= 100.0 + 20.0               # answered at once, at worst by the next cycle
    assert 0.0 < figures["transport_rtt_ms"]["p50"] < 20.0                # loopback with TCP_NODELAY: milliseconds


def test_zone_and_trains_run_a_scenario_file(mosquitto, tmp_path):
    """Both sides of a live run read the same scenario file: its ids, starts, stops and profiles."""
    scenario = tmp_path / "pair.yaml"
    scenario.write_text("layout: lego_oval\ntrains:\n  - {id: P1, start: south, profile: {length_m: 0.25}}\n"
                        "  - {id: F1, start: 2.5, stops: [north], dwell_s: 1}\n"
                        "faults:\n  - {name: stop_dead, train: F1, at_s: 100}\n")
    summary = str(tmp_path / "trains.json")
    zone = subprocess.Popen(cbtc("zone", "--broker", mosquitto.url, "--scenario", str(scenario), "--duration", "9",
                                 "--clear-track", "all",
                                 "--quiet", "--summary-json", str(tmp_path / "zone.json"), "--record",
                                 str(tmp_path / "run.jsonl")),
                            stdout=subprocess.DEVNULL, stderr=open(tmp_path / "zone.err", "w"))
    trains = subprocess.run(cbtc("trains", "--broker", mosquitto.url, "--scenario", str(scenario), "--duration",
                                 "7", "--quiet", "--summary-json", summary), capture_output=True, text=True,
                            timeout=60)
    assert zone.wait(30) == 0, (tmp_path / "zone.err").read_text()
    assert trains.returncode == 0, trains.stderr
    assert "the faults of scenario pair are for cbtc sim" in trains.stderr
    with open(summary) as fh:
        truth = json.load(fh)
    assert truth["collisions"] == 0 and {t["train"] for t in truth["trains"]} == {"P1", "F1"}
    assert all(t["distance_m"] > 0.5 and within_authority(t) for t in truth["trains"]), truth
    with open(tmp_path / "zone.json") as fh:
        assert json.load(fh)["trains"]["F1"]["station_stops"] >= 1
    with open(tmp_path / "run.jsonl") as fh:   # every accepted report, as cbtc calibrate reads them
        recorded = [json.loads(line) for line in fh]
    assert {r["id"] for r in recorded} == {"P1", "F1"} and all("odo_mm" in r for r in recorded)


def test_a_key_mismatch_is_said_once_per_train_per_10_s_with_the_key_file_and_the_fix(mosquitto, tmp_path):
    """The zone holds keys from a file, the boards derive theirs from --sim-seed (boards: they do not read the zone's
    info, as `cbtc trains` does, tests/test_zone_match.py): every report fails authentication, about a hundred a
    train in 5 s. The zone says so once per train, naming the keys file and the fix (the 10 s between lines and their
    counts: test_zone_flood.py); nothing else is logged until its end, one line naming the mismatch, exit 1."""
    import paho.mqtt.client as mqtt

    from cbtc.live.keys import train_keys

    keys = str(tmp_path / "keys.json")
    assert subprocess.run(cbtc("keys", "new", "--train-ids", "A,B", "--out", keys), capture_output=True).returncode == 0
    zone = subprocess.Popen(cbtc("zone", "--broker", mosquitto.url, "--layout", LAYOUT, "--train-ids", "A,B",
                                 "--clear-track", "all", "--keys", keys, "--duration", "6", "--quiet"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert zone.stdout.readline().startswith("zone zc1:")
    board_keys = train_keys(["A", "B"], None, 0)
    boards = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="boards")
    boards.connect("127.0.0.1", mosquitto.port)
    boards.loop_start()
    for seq in range(1, 101):
        for train in ("A", "B"):
            boards.publish(wire.topic_report(train), wire.encode_report(board_keys[train], train, 9, seq, 50 * seq, 0,
                                                                        0, 0, "idle", -1, -1, None, [], []))
        time.sleep(0.05)
    boards.loop_stop()
    boards.disconnect()
    zone_err = zone.communicate(timeout=40)[1]
    for train in ("A", "B"):
        (said,) = [line for line in zone_err.splitlines() if f"train {train}: wrong key" in line]
        assert f"keys file {keys}" in said and "cbtc flash --keys FILE" in said and len(said) - len(keys) < 220, said
    assert len(zone_err.splitlines()) == 3 and "never with a report this zone could authenticate" in zone_err
    assert zone.returncode == 1
