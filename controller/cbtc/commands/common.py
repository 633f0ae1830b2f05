"""Helpers shared by sub-commands: printing tables and JSON."""

import json
import sys


def print_json(data) -> None:
    print(json.dumps(data, indent=2, sort_keys=True))


def format_table(rows, columns):
    """A plain-text table of dict rows; `columns` is a list of (key, header)."""
    cells = [[header for _key, header in columns]]
    for row in rows:
        cells.append(["-" if row.get(key) is None else str(row.get(key)) for key, _header in columns])
    widths = [max(len(r[c]) for r in cells) for c in range(len(columns))]
    lines = ["  ".join(cell.rjust(w) for cell, w in zip(r, widths)) for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


TRAIN_COLUMNS = [("train", "train"), ("laps", "laps"), ("mean_lap_s", "mean lap s"), ("mean_gap_m", "mean gap m"),
                 ("min_gap_m", "min gap m"), ("station_stops", "stops"), ("collisions", "collisions"),
                 ("authority_overruns", "overruns"), ("estimation_rmse_m", "est. RMSE m")]


def run_scenario_and_report(config, title, args) -> int:
    """Run a scenario, draw `args.plot` if set, print the per-train table or `--json`; exit 1 on any collision."""
    import time

    from cbtc.experiments.plots import distance_time_png
    from cbtc.sim.simulation import Simulation

    started = time.perf_counter()
    recorder = Simulation(config).run()
    wall_s = time.perf_counter() - started
    summary = recorder.summary()
    if args.plot:
        distance_time_png([recorder], [title], args.plot)
    if args.json:
        print_json(summary)
    else:
        print(f"{title}: {summary['simulated_s']} s simulated in {wall_s:.1f} s "
              f"(policy {summary['policy']}, estimator {summary['estimator']})")
        print(format_table(summary["trains"], TRAIN_COLUMNS))
        print(f"collisions {summary['collisions']}, authority overruns {summary['authority_overruns']}, "
              f"emergency trips {summary['emergency_trips']}")
        if summary["all_standing_at_end_s"] > 20.0:
            print(f"warning: every train stood still for the last {summary['all_standing_at_end_s']:.0f} s: gridlock? "
                  f"(fixed block: give more blocks than the trains can fill, cbtc sim --blocks)", file=sys.stderr)
        if args.plot:
            print(f"distance-time plot: {args.plot}")
    return 0 if summary["collisions"] == 0 else 1
