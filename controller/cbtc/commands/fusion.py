"""`cbtc fusion`: the paper's Table 1 (RMSE of dead reckoning, IPS, UKF encoder+IPS, UKF encoder+IPS+RFID) on its
scenario."""

import time

from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json
from cbtc.commands.progress_bar import shown, simulation_bar
from cbtc.errors import ConfigError
from cbtc.zone.config import paper_scenario

EXAMPLES = (
    "cbtc fusion --seed 1 --laps 2 --json",
)


def register(sub):
    p = sub.add_parser("fusion", help="print the sensor fusion RMSE table (the paper's Table 1) on the paper scenario",
                       description="Runs the paper scenario once, then replays the recorded reports through each "
                                   "fusion variant (dead reckoning, IPS alone, UKF encoder+IPS, UKF encoder+IPS+RFID) "
                                   "and prints their RMSE against truth beside the paper's. Exit status 1 when the "
                                   "paper's ordering does not hold.")
    p.add_argument("--layout", type=arg_types.layout, default="itb_square",
                   help="layout file or packaged name (default: itb_square)")
    p.add_argument("--seed", type=arg_types.seed, default=0,
                   help="random seed; the same seed gives the same table (default: 0)")
    p.add_argument("--laps", type=arg_types.whole(1), default=5, help="laps each train completes (default: 5)")
    p.add_argument("--ips-sigma", type=arg_types.number(above=0.0, example="0.02"), default=None, metavar="M",
                   help="IPS noise per axis (m) of both trains, e.g. 0.27 for the paper's IPS (default: the profile's)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--plot", metavar="PNG", type=arg_types.plot_file, default="",
                   help="write the paper's Figure 3 for train A to this PNG")
    p.set_defaults(func=run)


def run(args):
    from cbtc.experiments.fusion_table import fusion_table, paper_ordering_holds, records_from_recorder
    from cbtc.layout_files import load_layout
    from cbtc.sim.simulation import Simulation

    if args.laps < 1:
        raise ConfigError(f"--laps must be >= 1, got {args.laps}")
    layout = load_layout(args.layout)
    config = paper_scenario(layout, seed=args.seed, laps=args.laps, duration_s=60.0 * args.laps)
    if args.ips_sigma is not None:
        if not 0.0 < args.ips_sigma < 5.0:
            raise ConfigError(f"--ips-sigma is a noise level in metres in (0, 5), got {args.ips_sigma}")
        for spec in config.trains:
            spec.profile = spec.profile.with_changes(ips_sigma_m=args.ips_sigma)
    started = time.perf_counter()
    with simulation_bar("fusion", 1, shown(args)):   # --laps 20 runs for a while
        recorder = Simulation(config, keep_reports=True, keep_samples=True).run()
    rows, traces = fusion_table(layout, records_from_recorder(recorder))
    checks = paper_ordering_holds(rows)
    wall_s = time.perf_counter() - started
    train_ids = [t.train_id for t in config.trains]
    ips_sigma_m = config.trains[0].profile.ips_sigma_m
    if args.plot:
        from cbtc.experiments.fusion_plot import fusion_png  # matplotlib: only when a plot is asked for
        fusion_png(layout, traces, train_ids[0], args.plot,
                   f"{layout.name}, seed {args.seed}, IPS noise {100 * ips_sigma_m:.1f} cm per axis")
    if args.json:
        print_json({"layout": layout.name, "seed": args.seed, "laps": args.laps, "ips_sigma_m": ips_sigma_m,
                    "simulated_s": recorder.summary()["simulated_s"], "rows": rows, "checks": checks})
    else:
        print(f"paper scenario on {layout.name}: {recorder.t_s[-1]:.1f} s simulated, seed {args.seed}, "
              f"IPS noise {100 * ips_sigma_m:.1f} cm per axis ({wall_s:.1f} s)")
        print("RMSE in cm; x / y in the layout frame, along = along the track; paper = Table 1 (x / y)")
        print(format_table(_table_rows(rows, train_ids), _columns(train_ids)))
        for name, ok in checks.items():
            print(f"  {'ok  ' if ok else 'FAIL'} {name}")
        if args.plot:
            print(f"figure: {args.plot}")
    return 0 if all(checks.values()) else 1


def _columns(train_ids):
    cols = [("label", "method")]
    cols += [(f"t_{t}", f"{t} x/y") for t in train_ids]
    cols += [("x_cm", "mean x"), ("y_cm", "mean y"), ("along_cm", "along"), ("paper", "paper x/y")]
    return cols


def _table_rows(rows, train_ids):
    from cbtc.experiments.fusion_table import METHODS

    out = []
    labels = {key: label for key, label, _x, _y in METHODS}
    for row in rows:
        line = {"label": labels[row["method"]], "x_cm": _cm(row["x_cm"]), "y_cm": _cm(row["y_cm"]),
                "along_cm": _cm(row["along_cm"]),
                "paper": None if row["paper_x_cm"] is None else f"{row['paper_x_cm']} / {row['paper_y_cm']}"}
        for t in train_ids:
            r = row["trains"][t]
            line[f"t_{t}"] = f"{_cm(r['x_cm'])} / {_cm(r['y_cm'])}"
        out.append(line)
    return out


def _cm(value):
    return None if value is None else f"{value:.2f}"
