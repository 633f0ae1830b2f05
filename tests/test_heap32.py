"""The whole firmware in a 32-bit MicroPython (the WebAssembly port, whose objects are the ESP8266's size): boot,
connect, report and obey commands, and the heap it needs, against the ESP8266's ~36 KB.

The unix port's objects and pointers are twice the size of a board's, so its heap figures (tests/test_board_mqtt.py)
overstate a board; this run measures the board's own figure. The port has no sockets, so tests/wasm/usocket.py plays
the broker in memory (it answers CONNECT and SUBSCRIBE and replies to each report with a command sealed here by the
zone controller's encoder); it and umqtt.simple (frozen into a board's ROM) are loaded before the baseline, so they
are not counted, while the MQTT client object and its buffers are. The port frees garbage only between calls from
JavaScript, so tests/wasm/heap32.mjs runs the boot halves and each pass of the loop as separate calls
(tests/wasm/heap_probe.py does what train.main and train.run do), collecting in between; and since nothing is freed
inside a call, the heap in use at the end of one is everything that phase allocated: each must stay under 36 KB.
"""

import json
import os
import shutil
import subprocess
import sys

import pytest

from cbtc.board.mpy_build import build
from cbtc.protocol import wire, wire_zc
from mpy_harness import MPY_TESTS_DIR, REPO, SHIMS_DIR, VENDOR_DIR, _compile

BOOT_ID = 4242   # tests/wasm/heap_probe.py gives the board this boot id, so the prepared commands name it

WASM_DIR = os.path.join(REPO, "tests", "wasm")
MICROPYTHON_MJS = os.path.join(VENDOR_DIR, "wasm", "node_modules", "@micropython", "micropython-webassembly-pyscript",
                               "micropython.mjs")
NODE = shutil.which("node")
ESP8266_FREE_HEAP_B = 36 * 1024
KEY = b"0123456789abcdef"

pytestmark = pytest.mark.skipif(
    NODE is None or not os.path.exists(MICROPYTHON_MJS) or not os.path.exists(os.path.join(VENDOR_DIR, "umqtt")),
    reason="needs node, the MicroPython WebAssembly port (npm install --prefix vendor/wasm "
           "@micropython/micropython-webassembly-pyscript) and umqtt (python tools/fetch_umqtt.py)")

for _folder in (SHIMS_DIR, MPY_TESTS_DIR):
    if _folder not in sys.path:
        sys.path.insert(0, _folder)


def _publish_packet(topic, payload):
    body = len(topic).to_bytes(2, "big") + topic.encode() + payload
    n, length = len(body), bytearray()
    while True:
        byte, n = n & 0x7F, n >> 7
        length.append(byte | (0x80 if n else 0))
        if not n:
            break
    return b"\x30" + bytes(length) + body


def test_whole_firmware_fits_an_esp8266_heap_in_32_bit_micropython(tmp_path):
    from check_ips import position

    tree = tmp_path / "fw"
    build(str(tree))
    for folder, names in ((SHIMS_DIR, ("machine.py", "network.py")), (WASM_DIR, ("usocket.py", "heap_probe.py"))):
        for name in names:
            _compile(os.path.join(folder, name), str(tree), name[:-3] + ".mpy", ["-O3"])
    _compile(os.path.join(VENDOR_DIR, "umqtt", "simple.py"), str(tree), "umqtt/simple.mpy", ["-O3"])
    (tree / "train_config.py").write_text("CONFIG = %r\n" % {
        "train_id": "A", "key_hex": KEY.hex(), "wifi_ssid": "lab", "wifi_password": "pw", "broker_host": "zc",
        "broker_port": 1883, "keepalive_s": 30, "repl_grace_ms": 0})
    cmds = tmp_path / "cmds"
    cmds.mkdir()
    for seq in range(200):
        payload = wire_zc.encode_command(KEY, "A", BOOT_ID, seq + 1, 7, seq, 300, 10000, 800, 600, 800)
        (cmds / str(seq)).write_bytes(_publish_packet(wire.topic_command("A"), payload))
    proc = subprocess.run([NODE, os.path.join(WASM_DIR, "heap32.mjs"), MICROPYTHON_MJS, str(tree), str(cmds), "600",
                           position(100, 200, 0).hex()], capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    print(proc.stdout)
    figures = json.loads(proc.stdout.strip().splitlines()[-1])
    assert "lego-cbtc train A boot" in proc.stdout
    # it ran as a board does: reported at 20 Hz, took the commands, drove
    assert figures["reports_sent"] >= 110 and figures["reports_seen"] == figures["reports_sent"]
    assert figures["last_command_taken"] >= 100 and figures["commands_rejected"] == 0
    assert figures["mode"] == "run"
    print("32-bit heap: boot peak %(boot_peak_b)d B (%(after_boot_b)d B kept), assembly peak %(assemble_peak_b)d B "
          "(%(after_assemble_b)d B kept), loop: live peak %(loop_live_peak_b)d B, peak before collection "
          "%(loop_peak_before_collection_b)d B" % figures)
    # the port does not collect inside a call, so each peak counts every byte allocated in that phase or pass
    for phase in ("boot_peak_b", "assemble_peak_b", "loop_peak_before_collection_b"):
        assert figures[phase] < ESP8266_FREE_HEAP_B, phase
