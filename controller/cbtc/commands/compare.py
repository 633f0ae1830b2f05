"""`cbtc compare`: moving block with Takagi control against the fixed-block baseline, on the paper's scenario or a
scenario file."""

from dataclasses import replace

from cbtc.authority.policy import FIXED_BLOCK, MOVING_BLOCK
from cbtc.commands import arg_types
from cbtc.commands.common import add_paper_or_scenario_args, format_table, print_json, with_scenario
from cbtc.commands.progress_bar import shown, simulation_bar
from cbtc.errors import ConfigError
from cbtc.zone.config import paper_scenario

COLUMNS = [("policy", "system"), ("mean_gap_m", "mean gap m"), ("mean_gap_following_m", "gap following m"),
           ("min_gap_m", "min gap m"), ("mean_lap_s", "lap s"), ("mean_headway_s", "headway s"),
           ("trains_per_hour", "trains/h"), ("collisions", "collisions"), ("authority_overruns", "overruns"),
           ("emergency_trips", "trips")]


FOLLOWING_COLUMNS = [("v", "B m/s"), ("report_ms", "reports ms"), ("achieved", "gap m"), ("theoretical", "S_min m"),
                     ("ratio", "ratio"), ("lowest", "lowest"), ("floor", "floor"), ("fresh_floor", "fresh floor"),
                     ("leader_moved", "leader moved"), ("k_sigma", "k sigma"),
                     ("estimates", "estimates"), ("stop_window", "stop window"), ("inside_curve", "inside curve"),
                     ("trips", "trips")]


def _following_row(f):
    row = {"v": f["follower_speed_mps"], "report_ms": f["report_ms"], "achieved": f["achieved_gap_m"],
           "theoretical": f["theoretical_min_gap_m"], "ratio": f["achieved_over_theoretical"],
           "lowest": f["lowest_over_theoretical"], "fresh_floor": f["fresh_floor_ratio"],
           "trips": f["emergency_trips"]}
    for name, metres in f["overhead_budget_m"].items():
        row[name[:-2]] = round(100.0 * metres, 2)
    row["floor"] = f["safety_floor_ratio"]
    return row


EXAMPLES = (
    "cbtc compare --laps 1",
    "cbtc compare --layout lego_passing_loop --duration 300",
    "cbtc compare --scenario lego_oval_mixed --laps 1 --json",
)


def register(sub):
    p = sub.add_parser("compare", description=__doc__,
                       help="compare moving block with fixed block on the paper scenario (gap, lap time, safety)")
    add_paper_or_scenario_args(p)
    p.add_argument("--blocks", default="", help="comma-separated block counts to sweep for the fixed-block baseline")
    p.add_argument("--report-ms", default="", metavar="MS,...",
                   help="also run the steady-following experiment with every report at these periods (ms), e.g. "
                        "100,50,20 (default: 50 ms, and 20 ms from a train the controller sees followed closely)")
    p.add_argument("--follow-mps", default="", metavar="V,...",
                   help="also run the steady-following experiment behind a leader at these speeds (m/s), e.g. "
                        "0.3,0.5 (the follower's line speed is 0.6)")
    p.add_argument("--code-ber", type=arg_types.number(minimum=0.0, maximum=0.5, example="0.001"), default=0.0,
                   metavar="P",
                   help="bit-error rate of the fixed-block speed-code telegrams on the track circuits (default 0)")
    p.add_argument("--seed", type=arg_types.seed, default=None, help="random seed (default: 0, or the scenario's)")
    p.add_argument("--trains", type=arg_types.train_count, default=None, metavar="N",
                   help="on a track network: number of trains (default: 4)")
    p.add_argument("--duration", type=arg_types.seconds, default=None,
                   help="on a track network: simulated seconds (default: 600, or the scenario's)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON (no table, no bar)")
    p.add_argument("--plot", metavar="PNG", type=arg_types.plot_file, default="",
                   help="distance-time plot of both systems (the paper's Figure 4)")
    p.set_defaults(func=run)


