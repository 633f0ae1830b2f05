"""The `cbtc` command line: one sub-command per module in `cbtc.commands`.

Each module there defines `register(subparsers)`, which adds its parser and sets `func(args) -> int`.
Adding a command is adding a module and one name to COMMANDS.
"""

import argparse
import importlib
import logging
import os
import sys
from importlib import metadata

from cbtc.errors import CbtcError
from cbtc.run_clock import RepeatLimit, RunClockFormatter

COMMANDS = (
    "demo",
    "sim",
    "layout", "scenario",
    "fusion",
    "compare",
    "ranging",
    "balise",
    "guard",
    "board",
    "flash",
    "calibrate",
    "setup", "zone", "trains", "keys", "broker", "bench", "fuzz", "campaign",
)


def _version() -> str:
    try:
        return metadata.version("lego-cbtc")
    except metadata.PackageNotFoundError:   # run from a source tree that was never installed
        return "unknown (not installed)"


class _Parser(argparse.ArgumentParser):
    """Refuses a bad command line in one line (naming the flag, the value and the fix) and exit status 2; the
    sub-commands' parsers are of this class too."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="cbtc",
        description="LEGO-scale Communication-Based Train Control: simulate, control, measure, flash.",
    )
    parser.add_argument("--version", action="version", version=f"cbtc {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        module = importlib.import_module(f"cbtc.commands.{name}")
        module.register(sub)
        examples = getattr(module, "EXAMPLES", ())
        if examples:   # each runs as written (tests/test_documented_commands.py)
            command = sub.choices[name]
            command.formatter_class = argparse.RawDescriptionHelpFormatter
            command.epilog = "examples:\n" + "\n".join(f"  {line}" for line in examples)
    return parser


def main(argv=None) -> int:
    # each line timed (the wall clock to the ms, or a simulation's own): a log read after a run tells what happened
    # when; a warning said again and again is held back and counted (cbtc.run_clock)
    handler = logging.StreamHandler()
    handler.setFormatter(RunClockFormatter("%(asctime)s %(name)s: %(levelname)s: %(message)s"))
    handler.addFilter(RepeatLimit())
    logging.basicConfig(level=logging.WARNING, handlers=[handler])
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
        if extra:
            _unknown(parser, args, extra)
    except SystemExit as exc:   # --help, --version, or a bad command line (already said): its status, returned
        return exc.code if isinstance(exc.code, int) else 2
    try:
        return int(args.func(args) or 0)
    except CbtcError as exc:
        print(f"cbtc {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"cbtc {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        _quiet_stdout()
        return 0


def _unknown(parser, args, extra) -> None:
    """Refuse words the command does not take, by the command's own parser, with the nearest flag it has."""
    import difflib

    command = parser._subparsers._group_actions[0].choices[args.command]
    inner = [a for a in command._actions if isinstance(a, argparse._SubParsersAction)]
    if inner and getattr(args, "what", None) in inner[0].choices:   # cbtc board virtual, cbtc calibrate encoder
        command = inner[0].choices[args.what]
    flags = [flag for action in command._actions for flag in action.option_strings]
    near = difflib.get_close_matches(extra[0].split("=")[0], flags, n=1) if extra[0].startswith("-") else []
    command.error(f"unrecognized arguments: {' '.join(extra)}" + (f"; did you mean {near[0]}?" if near else ""))


def _quiet_stdout() -> None:
    """The reader of our output went away (`cbtc layout show X | head`): what is left to print goes nowhere, so the
    command ends quietly, as the standard tools do, and Python's flush at exit raises nothing either."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (AttributeError, OSError, ValueError):   # not a real file (a test's capture)
        sys.stdout = open(os.devnull, "w")   # noqa: SIM115 -- lives until exit


if __name__ == "__main__":
    sys.exit(main())
