"""Argument types every command shares: a bad value is refused while the command line is parsed, before any work,
with one line naming the flag, the value and what to give instead (argparse adds the flag; exit status 2)."""

import argparse
import math
import os


def whole(minimum: int, maximum: int = None):
    """A whole number in [minimum, maximum]."""
    span = f">= {minimum}" if maximum is None else f"from {minimum} to {maximum}"

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number; give one {span}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"{value} is out of range; give a whole number {span}")
        return value
    parse.__name__ = "whole number"
    return parse


def seconds(text):
    """A finite duration above zero (s)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number of seconds; give e.g. 60") from None
    if not math.isfinite(value) or value <= 0.0:
        raise argparse.ArgumentTypeError(f"{text} is not a duration; give a finite number of seconds above 0, "
                                         f"e.g. 60")
    return value


seed = whole(0, 2 ** 32 - 1)
seed.__name__ = "seed"


def output_file(text):
    """A file to write: its folder must exist and be writable now, not after a long run."""
    folder = os.path.dirname(os.path.abspath(text)) or "."
    if not os.path.isdir(folder):
        raise argparse.ArgumentTypeError(f"{text}: folder {folder} does not exist; create it or give another path")
    if not os.access(folder, os.W_OK):
        raise argparse.ArgumentTypeError(f"{text}: folder {folder} is not writable; give another path")
    if os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text} is a folder; give a file name, e.g. {os.path.join(text, 'run.png')}")
    return text
