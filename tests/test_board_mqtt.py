"""The firmware booted under the MicroPython unix port talks to a real Mosquitto: it reports, obeys, brakes.

The board is `micropython` running firmware/main.py (precompiled, as `cbtc flash` deploys it) with the host shims:
Wi-Fi joins at once, the UART holds what the IPS sent (garbage, a corrupted frame, a good fix), no RFID reader is
on the SPI bus. A paho client plays the zone controller: it decodes reports with wire_zc.decode_report and sends sealed
commands with wire_zc.encode_command. Then the broker is killed and restarted: the board keeps looping, brakes when its
command expires, reconnects with backoff and reports again; when the board dies, its last will says `offline`.
"""

import os
import re
import shutil
import socket
import subprocess
import sys
import threading
import time

import paho.mqtt.client as mqtt

from cbtc.protocol import wire, wire_zc
from mpy_harness import (
    MPY_TESTS_DIR,
    SHIMS_DIR,
    micropython_argv,
    micropython_env,
    requires_micropython,
    requires_umqtt,
)

for _folder in (SHIMS_DIR, MPY_TESTS_DIR):
    if _folder not in sys.path:
        sys.path.insert(0, _folder)

from check_ips import position  # noqa: E402  (frame builder with an independent CRC)

pytestmark = [requires_micropython, requires_umqtt]

KEY = b"0123456789abcdef"
TRAIN = "A"
# The smallest heap in which the whole firmware reliably boots and runs these broker scenarios on the 64-bit unix port:
# its live heap peaks at 51.6 KB with the broker restart; at 56K fragmentation fails a command's decoding (it did once
# the board checked its encoder and read MQTT itself: 1.8 KB more on the 32-bit build). An ESP8266 has about 36 KB free,
# but its objects, pointers and GC blocks are half this port's size, and machine, network (the shims here) and
# umqtt.simple are built into its firmware, so their code and names (about 6 KB here) cost it no heap. The board's
# own figures: tests/test_heap32.py; where the bytes go: docs/hardware.md.
BOOT_HEAP = "64K"
BOOT_HEAP_BYTES = 64 * 1024
# The host shims' encoder never counts: without these the board would find it failed (no count in 60 mm of driving,
# or a drive at its ceiling with the train standing) and trip, as it must on a track (tests/test_encoder_failure.py).
NO_ENCODER = {"enc_slack_mm": 10 ** 6, "drive_margin_pct": 1000}
STATS_RE = (r"stats: up_ms (\d+) heap_peak (\d+) heap_live (\d+) heap_free (\d+) link (\w+) losses (\d+) mode (\w+) "
            r"errors (\d+)")


def free_port():
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_port(port, timeout_s=5.0):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.2).close()
            return
        except OSError:
            time.sleep(0.05)
    raise AssertionError("mosquitto did not listen on port %d" % port)


class Mosquitto:
    """A private Mosquitto on a loopback port, restartable on the same port."""

    def __init__(self, folder, port):
        self.port = port
        self.conf = os.path.join(folder, "mosquitto.conf")
        with open(self.conf, "w") as fh:
            fh.write("listener %d 127.0.0.1\nallow_anonymous true\nset_tcp_nodelay true\nlog_dest stderr\n"
                     "persistence false\n" % port)
        self.proc = None

    def start(self):
        exe = "/usr/sbin/mosquitto" if os.path.exists("/usr/sbin/mosquitto") else "mosquitto"
        self.proc = subprocess.Popen([exe, "-c", self.conf], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        wait_port(self.port)

    def stop(self):
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(5)
            self.proc = None


class Controller:
    """A paho client standing in for the zone controller: decoded reports, retained status, sealed commands."""

    def __init__(self, port, login=None):
        self.reports = []
        self.status = []
        self.rejected = []
        self.cmd_seq = 0
        self.lock = threading.Lock()
        self.client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="test-zc")
        self.client.on_message = self._on_message
        self.client.on_connect = lambda c, u, f, rc, p: c.subscribe("cbtc/train/%s/#" % TRAIN)
        self.client.reconnect_delay_set(0.2, 0.5)
        if login is not None:   # (user, password) on a broker that refuses anonymous clients
            self.client.username_pw_set(*login)
        self.client.connect("127.0.0.1", port)
        self.client.loop_start()

    def _on_message(self, _client, _userdata, msg):
        with self.lock:
            if msg.topic.endswith("/report"):
                try:
                    self.reports.append(wire_zc.decode_report(KEY, msg.topic, msg.payload))
                except wire.WireError as exc:
                    self.rejected.append(exc.reason)
            elif msg.topic.endswith("/status"):
                self.status.append(msg.payload)

    def last(self):
        with self.lock:
            return self.reports[-1] if self.reports else None

    def wait(self, predicate, timeout_s, what):
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            report = self.last()
            if report is not None and predicate(report):
                return report
            time.sleep(0.02)
        raise AssertionError("timed out waiting for %s; last report %r" % (what, self.last()))

    def command(self, v_mmps=400, eoa_mm=10000, ttl_ms=800):
        report = self.last()
        self.cmd_seq += 1
        payload = wire_zc.encode_command(KEY, TRAIN, report["boot"], self.cmd_seq, 7, report["seq"], v_mmps, eoa_mm,
                                      ttl_ms, 600, 800)
        self.client.publish(wire.topic_command(TRAIN), payload)

    def close(self):
        self.client.loop_stop()
        self.client.disconnect()


