"""Shared pytest fixtures. The board-side checks (tests/mpy, run under CPython and the MicroPython unix port) import
the firmware's modules by their board names (`drivers.ips`), so the firmware folder is on this test process's path."""

import sys

import pytest

from cbtc.firmware.manifest import FIRMWARE_DIR

if FIRMWARE_DIR not in sys.path:
    sys.path.append(FIRMWARE_DIR)


@pytest.fixture(scope="session")
def mpy_tree(tmp_path_factory):
    """The firmware, host shims, fakes and umqtt compiled to .mpy in one folder, for the MicroPython unix port."""
    from mpy_harness import build_tree

    return build_tree(str(tmp_path_factory.mktemp("mpy_tree")))


from mosquitto_fixture import mosquitto, secured_mosquitto  # noqa: E402,F401  (real-broker fixtures)
