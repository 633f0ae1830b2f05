"""`cbtc guard`: the faulty-leader scenario with the onboard collision guard off and on, collisions per seed."""

from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json
from cbtc.commands.progress_bar import shown, simulation_bar

EXAMPLES = (
    "cbtc guard --seeds 0-1 --duration 20",
)


def register(sub):
    p = sub.add_parser("guard", help="run a faulty leader: collisions without and with the onboard ranging guard",
                       description="Runs the paper scenario with train A's encoder counting 1.5x fast and its IPS "
                                   "1 m ahead, so the zone controller's authority for train B is too long; once "
                                   "without and once with train-to-train ranging and B's onboard collision guard. "
                                   "Exit status 1 unless the guard run has 0 collisions on every seed.")
    p.add_argument("--seeds", type=arg_types.seed_range, default=list(range(5)), metavar="RANGE",
                   help="seeds: A-B, a list A,B,C, or N for 0 to N-1 (default: 0-4)")
    p.add_argument("--duration", type=arg_types.seconds, default=60.0, help="simulated seconds per run (default: 60)")
    p.add_argument("--layout", type=arg_types.layout, default="itb_square",
                   help="layout file or packaged name (default: itb_square)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args):
    from cbtc.experiments.guard import ENCODER_FAULT, IPS_OFFSET_M, guard_comparison

    with simulation_bar("guard", 2 * len(args.seeds), shown(args)):   # each seed: guard off, then on
        result = guard_comparison(args.seeds, args.layout, args.duration)
    off_runs = sum(1 for case in result["off"] if case["collisions"] > 0)
    on_total = sum(case["collisions"] for case in result["on"])
    if args.json:
        print_json({"encoder_fault": ENCODER_FAULT, "ips_offset_m": IPS_OFFSET_M, "runs": result,
                    "seeds_with_collision_guard_off": off_runs, "collisions_guard_on": on_total})
    else:
        print(f"faulty leader A (encoder x{ENCODER_FAULT}, IPS +{IPS_OFFSET_M} m), {args.seeds} seeds, "
              f"{args.duration:.0f} s each")
        rows = [{"seed": off["seed"], "off": off["collisions"], "off_gap": off["min_gap_m"], "on": on["collisions"],
                 "on_gap": on["min_gap_m"], "trips": on["guard_trips"]}
                for off, on in zip(result["off"], result["on"])]
        print(format_table(rows, [("seed", "seed"), ("off", "collisions, guard off"), ("off_gap", "min gap m"),
                                  ("on", "collisions, guard on"), ("on_gap", "min gap m"), ("trips", "guard trips")]))
        print(f"guard off: collision in {off_runs} of {len(args.seeds)} seeds; guard on: {on_total} collisions")
    return 0 if on_total == 0 else 1