def start_board(tree, cfg_dir, port, uart_bytes, run_ms=0):
    """The board: a copy of the compiled tree with this test's train_config.py is its filesystem; it runs in it, as a
    board runs in its filesystem's root (modules load by their short names, wire.mpy), with nothing else on its path
    but the port's frozen modules."""
    board_dir = os.path.join(cfg_dir, "board")
    shutil.copytree(tree, board_dir)
    with open(os.path.join(board_dir, "train_config.py"), "w") as fh:
        fh.write("CONFIG = %r\n" % {
            "train_id": TRAIN, "key_hex": KEY.hex(), "wifi_ssid": "lab", "wifi_password": "pw",
            "broker_host": "127.0.0.1", "broker_port": port, "keepalive_s": 5, "stats_ms": 250,
            "repl_grace_ms": 0, "backoff_min_ms": 200, "backoff_max_ms": 1000, "run_ms": run_ms,
            "obu": NO_ENCODER})
    script = ("import binascii, machine\nmachine.UART_RX[0] = binascii.unhexlify(%r)\nimport main\n"
              % uart_bytes.hex())
    return subprocess.Popen(micropython_argv(BOOT_HEAP) + ["-c", script], env=dict(os.environ, MICROPYPATH=".frozen"),
                            cwd=board_dir, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_board_boots_reports_obeys_brakes_and_survives_a_lost_broker(mpy_tree, tmp_path):
    broker = Mosquitto(str(tmp_path), free_port())
    broker.start()
    zc = Controller(broker.port)
    corrupted = bytearray(position(111, 222, 0))
    corrupted[12] ^= 0x01
    uart = bytes([0x00, 0x47, 0xFF, 0x13]) + bytes(corrupted) + position(1234, -567, 89)
    board = start_board(mpy_tree, str(tmp_path), broker.port, uart)
    try:
        first = zc.wait(lambda r: True, 10, "the first report")
        assert first["mode"] == "idle" and first["duty"] == 0 and first["cseq"] == -1
        assert zc.status and zc.status[-1] == b"online"
        seen = zc.wait(lambda r: r["ips"] is not None or r["seq"] > 5, 3, "the IPS fix")
        reports = list(zc.reports)
        fixes = [r["ips"] for r in reports if r["ips"] is not None]
        assert fixes and fixes[0][1:] == [1234, -567], fixes
        assert "ips_crc" in seen["flt"] and "rfid_absent" in seen["flt"]
        assert not zc.rejected

        # obey: commands at 10 Hz -> run with a positive duty (the shim encoder never moves: the PI winds up)
        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline:
            zc.command(ttl_ms=800)
            time.sleep(0.1)
        running = zc.wait(lambda r: r["mode"] == "run" and r["duty"] > 0, 1, "run with duty")
        assert running["cseq"] >= 1
        # a command sealed with another key: refused, and said on the console with the stats, once
        zc.client.publish("cbtc/train/%s/cmd" % TRAIN, wire_zc.encode_command(
            b"wrong key 16 byt", TRAIN, running["boot"], zc.cmd_seq + 1, 7, running["seq"], 400, 10000, 800, 600, 800))

        # silence: the command expires and the train brakes to a stop
        stopped = zc.wait(lambda r: r["mode"] == "stop" and r["duty"] == 0, 3, "stop after expiry")
        assert "cmd_timeout" in stopped["flt"]

        # run again with a long command, then lose the broker while running
        deadline = time.monotonic() + 0.6
        while time.monotonic() < deadline:
            zc.command(ttl_ms=2500)
            time.sleep(0.1)
        zc.wait(lambda r: r["mode"] == "run" and r["duty"] > 0, 1, "run before the broker dies")
        broker.stop()
        time.sleep(3.5)                       # longer than the command's validity: the board must have braked
        count_before = len(zc.reports)
        broker.start()
        back = zc.wait(lambda r: len(zc.reports) > count_before + 3, 10, "reports after the broker came back")
        assert back["mode"] == "stop" and back["duty"] == 0 and "broker_lost" not in back["flt"]
        assert zc.status[-1] == b"online"
    finally:
        board.kill()
        out = board.communicate(timeout=10)[0]
        print(out[-2000:])   # the board's console, shown with a failure
        zc_status = list(zc.status)
        time.sleep(0.3)
        zc.close()
        broker.stop()
    stats = re.findall(STATS_RE, out)
    assert stats, out
    assert "lego-cbtc train A boot" in out
    assert any(s[4] == "down" and s[6] == "stop" for s in stats), "the board braked while the broker was gone"
    assert int(stats[-1][5]) >= 1                      # the loss was counted, the loop went on
    assert all(s[7] == "0" for s in stats), "no exception reached the loop"
    refused = re.findall(r"refused: (\d+) commands since the last stats; the newest: (.*)", out)
    assert refused and refused[0][1].startswith("payload on cbtc/train/A/cmd fails authentication"), out
    live = max(int(s[2]) for s in stats)
    print("firmware on the 64-bit unix port: peak live heap %d bytes (heap %s)" % (live, BOOT_HEAP))
    assert 0 < live < BOOT_HEAP_BYTES
    assert zc_status[0] == b"online"


def test_whole_firmware_runs_in_its_heap_and_reports_the_peak(mpy_tree, tmp_path):
    """Boot, connect, report and obey commands for 3 s of board time in BOOT_HEAP, then stop and print the heap
    figures: every module the board loads is loaded (the shims and umqtt too), nothing is skipped."""
    broker = Mosquitto(str(tmp_path), free_port())
    broker.start()
    zc = Controller(broker.port)
    board = start_board(mpy_tree, str(tmp_path), broker.port, position(10, 20, 0), run_ms=3000)
    try:
        zc.wait(lambda r: True, 10, "the first report")
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            zc.command(ttl_ms=800)
            time.sleep(0.1)
        zc.wait(lambda r: r["mode"] == "run", 1, "run")
        out = board.communicate(timeout=15)[0]
    finally:
        board.kill()
        zc.close()
        broker.stop()
    assert board.returncode == 0, out
    stopped = re.search(r"stopped: heap_peak (\d+) heap_live (\d+)", out)
    assert stopped, out
    peak, live = int(stopped.group(1)), int(stopped.group(2))
    print("whole firmware under micropython -X heapsize=%s: peak live heap %d bytes, peak before collection %d"
          % (BOOT_HEAP, live, peak))
    assert all(s[7] == "0" for s in re.findall(STATS_RE, out)), "no exception reached the loop:\n" + "\n".join(
        line for line in out.splitlines() if line.startswith("loop:"))
    assert 0 < live <= peak <= BOOT_HEAP_BYTES


def test_oversized_and_retained_messages_neither_block_the_loop_nor_stop_commands(mpy_tree, tmp_path):
    """A stranger's 64 KiB on the train's command topic, retained before the board boots and again live while it runs
    (anyone may publish on this anonymous broker): the board takes commands at once after booting; the live one does
    not stall its loop (reports keep coming), the motor brakes within one command timeout once the commands stop, and
    commands are taken again after it. The console counts both messages as dropped."""
    broker = Mosquitto(str(tmp_path), free_port())
    broker.start()
    zc = Controller(broker.port)
    stranger = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id="stranger")
    stranger.connect("127.0.0.1", broker.port)
    stranger.loop_start()
    junk = b"x" * 65536
    stranger.publish(wire.topic_command(TRAIN), junk, retain=True).wait_for_publish(5)
    board = start_board(mpy_tree, str(tmp_path), broker.port, position(10, 20, 0))
    ttl_ms = 800
    try:
        zc.wait(lambda r: True, 10, "the first report")
        deadline = time.monotonic() + 2.0
        while time.monotonic() < deadline and (zc.last()["mode"] != "run" or zc.last()["duty"] == 0):
            zc.command(ttl_ms=ttl_ms)
            time.sleep(0.1)
        zc.wait(lambda r: r["mode"] == "run" and r["duty"] > 0, 0.5, "run despite the retained message")

        count_before = len(zc.reports)
        stranger.publish(wire.topic_command(TRAIN), junk).wait_for_publish(5)
        sent_s = time.monotonic()   # the controller falls silent with the stranger's message
        braked = zc.wait(lambda r: r["mode"] == "stop" and r["duty"] == 0, ttl_ms / 1000 + 0.5, "brake after expiry")
        assert time.monotonic() - sent_s < ttl_ms / 1000 + 0.5
        assert "cmd_timeout" in braked["flt"]
        with zc.lock:
            recent = zc.reports[count_before:]
        gaps_ms = [wire.wrap_diff(b["t_ms"], a["t_ms"]) for a, b in zip(recent, recent[1:])]
        assert gaps_ms and max(gaps_ms) < 250, gaps_ms   # the loop went on reporting every 50 ms

        deadline = time.monotonic() + 1.5
        while time.monotonic() < deadline and (zc.last()["mode"] != "run" or zc.last()["duty"] == 0):
            zc.command(ttl_ms=ttl_ms)
            time.sleep(0.1)
        zc.wait(lambda r: r["mode"] == "run" and r["duty"] > 0, 0.5, "commands taken again")
        time.sleep(0.3)
    finally:
        board.kill()
        out = board.communicate(timeout=10)[0]
        print(out[-2000:])
        stranger.loop_stop()
        zc.close()
        broker.stop()
    dropped = re.findall(r"dropped (\d+) (\d+) (\d+)", out)
    assert dropped and dropped[-1] == ("2", "0", "0"), out   # both dropped unread for their size (retained or not)
    assert all(s[7] == "0" for s in re.findall(STATS_RE, out)), "no exception reached the loop"
    assert "mqtt: " not in out.split("connected", 1)[-1], "the link was never lost"