def _number_list(text, option, kind, low, high, what, example):
    """The comma-separated numbers of `option` converted by `kind` (int or float), each in [low, high]; ConfigError
    naming the option, the bad item, `what` it must be and an example."""
    values = []
    for item in text.split(","):
        if item.strip():
            try:
                value = kind(item)
            except ValueError:
                value = None
            if value is None or not low <= value <= high:
                raise ConfigError(f"{option}: {item.strip()!r} is not {what}; give e.g. {option} {example}")
            values.append(value)
    return values


def run(args):
    # every setting is checked before the first (long) run
    from cbtc.commands.compare_network import network_base, run_network
    from cbtc.experiments.headway import (
        PAPER,
        block_sweep,
        check_block_counts,
        lone_lap,
        reductions,
        run_systems,
        steady_following,
    )
    from cbtc.layout_files import load_layout

    report_periods, speeds, counts = _checked_lists(args)
    network = network_base(args)
    if network is not None:
        return run_network(args, *network)
    base = with_scenario(args, {"layout": "itb_square", "seed": 0}, fixed=("layout",), overrides={"seed": "seed"})
    if base is None:
        laps = args.laps or 5
        layout = load_layout(args.layout)
        base = paper_scenario(layout, seed=args.seed, laps=laps, duration_s=80.0 * laps)
        title = f"paper scenario on {layout.name}, seed {args.seed}"
    else:
        if args.laps is not None:
            base = replace(base, laps=args.laps, duration_s=max(base.duration_s, 80.0 * args.laps))
        layout, args.seed = base.layout, base.seed
        title = f"scenario {base.name}: {len(base.trains)} trains on {layout.name}, seed {base.seed}"
    check_block_counts(layout, counts, base=base)
    with_alone = layout.closed and layout.stations   # the first train alone: its lap against the minimum
    runs = 2 + bool(with_alone) + 1 + len(report_periods) + len(speeds) + len(counts)
    with simulation_bar("compare", runs, shown(args)):
        systems, recorders = run_systems(base, code_ber=args.code_ber)
        alone = None
        if with_alone:
            low_s, high_s = base.trains[0].dwell_s or base.dwell_s
            alone = lone_lap(layout, base.trains[0].profile, dwell_s=low_s if low_s == high_s else 2.0,
                             seed=args.seed)
        following = steady_following(layout, seed=args.seed)
        by_period = [steady_following(layout, seed=args.seed, report_ms=ms) for ms in report_periods]
        by_speed = [steady_following(layout, seed=args.seed, leader_v_mps=v) for v in speeds]
        sweep = block_sweep(layout, counts, base=base) if counts else []
    cuts = reductions(systems[MOVING_BLOCK], systems[FIXED_BLOCK])
    least_s = _least_headway(base)
    result = {"layout": layout.name, "seed": args.seed, "scenario": base.name, "systems": systems, "reductions": cuts,
              "paper": PAPER, "following": following, "following_by_report_ms": by_period,
              "following_by_speed": by_speed,
              "block_sweep": sweep, "reference": base.reference, "alone": alone, "least_headway_s": least_s}
    if args.plot:
        from cbtc.experiments.plots import distance_time_png  # matplotlib: only when a plot is asked for
        distance_time_png([recorders[FIXED_BLOCK], recorders[MOVING_BLOCK]], args.plot,
                          ["fixed block (baseline)", "moving block + Takagi control"],
                          paper_note="paper: gap 1.89 m -> 0.91 m (-52 %), lap 15.72 s -> 6.84 s (-56 %)"
                          if base.name in (None, "paper_itb") else None)
    if args.json:
        print_json(result)
        return 0
    _print_comparison(args, title, base, result)
    return 0


