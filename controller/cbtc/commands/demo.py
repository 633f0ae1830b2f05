"""`cbtc demo`: the source paper's scenario, two trains on the square loop, on the embedded mock broker."""

import time

from ..layout import load_layout
from ..plots import distance_time_png
from ..scenario import Simulation, paper_scenario
from .common import format_table, print_json

TRAIN_COLUMNS = [("train", "train"), ("laps", "laps"), ("mean_lap_s", "mean lap s"), ("mean_gap_m", "mean gap m"),
                 ("min_gap_m", "min gap m"), ("station_stops", "stops"), ("collisions", "collisions"),
                 ("authority_overruns", "overruns"), ("estimation_rmse_m", "est. RMSE m")]


def register(sub):
    p = sub.add_parser("demo", help="run the paper scenario: two virtual trains on the square loop (no hardware)",
                       description="Two virtual LEGO trains run laps of the paper's square loop under the zone controller, "
                                   "on the in-process mock broker under a virtual clock.")
    p.add_argument("--layout", default="itb_square", help="layout file or packaged name (default: itb_square)")
    p.add_argument("--laps", type=int, default=5, help="laps each train completes (default: 5)")
    p.add_argument("--seed", type=int, default=0, help="random seed; the same seed gives the same result (default: 0)")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default="ukf")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="PNG", default="cbtc-demo.png", help="distance-time plot (default: cbtc-demo.png; '' for none)")
    p.set_defaults(func=run)


def run(args):
    layout = load_layout(args.layout)
    config = paper_scenario(layout, seed=args.seed, laps=args.laps, duration_s=60.0 * args.laps,
                            estimator=args.estimator)
    started = time.perf_counter()
    recorder = Simulation(config).run()
    wall_s = time.perf_counter() - started
    summary = recorder.summary()
    if args.plot:
        distance_time_png([recorder], [f"moving block on {layout.name} (seed {args.seed})"], args.plot)
    if args.json:
        print_json(summary)
    else:
        print(f"paper scenario on {layout.name}: {summary['simulated_s']} s simulated in {wall_s:.1f} s "
              f"(policy {summary['policy']}, estimator {summary['estimator']}, seed {args.seed})")
        print(format_table(summary["trains"], TRAIN_COLUMNS))
        print(f"collisions {summary['collisions']}, authority overruns {summary['authority_overruns']}")
        if args.plot:
            print(f"distance-time plot: {args.plot}")
    return 0 if summary["collisions"] == 0 else 1
