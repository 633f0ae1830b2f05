"""`cbtc sim`: any number of virtual trains on any layout, each following the one ahead."""

import time

from ..layout import load_layout
from ..plots import distance_time_png
from ..scenario import Simulation, queue_scenario
from .common import format_table, print_json
from .demo import TRAIN_COLUMNS


def register(sub):
    p = sub.add_parser("sim", help="simulate N trains on a layout", description=__doc__)
    p.add_argument("--layout", default="lego_oval", help="layout file or packaged name (default: lego_oval)")
    p.add_argument("--trains", type=int, default=3, help="number of trains (default: 3)")
    p.add_argument("--duration", type=float, default=120.0, help="simulated seconds (default: 120)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--policy", choices=("moving_block", "fixed_block"), default="moving_block")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default="ukf")
    p.add_argument("--json", action="store_true")
    p.add_argument("--plot", metavar="PNG", default="", help="write a distance-time plot")
    p.set_defaults(func=run)


def run(args):
    layout = load_layout(args.layout)
    config = queue_scenario(layout, args.trains, seed=args.seed, duration_s=args.duration, policy=args.policy,
                            estimator=args.estimator)
    started = time.perf_counter()
    recorder = Simulation(config).run()
    wall_s = time.perf_counter() - started
    summary = recorder.summary()
    if args.plot:
        distance_time_png([recorder], [f"{args.trains} trains, {summary['policy']} on {layout.name}"], args.plot)
    if args.json:
        print_json(summary)
    else:
        print(f"{args.trains} trains on {layout.name}: {summary['simulated_s']} s simulated in {wall_s:.1f} s")
        print(format_table(summary["trains"], TRAIN_COLUMNS))
        print(f"collisions {summary['collisions']}, authority overruns {summary['authority_overruns']}")
    return 0 if summary["collisions"] == 0 else 1