def _print_comparison(args, title, base, result):
    """The comparison of `result` (run's figures) as tables and lines of text."""
    systems, cuts, least_s, alone = result["systems"], result["reductions"], result["least_headway_s"], \
        result["alone"]
    following, sweep = result["following"], result["block_sweep"]
    by_period, by_speed = result["following_by_report_ms"], result["following_by_speed"]
    print(title)
    print(format_table([systems[FIXED_BLOCK], systems[MOVING_BLOCK]], COLUMNS))
    codes = systems[FIXED_BLOCK]["speed_code_telegrams"]
    print(f"fixed-block speed codes as telegrams (bit-error rate {args.code_ber}): {codes['sent']} sent, "
          f"{codes['ok']} clean, {codes['corrected']} corrected, {codes['detected']} rejected (lowest code given), "
          f"{codes['undetected']} wrong")
    paper = base.name in (None, "paper_itb")
    print(f"moving block vs fixed block: gap -{cuts['gap_reduction_pct']} %{' (paper -52 %)' if paper else ''}, "
          f"lap time -{cuts['lap_reduction_pct']} %{' (paper -56 %)' if paper else ''}")
    if base.reference:
        ref = dict(base.reference)
        source = ref.pop("source")
        ours = systems[base.policy]
        print(f"{source}: " + ", ".join(f"{name} {value:g} (testbed {ours.get(name)})" for name, value in ref.items()))
    if least_s is not None:
        ours = systems[base.policy]["mean_headway_s"]
        print(f"the least headway the trains' profile allows (exact positions, no reaction time, no k sigma): "
              f"{least_s:.2f} s; {base.policy.replace('_', ' ')}: {ours} s"
              + (f" ({ours / least_s:.3f}x)" if ours else ""))
    if alone is not None:
        a = alone
        print(f"train {base.trains[0].train_id} alone, {a['dwell_s']:g} s at every station: lap {a['lap_s']} s, "
              f"the minimum for its profile {a['minimum_lap_s']} s ({a['lap_over_minimum']}x); top speed "
              f"{a['top_speed_mps']} m/s (line {a['line_speed_mps']}); stops {a['stop_error_mean_mm']} mm from the "
              f"mark on average, {a['stop_error_max_mm']} mm at most; {a['stops_with_creep']} times it stood short "
              f"of a stop and moved on to it")
    print("steady following (B behind a slower A): achieved gap against S_M + v^2/(2 beta_s) at B's speed, on "
          "average and at its lowest; floor: the ratio with a perfect speed loop and estimates (only the leader's "
          "travel since its data, k sigma and the stop window left); fresh floor: that with the leader's data of no "
          "age too; where the overhead goes, in cm, measured against truth")
    print(format_table([_following_row(f) for f in [following] + by_period + by_speed], FOLLOWING_COLUMNS))
    if sweep:
        print("fixed-block sweep:")
        print(format_table(sweep, [("blocks", "blocks"), ("block_length_m", "block m")] + COLUMNS[1:]))
    if args.plot:
        print(f"distance-time plot: {args.plot}")


def _checked_lists(args):
    """(report periods, follower speeds, block counts) of --report-ms, --follow-mps and --blocks, and --code-ber,
    checked: ConfigError naming the flag and its fix."""
    from cbtc.authority.speed_code_channel import SpeedCodeChannel

    report_periods = _number_list(args.report_ms, "--report-ms", int, 1, 10000, "a whole number >= 1", "100,20")
    speeds = _number_list(args.follow_mps, "--follow-mps", float, 0.05, 0.55, "a speed in [0.05, 0.55] m/s",
                          "0.3,0.5")
    counts = _number_list(args.blocks, "--blocks", int, 2, 10000, "a whole number >= 2", "3,4,8")
    SpeedCodeChannel(args.code_ber)
    return report_periods, speeds, counts


def _least_headway(base):
    """least_headway_s for a scenario of two or more trains of one profile on a loop with stations, each dwelling a
    fixed time at every one of them; None otherwise."""
    from cbtc.experiments.headway import least_headway_s
    profiles = {spec.profile for spec in base.trains}
    dwells = {spec.dwell_s or base.dwell_s for spec in base.trains}
    if len(base.trains) < 2 or not base.layout.closed or not base.layout.stations or len(profiles) != 1 \
            or len(dwells) != 1:
        return None
    (low_s, high_s), = dwells
    if low_s != high_s or any(set(spec.stops) != {st.name for st in base.layout.stations} for spec in base.trains):
        return None
    return round(least_headway_s(profiles.pop(), base.params.margin_m, low_s), 3)
