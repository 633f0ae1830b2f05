"""What goes onto each kind of board: the firmware's files per board role, relative to this folder.

`cbtc flash`, the MicroPython tests and the 32-bit heap test read these lists; nothing else is copied to a board.
This file itself stays on the host.
"""

import os

FIRMWARE_DIR = os.path.dirname(os.path.abspath(__file__))

# A train board: the boot (main, train, startup, assemble), pins and drivers (board, drivers/), the MQTT link
# policy, the OnboardUnit and the board's half of the wire protocol. train_config.py is written per train by
# `cbtc flash`.
TRAIN = (
    "main.py", "train.py", "startup.py", "assemble.py", "board.py", "link.py", "obu.py", "wire.py",
    "drivers/__init__.py", "drivers/encoder.py", "drivers/ips.py", "drivers/mfrc522.py", "drivers/motor.py",
)

# MicroPython-compatible modules that only the controller imports (the zone's half of the protocol, balise
# telegrams); the host tests run them under the MicroPython unix port too. They go onto no train board.
SHARED = ("messages.py", "wire_zc.py", "telegram.py")

ROLES = {"train": TRAIN}


def files(role: str = "train") -> tuple:
    """The files of a board role, e.g. files("train")."""
    if role not in ROLES:
        raise ValueError(f"unknown board role {role!r}: one of {sorted(ROLES)}")
    return ROLES[role]
