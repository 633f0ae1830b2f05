"""Access to the firmware's own modules (wire protocol, OnboardUnit, telegrams) from the controller, and to the firmware files.

The firmware is flat MicroPython code (`import wire` on the board). The controller imports the very same files, so
there is one protocol definition and one OnboardUnit: the firmware folder goes on sys.path once, here.
"""

import importlib
import os
import sys

import cbtc.firmware as _firmware_package

FIRMWARE_DIR = os.path.dirname(os.path.abspath(_firmware_package.__file__))

if FIRMWARE_DIR not in sys.path:
    sys.path.insert(0, FIRMWARE_DIR)

wire = importlib.import_module("wire")
obu = importlib.import_module("obu")
telegram = importlib.import_module("telegram")


def firmware_files():
    """Paths (relative to FIRMWARE_DIR) of every file that goes onto a board, sorted."""
    found = []
    for root, _dirs, files in os.walk(FIRMWARE_DIR):
        for name in files:
            if name.endswith(".py") and not (root == FIRMWARE_DIR and name == "__init__.py"):
                found.append(os.path.relpath(os.path.join(root, name), FIRMWARE_DIR))
    return sorted(found)
