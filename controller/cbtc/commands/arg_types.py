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


# the formats a plot is written in: matplotlib's own, those its Agg backend and its vector backends write
# (tests/test_cli_inputs.py holds the list to matplotlib's)
PLOT_FORMATS = ("png", "pdf", "svg", "svgz", "eps", "ps", "jpg", "jpeg", "tif", "tiff", "webp")


def plot_file(text):
    """A plot to write: an output_file whose extension names a format matplotlib writes."""
    if not text:
        return text
    output_file(text)
    ext = os.path.splitext(text)[1].lstrip(".").lower()
    if ext not in PLOT_FORMATS:
        stem = os.path.splitext(text)[0] if ext else text
        raise argparse.ArgumentTypeError(f"{text}: a plot is written as {', '.join(PLOT_FORMATS)}, not "
                                         f"{ext or 'a file without an extension'}; give e.g. {stem}.png")
    return text


plot_file.__name__ = "plot file"


def train_count(text):
    """How many trains: a whole number >= 1; a list of names is pointed at --train-ids."""
    try:
        return whole(1)(text)
    except argparse.ArgumentTypeError:
        if any(c.isalpha() or c == "," for c in text):
            raise argparse.ArgumentTypeError(f"{text!r} is not a number of trains; name trains with --train-ids "
                                             f"{text}") from None
        raise


train_count.__name__ = "train count"


def train_ids(text):
    """Train ids 'A,B' -> ['A', 'B']: each a valid id, none twice."""
    from cbtc.bus.broker_config import checked_train_ids
    return _checked(lambda t: checked_train_ids([i.strip() for i in t.split(",") if i.strip()], repr(t)), text)


train_ids.__name__ = "train ids"


def zone_id(text):
    """A zone id: 1-16 of A-Z a-z 0-9 _ - (it is a topic level, cbtc/zc/<id>/...)."""
    from cbtc.protocol import wire
    try:
        return wire.check_train_id(text)
    except wire.WireError as exc:
        raise argparse.ArgumentTypeError(str(exc).replace("train id", "zone id")) from None


zone_id.__name__ = "zone id"


def seed_range(text):
    """Seeds: 'A-B' (A to B), 'A,B,C', or 'N' (0 to N-1); each a seed."""
    try:
        if "-" in text.strip("-"):
            low, high = (int(part) for part in text.split("-", 1))
            seeds = list(range(low, high + 1))
        elif "," in text:
            seeds = [int(part) for part in text.split(",") if part.strip()]
        else:
            seeds = list(range(int(text)))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a range of seeds; give e.g. 0-19, 3,5,8 or 20 "
                                         f"(0 to 19)") from None
    if not seeds or min(seeds) < 0 or max(seeds) > 2 ** 32 - 1:
        raise argparse.ArgumentTypeError(f"{text!r} holds no seeds from 0 to 2^32-1; give e.g. 0-19 or 20")
    return seeds


seed_range.__name__ = "seed range"


def output_folder(text):
    """A folder to write into: it may not exist yet, but the folder it goes in must."""
    parent = os.path.dirname(os.path.abspath(text)) or "."
    if os.path.exists(text) and not os.path.isdir(text):
        raise argparse.ArgumentTypeError(f"{text} is a file; give a folder")
    if not os.path.isdir(parent):
        raise argparse.ArgumentTypeError(f"{text}: folder {parent} does not exist; create it or give another path")
    return text


def renamed(parser, old: str, new: str) -> None:
    """`old` is no longer a flag of `parser`: using it is refused with the flag to use instead."""
    class _Renamed(argparse.Action):
        def __call__(self, p, namespace, values, option_string=None):
            p.error(f"{old} is now {new}")
    parser.add_argument(old, nargs="?", action=_Renamed, help=argparse.SUPPRESS)


def number(minimum: float = None, above: float = None, maximum: float = None, example: str = "1"):
    """A finite number: >= `minimum`, > `above`, <= `maximum` (those given)."""
    bounds = [f">= {minimum:g}" if minimum is not None else "", f"above {above:g}" if above is not None else "",
              f"<= {maximum:g}" if maximum is not None else ""]
    span = " and ".join(b for b in bounds if b) or "finite"

    def parse(text):
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number; give one {span}, e.g. {example}") from None
        if not math.isfinite(value) or (minimum is not None and value < minimum) \
                or (above is not None and value <= above) or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"{text} is out of range; give a number {span}, e.g. {example}")
        return value
    parse.__name__ = "number"
    return parse


