#!/usr/bin/env python3
"""Write a Mosquitto configuration for the testbed (same as `cbtc broker config`).

    python tools/make_broker_config.py --train-ids A,B --out broker/ [--port 1883] [--host 127.0.0.1]
"""

import sys

from cbtc.cli import main

if __name__ == "__main__":
    sys.exit(main(["broker", "config"] + sys.argv[1:]))