WATCHDOG_SCRIPT = """
import machine, train
class Clock:
    ms = 0
    def now(self):
        return self.ms
class Motor:
    mode = "brake"
    def brake(self):
        self.mode = "brake"
class Net:
    connected = True
    losses = oversized = retained = failed = 0
    def poll(self, now_ms):
        pass
class Wdt:
    feeds = 0
    def feed(self):
        self.feeds += 1
clock = Clock()
wdt = Wdt()
fed = []   # watchdog feeds counted before each pass's step
class Unit:
    motor = Motor()
    mode = "idle"
    sensor_errors = 0
    rejected = 0
    link_ok = True
    steps = 0
    def step(self, now_ms):
        self.steps += 1
        fed.append(wdt.feeds)
        clock.ms += 10                       # a pass takes 10 ms
        if self.steps == 41:
            clock.ms += 1000                 # one blocked step: 1 s
        if 21 <= self.steps <= 40:
            raise OSError("storm")
cfg = {"max_pass_ms": 500, "repl_grace_ms": 0, "stats_ms": 100000, "run_ms": 2000, "loop_ms": 0,
       "broker_host": "", "broker_port": 0}
train.run(cfg, clock.now, Unit(), Net(), machine.Pin(0, machine.Pin.IN, machine.Pin.PULL_UP), wdt)
print("FED", fed[20], fed[40], fed[41], fed[42], fed[43], len(fed), wdt.feeds)
"""


def test_watchdog_is_fed_only_while_the_loop_is_healthy(mpy_tree):
    """A counting watchdog: one feed per healthy pass; none during an exception storm; none for the pass that
    follows a blocked step (it comes more than max_pass_ms after the previous one); feeding resumes after."""
    proc = subprocess.run(micropython_argv(BOOT_HEAP) + ["-c", WATCHDOG_SCRIPT], env=micropython_env(mpy_tree),
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    fed = [int(x) for x in re.search(r"FED ([\d ]+)", proc.stdout).group(1).split()]
    after_healthy, after_storm, after_block, one_late, recovered, passes, total = fed
    assert after_healthy == 20                      # passes 1-20: all fed
    assert after_storm == 20                        # passes 21-40 raised: none fed
    assert after_block == 21                        # pass 41 started on time; its step blocked for 1 s
    assert one_late == 21                           # pass 42 came 1010 ms after pass 41: not fed
    assert recovered == 22                          # pass 43 on time again: fed
    assert total == passes - 20 - 1                 # every pass fed but the storm's 20 and the late one
