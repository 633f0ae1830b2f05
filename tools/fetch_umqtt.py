#!/usr/bin/env python3
"""Fetch umqtt.simple (frozen into the ESP8266 firmware) for the tests that run the firmware under the MicroPython
unix port: into the git-ignored folder vendor/umqtt/ at the repository root (cbtc.board.umqtt_source does the
fetching). Idempotent: does nothing when the file is already there (use --force to fetch again).
"""

import argparse
import os
import shutil
import sys

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENDOR_DIR = os.path.join(REPO, "vendor")


def main(argv=None):
    from cbtc.board.umqtt_source import umqtt_simple
    from cbtc.errors import BoardError

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--force", action="store_true", help="download again even if vendor/umqtt/simple.py exists")
    args = parser.parse_args(argv)
    target = os.path.join(VENDOR_DIR, "umqtt", "simple.py")
    if os.path.exists(target) and not args.force:
        print("fetch_umqtt: %s already present" % os.path.relpath(target, REPO))
        return 0
    if args.force:
        shutil.rmtree(os.path.join(VENDOR_DIR, "umqtt"), ignore_errors=True)
    try:
        umqtt_simple(VENDOR_DIR)
    except BoardError as exc:
        raise SystemExit("fetch_umqtt: %s" % exc) from None
    print("fetch_umqtt: wrote %s (%d bytes)" % (os.path.relpath(target, REPO), os.path.getsize(target)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
