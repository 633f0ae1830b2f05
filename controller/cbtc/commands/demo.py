"""`cbtc demo`: the source paper's scenario, two trains on the square loop, on the embedded mock broker."""

from cbtc.commands import arg_types
from cbtc.commands.common import run_scenario_and_report
from cbtc.layout_files import load_layout
from cbtc.zone.config import paper_scenario


def register(sub):
    p = sub.add_parser("demo", help="run the paper scenario: two virtual trains on the square loop (no hardware)",
                       description="Two virtual LEGO trains run laps of the paper's square loop under the zone "
                                   "controller, on the in-process mock broker under a virtual clock.")
    p.add_argument("--layout", type=arg_types.layout, default="itb_square",
                   help="layout file or packaged name (default: itb_square)")
    p.add_argument("--laps", type=arg_types.whole(1), default=5, help="laps each train completes (default: 5)")
    p.add_argument("--seed", type=arg_types.seed, default=0,
                   help="random seed; the same seed gives the same result (default: 0)")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default="ukf")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="PNG", type=arg_types.output_file, default="cbtc-demo.png",
                   help="distance-time plot (default: cbtc-demo.png; '' for none)")
    p.set_defaults(func=run)


def run(args):
    layout = load_layout(args.layout)
    config = paper_scenario(layout, seed=args.seed, laps=args.laps, duration_s=60.0 * args.laps,
                            estimator=args.estimator)
    return run_scenario_and_report(config, f"paper scenario on {layout.name}, seed {args.seed}", args)
