"""The `cbtc` command line: one sub-command per module in `cbtc.commands`.

Each module there defines `register(subparsers)`, which adds its parser and sets `func(args) -> int`.
Adding a command is adding a module and one name to COMMANDS.
"""

import argparse
import importlib
import logging
import sys

from cbtc.errors import CbtcError

COMMANDS = (
    "demo",
    "sim",
    "layout",
    "fusion",
    "compare",
    "ranging",
    "balise",
    "guard",
    "flash",
    "calibrate",
    "zone", "trains", "keys", "broker", "bench", "fuzz", "campaign",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cbtc",
        description="LEGO-scale Communication-Based Train Control: simulate, control, measure, flash.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(f"cbtc.commands.{name}").register(sub)
    return parser


def main(argv=None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(name)s: %(levelname)s: %(message)s")
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except CbtcError as exc:
        print(f"cbtc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"cbtc {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
