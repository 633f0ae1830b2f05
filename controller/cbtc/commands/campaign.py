"""`cbtc campaign`: seeded simulation runs over fault classes x layouts x fleet sizes, judged by truth.

Each run is a `cbtc sim` command with one fault drawn from its seed (experiments/campaign.py says which run is
which). Runs are made in worker processes on every core, or on a Dask cluster with --scheduler; each finished run
is kept in the results file at once, so a stopped campaign, run again, makes only the missing runs. Exit status 1
when any run has a violation (a collision, an authority overrun, an authority reaching beyond the train ahead), each
printed with the `cbtc sim` command that reproduces it alone; 0 otherwise.
"""

import argparse
import os
import sys
import time

from cbtc.commands import arg_types
from cbtc.commands.common import SCENARIO_HELP, format_table, print_json
from cbtc.commands.progress_bar import bar, shown
from cbtc.errors import ConfigError
from cbtc.experiments import campaign

MAX_RUNS = 1_000_000


EXAMPLES = (
    "cbtc campaign --runs 4 --duration 10 --trains 2 --results runs.jsonl",
    "cbtc campaign --scenario paper_itb --runs 2 --duration 10 --fault link_loss --results paper-runs.jsonl",
)


def register(sub):
    p = sub.add_parser("campaign", help="run seeded faults over classes, layouts and fleet sizes, judged by truth",
                       description=__doc__ + "\n" + campaign.__doc__,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--runs", type=arg_types.whole(1, MAX_RUNS), default=100, help="number of runs (default 100)")
    p.add_argument("--fault", action="append", default=[], metavar="CLASS[:PARAM=VALUE,...]",
                   help="a fault class to run (repeatable; default: every class); parameters given are kept, the "
                        "others drawn per run; classes: " + ", ".join(campaign.CLASSES))
    p.add_argument("--scenario", type=arg_types.scenario, default=None, metavar="FILE",
                   help=SCENARIO_HELP + ": every run is it, with the run's seed and a fault drawn for its trains "
                        "(instead of --layouts and --trains)")
    p.add_argument("--layouts", default=None, metavar="NAMES",
                   help=f"layouts, comma-separated (default {','.join(campaign.LAYOUTS)})")
    p.add_argument("--trains", default=None, metavar="COUNTS",
                   help="fleet sizes: a range 2-6 or a list 2,4 (default 2-6)")
    p.add_argument("--duration", type=arg_types.seconds, default=60.0, help="simulated seconds per run (default 60)")
    p.add_argument("--seed", type=arg_types.seed, default=0,
                   help="seed of the first run; run k has seed + k (default 0)")
    p.add_argument("--workers", type=arg_types.whole(1), default=os.cpu_count() or 1,
                   help=f"worker processes on this machine (default: every core, {os.cpu_count()})")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run on this Dask distributed cluster instead, e.g. tcp://10.0.0.5:8786")
    p.add_argument("--results", type=arg_types.output_file, default="campaign-results.jsonl", metavar="FILE",
                   help="finished runs, kept and reused (default campaign-results.jsonl)")
    p.add_argument("--fresh", action="store_true", help="forget the results file's runs and make every run again")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def fleet_sizes(text: str) -> tuple:
    """'2-6' -> (2, 3, 4, 5, 6); '2,4' -> (2, 4); ConfigError otherwise."""
    try:
        if "-" in text:
            low, high = (int(v) for v in text.split("-"))
            sizes = tuple(range(low, high + 1))
        else:
            sizes = tuple(int(v) for v in text.split(","))
    except ValueError:
        raise ConfigError(f"--trains {text!r}: give a range such as 2-6 or a list such as 2,4") from None
    if not sizes or min(sizes) < 1:
        raise ConfigError(f"--trains {text!r}: give fleet sizes of 1 train or more, such as 2-6")
    return sizes


def checked_plan(args):
    """Every argument checked and every run planned before any run starts."""
    if not 5.0 <= args.duration <= 3600.0:
        raise ConfigError(f"--duration {args.duration}: give 5 to 3600 simulated seconds per run")
    if args.scenario is not None:
        return _scenario_plan(args)
    args.layouts = args.layouts or ",".join(campaign.LAYOUTS)
    args.trains = args.trains or "2-6"
    layouts = tuple(name.strip() for name in args.layouts.split(",") if name.strip())
    if not layouts:
        raise ConfigError(f"--layouts {args.layouts!r}: give layout names, such as itb_square,lego_oval")
    sizes = fleet_sizes(args.trains)
    from cbtc.sim.runs import sim_config
    for layout in layouts:
        for n in sizes:                                   # the layout loads and the fleet fits on it
            sim_config(layout, min(n, campaign.NETWORK_FLEET) if campaign.is_network(layout) else n, 0, args.duration)
    classes = campaign.parse_classes(args.fault or [   # by default, the classes that run on some layout given
        c for c in campaign.CLASSES if any(campaign.runs_on(c, name) for name in layouts)])
    specs = campaign.plan(args.runs, classes, layouts, sizes, args.duration, args.seed)
    for spec in specs:                                    # a train named in a class exists in every run
        spec.config()
        for text in spec.faults:
            train = campaign.faults.parse(text).params.get("train", "")
            if train and (not train[1:].isdigit() or int(train[1:]) > spec.trains):
                raise ConfigError(f"--fault {text}: no train {train} in a run of {spec.trains} trains "
                                  f"({spec.command()})")
    return specs


def _scenario_plan(args):
    """Every run the scenario file of `args.scenario`, with the run's seed and a drawn fault of a chosen class."""
    for flag, value in (("--layouts", args.layouts), ("--trains", args.trains)):
        if value is not None:
            raise ConfigError(f"{flag}: the scenario {args.scenario.name} sets the layout and the trains; leave "
                              f"{flag} out or edit the file")
    if any(text.partition(":")[0] == campaign.PACKED for text in args.fault):
        raise ConfigError(f"--fault {campaign.PACKED}: the scenario {args.scenario.name} sets where the trains "
                          f"start; choose another class")
    classes = campaign.parse_classes(args.fault or [c for c in campaign.CLASSES if c != campaign.PACKED])
    ids = [spec.train_id for spec in args.scenario.trains]
    specs = campaign.plan(args.runs, classes, (), (), args.duration, args.seed,
                          scenario=(args.scenario.source, args.scenario))
    for spec in specs:
        for text in spec.faults:
            train = campaign.faults.parse(text).params.get("train", "")
            if train and train not in ids:
                raise ConfigError(f"--fault {text}: no train {train} in scenario {args.scenario.name} ({ids})")
        spec.config()
    return specs


def run(args):
    from cbtc.experiments.campaign_runner import ResultsFile, run_dask, run_local

    specs = checked_plan(args)
    results = ResultsFile(args.results)
    if args.fresh:
        results.clear()
    todo = [spec for spec in specs if spec.command() not in results.records]
    reused = len(specs) - len(todo)
    if results.other_code and not args.json:
        print(f"campaign: {results.other_code} runs in {args.results} were made by other code (it changed since): "
              f"they are made again", file=sys.stderr)
    if results.unreadable and not args.json:
        print(f"campaign: {results.unreadable} unreadable lines in {args.results} (a run cut short?) are ignored; "
              f"their runs are made again", file=sys.stderr)
    where = f"Dask cluster {args.scheduler}" if args.scheduler else f"{min(args.workers, max(1, len(todo)))} workers"
    if not args.json:
        print(f"campaign: {len(specs)} runs of {args.duration:g} s ({reused} already in {args.results}), "
              f"{len(todo)} to make on {where}", flush=True)
    started = time.perf_counter()
    try:
        with bar("campaign", len(todo), shown(args) and bool(todo)) as update:
            made = [0]

            def done(record):
                results.add(record)
                made[0] += 1
                update(made[0], f"{made[0]}/{len(todo)} runs")
            _make(todo, args, done, run_dask, run_local)
    except KeyboardInterrupt:
        made = sum(1 for spec in todo if spec.command() in results.records)
        print(f"campaign: stopped; {made} of {len(todo)} runs made are kept in {args.results}: run the same command "
              f"again to make the rest", file=sys.stderr)
        raise
    figures = campaign.tables(specs, results.records)
    figures.update({"runs_made": len(todo), "runs_reused": reused, "wall_s": round(time.perf_counter() - started, 1),
                    "where": where, "results": args.results})
    if args.json:
        print_json(figures)
    else:
        _print(figures)
    return 1 if figures["violations"] else 0


def _make(todo, args, done, run_dask, run_local):
    if args.scheduler:
        run_dask(todo, args.scheduler, done)
    else:
        run_local(todo, min(args.workers, max(1, len(todo))), done)


COLUMNS = [("class", "fault class"), ("runs", "runs"), ("runs_with_violations", "violating"),
           ("collisions", "collisions"), ("authority_overruns", "overruns"), ("rolled_onto", "rolled onto"),
           ("worst_granted_beyond_m", "beyond m"), ("emergency_trips", "trips"), ("stranded", "stranded"),
           ("mean_following_gap_m", "follow gap m"), ("worst_gap_m", "worst gap m"), ("mean_lap_s", "lap s")]


def _print(f):
    rows = [dict(v, **{"class": cls}) for cls, v in f["by_fault"].items()]
    rows.append(dict({k: v for k, v in f.items() if k not in ("by_fault", "violations")}, **{"class": "all"}))
    print(format_table(rows, COLUMNS))
    print(f"{f['runs']} runs ({f['runs_made']} made now in {f['wall_s']} s on {f['where']}, {f['runs_reused']} "
          f"reused); beyond m: the worst reach of an authority past the true tail of the train ahead (> 0 is a "
          f"violation); rolled onto: a train ahead that rolled back into a standing train's margin or onto it "
          f"(onto it: counted among the collisions too)")
    if f["violations"]:
        print(f"{len(f['violations'])} runs with violations; each reproduces alone with:")
        for v in f["violations"]:
            print(f"  {'+'.join(v['kinds'])}: {v['command']}" + (f"  ({v['error']})" if "error" in v else ""))
    else:
        print("no violations")