def track_spans(text):
    """`all`, or stretches of track `FROM-TO[,FROM-TO...]` in metres along it (FROM >= 0, TO >= 0): a list of
    (from_m, to_m), or "all"."""
    if text.strip().lower() == "all":
        return "all"
    spans = []
    for part in text.split(","):
        low, sep, high = part.strip().partition("-")
        try:
            from_m, to_m = float(low), float(high)
        except ValueError:
            from_m = to_m = None
        if not sep or from_m is None or not (math.isfinite(from_m) and math.isfinite(to_m)) or from_m < 0.0 \
                or to_m < 0.0 or from_m == to_m:
            raise argparse.ArgumentTypeError(f"{part.strip()!r} is not a stretch of track; give all, or FROM-TO in "
                                             f"metres along the track (e.g. 0-2.5,3.1-6), FROM and TO different")
        spans.append((from_m, to_m))
    return spans


def tail_beacons(text):
    """`TRAIN=ADDRESS,...`: {beacon address: train id} (cbtc.live.ips_modem.parse_tail_beacons)."""
    from cbtc.live.ips_modem import parse_tail_beacons
    return _checked(parse_tail_beacons, text)


def input_file(text):
    """A file to read: it must exist now."""
    if not os.path.isfile(text):
        what = "is a folder" if os.path.isdir(text) else "is not a regular file" if os.path.exists(text) else \
            "does not exist"
        raise argparse.ArgumentTypeError(f"{text} {what}; give the path of a file")
    if not os.access(text, os.R_OK):
        raise argparse.ArgumentTypeError(f"{text} is not readable; check its permissions")
    return text


def _checked(check, text):
    """`check(text)`'s value, its CbtcError turned into the parser's one-line refusal."""
    from cbtc.errors import CbtcError
    try:
        return check(text)
    except CbtcError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def layout(text):
    """A layout: a packaged name or a YAML file (its contents are checked when it is loaded)."""
    from cbtc.layout_files import resolve_layout
    _checked(resolve_layout, text)
    return text


def broker_url(text):
    """mqtt://HOST:PORT (user and password may be in it)."""
    from cbtc.bus.client import parse_broker_url
    _checked(parse_broker_url, text)
    return text


def scenario(text):
    """A scenario file or packaged name, read and checked now: its ScenarioConfig."""
    from cbtc.scenario_files import load_scenario
    return _checked(load_scenario, text)


scenario.__name__ = "scenario"


FLEET_PRESETS = ("auto", "paper", "queue")


def fleet_scenario(text):
    """A live fleet's scenario: a preset (auto, paper, queue) as is, or a scenario file or packaged name, read and
    checked now (its ScenarioConfig)."""
    return text if text in FLEET_PRESETS else scenario(text)


fleet_scenario.__name__ = "scenario"


def setup_folder(text):
    """A folder `cbtc setup` wrote: (folder, its live.json's values, checked and with paths made whole)."""
    import json
    path = os.path.join(text, "live.json")
    if not os.path.isfile(path):
        raise argparse.ArgumentTypeError(f"{text} holds no live.json; make it with `cbtc setup --out {text}`")
    try:
        with open(path) as fh:
            values = json.load(fh)
        fleet = ("scenario",) if "scenario" in values else ("layout", "train_ids")
        values = {k: values[k] for k in ("broker", "keys", "credentials", *fleet)}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise argparse.ArgumentTypeError(f"{path} is not a setup `cbtc setup` wrote ({exc}); make it again with "
                                         f"`cbtc setup --out {text} --force`") from None
    broker_url(values["broker"])
    for name in ("keys", "credentials"):
        values[name] = input_file(os.path.join(text, values[name]))
    if "scenario" in values:
        values["scenario"] = scenario(values["scenario"])
    else:
        layout(values["layout"])
        values["train_ids"] = train_ids(",".join(values["train_ids"]))
    return text, values


setup_folder.__name__ = "setup folder"
