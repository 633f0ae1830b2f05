"""Train-board drivers, byte-exact against constructed frames and a register-level fake MFRC522.

Every check in tests/mpy/check_*.py runs twice: imported here under CPython, and inside the MicroPython unix port
with an ESP8266-sized heap (`micropython -X heapsize=36K`) on the precompiled firmware and shims.
"""

import importlib
import sys

import pytest

from cbtc.firmware.manifest import FIRMWARE_DIR
from mpy_harness import MPY_TESTS_DIR, SHIMS_DIR, requires_micropython, run_micropython

for _folder in (SHIMS_DIR, MPY_TESTS_DIR, FIRMWARE_DIR):
    if _folder not in sys.path:
        sys.path.insert(0, _folder)

MODULES = ("check_encoder", "check_ips", "check_mfrc522", "check_motor")


def _checks():
    found = []
    for module_name in MODULES:
        module = importlib.import_module(module_name)
        found += [(module_name, name) for name in sorted(vars(module)) if name.startswith("check_")]
    return found


CHECKS = _checks()


def test_every_device_has_checks():
    assert {m for m, _ in CHECKS} == set(MODULES)
    assert len(CHECKS) >= 16


@pytest.mark.parametrize("module_name,check", CHECKS, ids=["%s.%s" % c for c in CHECKS])
def test_driver_under_cpython(module_name, check):
    getattr(importlib.import_module(module_name), check)()


@requires_micropython
@pytest.mark.parametrize("module_name,check", CHECKS, ids=["%s.%s" % c for c in CHECKS])
def test_driver_under_micropython(mpy_tree, module_name, check):
    script = "import %s\n%s.%s()\nprint('OK')\n" % (module_name, module_name, check)
    rc, out, err = run_micropython(mpy_tree, script, heap="36K")
    assert rc == 0 and "OK" in out, out + err
