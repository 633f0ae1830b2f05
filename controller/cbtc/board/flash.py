"""Deploy the firmware to a train board over its USB serial port with mpremote, and verify it.

Steps: compile the firmware to .mpy (cbtc.board.mpy_build), write a train_config.py for this train, copy everything with
one `mpremote connect PORT exec ... + fs cp ...` chain, check the sha256 of every file on the board against the local
copy (`mpremote exec`), then soft-reset the board over the serial line and wait for its boot message
"lego-cbtc train <id> boot <version>". Any failure raises BoardError naming the port and the fix.
"""

import hashlib
import os
import re
import subprocess
import sys
import tempfile
import time
from urllib.parse import urlparse

from cbtc.board.mpy_build import build
from cbtc.errors import BoardError, ConfigError
from cbtc.protocol import wire

CONFIG_NAME = "train_config.py"
BOOT_RE = r"lego-cbtc train %s boot (\S+)"
_FIX_PORT = "check the cable and the port name (mpremote connect list shows the boards)"
_FIX_BUSY = ("press RST, then hold the board's FLASH button in the first 2 s of boot so it stays in the REPL; "
             "close other programs using the port, then try again")


def parse_broker(url):
    """(host, port) of `mqtt://host[:port]` or `host[:port]`; ConfigError otherwise."""
    parsed = urlparse(url if "://" in url else "mqtt://" + url)
    if parsed.scheme not in ("mqtt", "tcp") or not parsed.hostname:
        raise ConfigError(f"--broker {url!r}: expected mqtt://HOST[:PORT] (TLS is not supported on the board)")
    try:
        return parsed.hostname, parsed.port or 1883
    except ValueError:
        raise ConfigError(f"--broker {url!r}: the port must be a number 1-65535") from None


def parse_key(key_hex):
    """The 16-byte key as 32 lower-case hex digits; ConfigError otherwise."""
    try:
        key = bytes.fromhex(key_hex)
    except ValueError:
        raise ConfigError(f"--key {key_hex!r} is not hex: give 32 hex digits (16 bytes)") from None
    if len(key) != 16:
        raise ConfigError(f"--key has {len(key)} bytes: give 32 hex digits (16 bytes)")
    return key.hex()


def train_config_source(train_id, key_hex, broker_host, broker_port, wifi_ssid=None, wifi_password="", extra=None):
    """Text of the board's train_config.py."""
    try:
        wire.check_train_id(train_id)
    except wire.WireError as exc:
        raise ConfigError(f"--train: {exc.reason}") from None
    config = {"train_id": train_id, "key_hex": parse_key(key_hex), "wifi_ssid": wifi_ssid,
              "wifi_password": wifi_password or "", "broker_host": broker_host, "broker_port": int(broker_port)}
    config.update(extra or {})
    lines = ["# Written by cbtc flash. Holds the train's key: never commit it.", "CONFIG = {"]
    lines += [f"    {name!r}: {config[name]!r}," for name in config]
    lines.append("}")
    return "\n".join(lines) + "\n"


def stage(out_dir, config_text):
    """Compile the firmware into out_dir and write train_config.py; returns the relative paths, config last."""
    files = [rel for rel in build(out_dir) if os.path.basename(rel) != CONFIG_NAME]
    with open(os.path.join(out_dir, CONFIG_NAME), "w") as fh:
        fh.write(config_text)
    return files + [CONFIG_NAME]


def _sha256(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def _board_script(files):
    """MicroPython code: make folders, drop .py files shadowed by new .mpy ones."""
    folders = sorted({os.path.dirname(f) for f in files if os.path.dirname(f)})
    stale = [f[:-4] + ".py" for f in files if f.endswith(".mpy")]
    return ("import os\nfor d in %r:\n    try:\n        os.mkdir(d)\n    except OSError:\n        pass\n"
            "for f in %r:\n    try:\n        os.remove(f)\n    except OSError:\n        pass\n" % (folders, stale))


def _hash_script(files):
    return ("import hashlib, binascii\nfor f in %r:\n    h = hashlib.sha256()\n    with open(f, 'rb') as fh:\n"
            "        while True:\n            b = fh.read(512)\n            if not b:\n                break\n"
            "            h.update(b)\n    print('sha', f, binascii.hexlify(h.digest()).decode())\n" % (files,))


def _mpremote(port, args, timeout_s):
    cmd = [sys.executable, "-m", "mpremote", "connect", port] + args
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        raise BoardError(f"board on {port} did not answer within {timeout_s:.0f} s: {_FIX_BUSY}") from None
    if proc.returncode != 0:
        detail = (proc.stderr.strip() or proc.stdout.strip()).splitlines()[-1:] or ["no output"]
        raise BoardError(f"mpremote on {port} failed ({detail[0]}): {_FIX_BUSY}")
    return proc.stdout


def copy_and_verify(port, staged_dir, files, timeout_s=120):
    """Copy `files` (relative to staged_dir) to the board and check each file's sha256 there."""
    args = ["exec", _board_script(files)]
    for rel in files:
        args += ["+", "fs", "cp", os.path.join(staged_dir, rel), ":" + rel]
    args += ["+", "exec", _hash_script(files)]
    out = _mpremote(port, args, timeout_s)
    on_board = dict(re.findall(r"^sha (\S+) ([0-9a-f]{64})\s*$", out, re.MULTILINE))
    for rel in files:
        if on_board.get(rel) != _sha256(os.path.join(staged_dir, rel)):
            raise BoardError(f"{rel} on the board at {port} does not match the local file after copying: the copy "
                             f"failed or the board's filesystem is full; flash again, or erase the board's files")
    return on_board


def reset_and_wait_boot(port, train_id, timeout_s=15.0):
    """Soft-reset the board from its friendly REPL and wait for the boot message; returns the firmware version."""
    import serial

    try:
        link = serial.Serial(port, 115200, timeout=0.1)
    except (serial.SerialException, OSError) as exc:
        raise BoardError(f"cannot open {port} ({exc}): {_FIX_PORT}") from None
    seen = b""
    try:
        link.write(b"\r\x03\x03\x02")     # interrupt, leave the raw REPL
        time.sleep(0.2)
        link.reset_input_buffer()
        link.write(b"\x04")               # soft reset: the board runs main.py
        deadline = time.monotonic() + timeout_s
        pattern = re.compile((BOOT_RE % re.escape(train_id)).encode())
        while time.monotonic() < deadline:
            seen += link.read(256)
            match = pattern.search(seen)
            if match:
                return match.group(1).decode()
    finally:
        link.close()
    tail = seen.decode("utf-8", "replace").strip().splitlines()[-3:]
    raise BoardError(f"the board on {port} did not print its boot message within {timeout_s:.0f} s after reset "
                     f"(last output: {tail!r}); check train_config.py and the MicroPython version on the board")


def flash(port, train_id, key_hex, broker_url, wifi_ssid=None, wifi_password="", extra=None, timeout_s=120):
    """Deploy and verify; returns {"files": n, "version": str, "port": port}."""
    if not os.path.exists(port):
        raise BoardError(f"serial port {port} does not exist: {_FIX_PORT}")
    host, broker_port = parse_broker(broker_url)
    config_text = train_config_source(train_id, key_hex, host, broker_port, wifi_ssid, wifi_password, extra)
    with tempfile.TemporaryDirectory(prefix="cbtc-flash-") as staged:
        files = stage(staged, config_text)
        copy_and_verify(port, staged, files, timeout_s)
    version = reset_and_wait_boot(port, train_id)
    return {"files": len(files), "version": version, "port": port}
