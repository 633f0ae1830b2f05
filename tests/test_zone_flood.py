"""A flood of bad payloads on one train's report topic, over a real Mosquitto, against a zone controller in this
process: counted, logged a few times at most, never echoed at length, memory flat; the zone still answers the train."""

import gc
import logging
import os
import subprocess
import sys
import time

from cbtc.bus.paho_bus import PahoBus
from cbtc.layout_files import load_layout
from cbtc.protocol import wire
from cbtc.zone.config import paper_scenario
from cbtc.zone.factory import build_zone


def rss_bytes():
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


class Lines(logging.Handler):
    def __init__(self):
        super().__init__()
        self.lines = []

    def emit(self, record):
        self.lines.append(self.format(record))


# The stranger runs in a process of its own, so this process's memory is the zone's alone
STRANGER = """
import random, sys
import paho.mqtt.client as mqtt
rng = random.Random(3)
kinds = [lambda: bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 900))),
         lambda: b'{"v":1,"k":"rep","id":"A","mode":"' + b"x" * 600 + b'"}#' + b"0" * 32,
         lambda: b"\\xff" * 1024, lambda: b"", lambda: ("{" * 500).encode()]
client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="stranger")
client.connect("127.0.0.1", int(sys.argv[1]))
client.loop_start()
for i in range(2000):
    info = client.publish("cbtc/train/A/report", rng.choice(kinds)())
    if i % 10 == 0:   # and some for trains the zone does not know, each under another id
        info = client.publish("cbtc/train/X%d/report" % i, rng.choice(kinds)())
info.wait_for_publish(10)
client.loop_stop()
client.disconnect()
"""


def test_a_flood_of_bad_reports_is_counted_quietly_with_flat_memory(mosquitto):
    config = paper_scenario(load_layout("itb_square"), seed=0)
    keys = {spec.train_id: bytes([65 + i]) * 16 for i, spec in enumerate(config.trains)}
    zone_bus = PahoBus(mosquitto.url, "zc-zc1").start()
    zc = build_zone(config, keys, zone_bus, time.monotonic)
    lines = Lines()
    logging.getLogger("cbtc.zone").addHandler(lines)
    try:
        zc.start()
        zone_bus.publish(wire.topic_report("A"), b"warm-up")   # the zone's first refusal, before the measure
        time.sleep(0.3)
        gc.collect()
        before = rss_bytes()
        subprocess.run([sys.executable, "-c", STRANGER, str(mosquitto.port)], check=True, timeout=60)
        deadline = time.monotonic() + 10
        while zc.state_of("A").reports_rejected < 2001 and time.monotonic() < deadline:
            time.sleep(0.05)
        time.sleep(0.3)
        gc.collect()
        grown = rss_bytes() - before
    finally:
        logging.getLogger("cbtc.zone").removeHandler(lines)
        zone_bus.disconnect()
    assert zc.state_of("A").reports_rejected == 2001 and zc.unknown_reports == 200
    assert zc.refusals.total("A") == 2001
    print("%d log lines, longest %d characters, resident memory %+.2f MB" % (
        len(lines.lines), max(map(len, lines.lines)), grown / 1e6))
    assert len(lines.lines) <= 20, lines.lines
    assert all(len(line) <= 200 for line in lines.lines), lines.lines
    assert grown < 2 * 1024 * 1024


class Quiet:
    """A bus client that takes every command and delivers nothing."""

    def subscribe(self, topic_filter, callback):
        pass

    def unsubscribe(self, topic_filter):
        pass

    def publish(self, topic, payload, retain=False):
        pass


def test_a_board_with_another_key_is_said_once_per_10_s_with_the_count_the_key_source_and_the_fix():
    """Reports sealed with a key the zone does not hold, at 20 Hz for 25 s of zone time: three lines for the train
    (at 0, 10 and 20 s), each with the count since the one before, where the zone's key is from, and what to do."""
    config = paper_scenario(load_layout("itb_square"), seed=0, laps=None, duration_s=30.0)
    keys = {spec.train_id: bytes(16) for spec in config.trains}
    now = [0.0]
    zc = build_zone(config, keys, Quiet(), lambda: now[0])
    zc.clear_track(None, by="the test")   # only what the reports bring is logged
    zc.key_source = "keys file keys.json"
    lines = Lines()
    logger = logging.getLogger("cbtc.zone")
    logger.addHandler(lines)
    try:
        zc.start()
        for i in range(500):
            now[0] = i * 0.05
            zc.on_report(wire.topic_report("A"), wire.encode_report(b"another key 16 b", "A", 1, i, i * 50, 0, 0, 0,
                                                                    "idle", -1, -1, None, [], []))
    finally:
        logger.removeHandler(lines)
    said = [line for line in lines.lines if line.startswith("train A: wrong key")]
    assert len(said) == 3 and len(lines.lines) == 3, lines.lines
    assert "(x200 since this line last)" in said[1] and "(x200 since this line last)" in said[2]
    assert all("keys file keys.json" in line and "cbtc flash --keys FILE" in line for line in said)
    assert zc.state_of("A").reports_rejected == 500 and zc.refusals.total("A") == 500


def test_a_board_of_another_protocol_version_is_told_to_be_flashed_with_this_ones_firmware():
    """An authenticated report that names another protocol version (a board flashed before an upgrade): refused, and
    the line says what to do."""
    import json

    config = paper_scenario(load_layout("itb_square"), seed=0, laps=None, duration_s=30.0)
    keys = {spec.train_id: bytes(16) for spec in config.trains}
    zc = build_zone(config, keys, Quiet(), lambda: 0.0)
    zc.clear_track(None, by="the test")   # only what the reports bring is logged
    lines = Lines()
    logger = logging.getLogger("cbtc.zone")
    logger.addHandler(lines)
    try:
        zc.start()
        payload = wire.encode_report(bytes(16), "A", 1, 1, 50, 0, 0, 0, "idle", -1, -1, None, [], [])
        body = json.loads(payload[:payload.rindex(b"#")])
        body["v"] = wire.VERSION - 1
        zc.on_report(wire.topic_report("A"), wire.seal(bytes(16), wire.topic_report("A"), json.dumps(body).encode()))
    finally:
        logger.removeHandler(lines)
    assert len(lines.lines) == 1 and lines.lines[0].startswith("train A: other version"), lines.lines
    assert f"names version {wire.VERSION - 1}" in lines.lines[0] and "cbtc flash" in lines.lines[0]
    assert zc.state_of("A").reports_rejected == 1
