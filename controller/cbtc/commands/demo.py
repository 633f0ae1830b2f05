"""`cbtc demo`: the source paper's scenario, two trains on the square loop (or a scenario file), on the embedded mock
broker."""

import argparse
from dataclasses import replace

from cbtc.commands import arg_types
from cbtc.commands.common import add_paper_or_scenario_args, run_scenario_and_report, with_scenario
from cbtc.errors import ConfigError
from cbtc.zone.config import paper_scenario

DEFAULT_PLOT = "cbtc-demo.png"

EXAMPLES = (
    "cbtc demo --laps 1 --plot demo.png",
    "cbtc demo --scenario lego_oval_mixed --laps 1 --json",
)


def register(sub):
    p = sub.add_parser("demo", help="run the paper scenario: two virtual trains on the square loop (no hardware)",
                       description="Two virtual LEGO trains run laps of the paper's square loop under the zone "
                                   "controller, on the in-process mock broker under a virtual clock.")
    add_paper_or_scenario_args(p)
    p.add_argument("--seed", type=arg_types.seed, default=None,
                   help="random seed; the same seed gives the same result (default: 0, or the scenario's)")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default=None,
                   help="position estimator (default: ukf, or the scenario's)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="PNG", type=arg_types.plot_file, default=None,
                   help="distance-time plot (default: cbtc-demo.png, none under --json; '' for none)")
    p.set_defaults(func=run)


def run(args):
    from cbtc.layout_files import load_layout

    if args.plot is None:   # the default picture, checked as a given one is (here, where it is known to be wanted)
        try:
            args.plot = "" if args.json else arg_types.plot_file(DEFAULT_PLOT)
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"--plot: {exc}; or give --plot ''") from None

    config = with_scenario(args, {"layout": "itb_square", "seed": 0, "estimator": "ukf"}, fixed=("layout",),
                           overrides={"seed": "seed", "estimator": "estimator"})
    if config is not None:
        if args.laps is not None:
            config = replace(config, laps=args.laps, duration_s=max(config.duration_s, 60.0 * args.laps))
        title = f"scenario {config.name}: {len(config.trains)} trains on {config.layout.name}, seed {config.seed}"
        return run_scenario_and_report(config, title, args)
    laps = args.laps or 5
    layout = load_layout(args.layout)
    config = paper_scenario(layout, seed=args.seed, laps=laps, duration_s=60.0 * laps, estimator=args.estimator)
    return run_scenario_and_report(config, f"paper scenario on {layout.name}, seed {args.seed}", args)
