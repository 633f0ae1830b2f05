"""`cbtc bench latency|sim|fusion|controller|memory|build|startup|all`: report -> command round trips through a real
MQTT broker and the controller's compute time (experiments/latency.py says what each figure measures); simulation
speed, the filter's update time, memory growth, the compiled build and start-up, each beside its reference
(experiments/speed.py)."""

import argparse
import sys

from cbtc.commands import arg_types
from cbtc.commands.common import add_mqtt_client_arg, format_table, module_doc, print_json
from cbtc.commands.progress_bar import shown, steps
from cbtc.errors import ConfigError

EXAMPLES = (
    "cbtc bench latency --trains 4 --duration 2 --warmup 0.5 --json",
    "cbtc bench sim --layout lego_oval --trains 4 --duration 10",
    "cbtc bench fusion --trains 5 --steps 10",
    "cbtc bench controller --trains 4 --duration 5",
    "cbtc bench memory --trains 2 --duration 20",
    "cbtc bench all --duration 2 --controller-duration 1 --memory-duration 10 --json",
    "cbtc bench startup --runs 1",
    "cbtc bench build --duration 5",
)


def register(sub):
    p = sub.add_parser("bench", help="measure latency, simulation speed, fusion and start-up, each beside a reference",
                       description=module_doc("cbtc.experiments.latency"),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    bench_sub = p.add_subparsers(dest="bench_command", metavar="WHAT")
    bench_sub.required = True
    _latency_parser(bench_sub)
    _sim_parsers(bench_sub)
    _other_parsers(bench_sub)


def _latency_parser(bench_sub):
    lat = bench_sub.add_parser("latency", help="time the report -> command round trip through the broker",
                               description=module_doc("cbtc.experiments.latency"),
                               formatter_class=argparse.RawDescriptionHelpFormatter)
    lat.add_argument("--broker", default="embedded", metavar="URL",
                     help="mqtt://HOST:PORT of an open broker, or 'embedded' (default): a private Mosquitto")
    lat.add_argument("--trains", type=arg_types.whole(1), default=20, help="number of virtual trains (default 20)")
    lat.add_argument("--rate", type=arg_types.number(minimum=1.0, maximum=50.0, example="20"), default=20.0,
                     metavar="HZ", help="reports a second each train sends (default 20, the board's); the raw paho "
                                        "reference pings at the same rate")
    lat.add_argument("--duration", type=arg_types.seconds, default=10.0,
                     help="seconds measured after the warm-up (default 10)")
    lat.add_argument("--warmup", type=arg_types.number(minimum=0.0, example="2"), default=2.0,
                     help="seconds left out at the start (default 2)")
    lat.add_argument("--train-procs", type=arg_types.whole(1), default=4,
                     help="processes the trains are shared out to (default 4): in one process, 20 trains queue "
                          "behind each other for the GIL as 20 boards never would")
    lat.add_argument("--layout", type=arg_types.layout, default=None,
                     help="layout (default: a LEGO oval long enough for the trains)")
    lat.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    add_mqtt_client_arg(lat)
    lat.add_argument("--json", action="store_true", help="print the figures as JSON")
    lat.set_defaults(func=run_latency)


def _sim_parsers(bench_sub):
    sim = _speed_parser(bench_sub, "sim", "measure simulated seconds per wall second, beside a do-nothing controller")
    sim.add_argument("--layout", type=arg_types.layout, default=None,
                     help="one layout (with --trains); default: the paper's 2 trains on itb_square, 11 on lego_oval, "
                          "50 on lego_long_oval")
    sim.add_argument("--trains", type=arg_types.train_count, default=None, help="trains on --layout")
    sim.add_argument("--duration", type=arg_types.seconds, default=30.0, help="simulated seconds a case (default 30)")
    sim.add_argument("--runs", type=arg_types.whole(1, 100), default=3,
                     help="runs of each case and of its reference, in turn (default 3): the fastest of each is "
                          "the figure, as timeit takes it")
    sim.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    sim.set_defaults(func=run_sim)
    fusion = _speed_parser(bench_sub, "fusion", "time our filter's train-update beside filterpy's, on the same inputs")
    fusion.add_argument("--trains", type=arg_types.train_count, default=50, help="filters (default 50)")
    fusion.add_argument("--steps", type=arg_types.whole(1), default=40, help="updates each (default 40)")
    fusion.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    fusion.set_defaults(func=run_fusion)
    ctl = _speed_parser(bench_sub, "controller", "time a zone per report, beside decoding the reports alone")
    ctl.add_argument("--trains", type=arg_types.train_count, default=None,
                     help="trains (default: 11 and 50); up to 11 on lego_oval, more on lego_long_oval")
    ctl.add_argument("--duration", type=arg_types.seconds, default=10.0,
                     help="simulated seconds of reports replayed (default 10)")
    ctl.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    ctl.set_defaults(func=run_controller)


def _other_parsers(bench_sub):
    mem = _speed_parser(bench_sub, "memory", "measure a simulation's memory growth an hour, beside keeping samples")
    mem.add_argument("--trains", type=arg_types.train_count, default=6, help="trains on lego_oval (default 6)")
    mem.add_argument("--duration", type=arg_types.seconds, default=600.0,
                     help="simulated seconds (default 600; 3600 for the hour itself)")
    mem.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    mem.set_defaults(func=run_memory)
    every = _speed_parser(bench_sub, "all", "run sim, fusion, controller, memory and startup in one run, one report")
    every.add_argument("--duration", type=arg_types.seconds, default=30.0,
                       help="simulated seconds of each sim case (default 30)")
    every.add_argument("--controller-duration", type=arg_types.seconds, default=10.0,
                       help="simulated seconds of reports the controller replays (default 10)")
    every.add_argument("--memory-duration", type=arg_types.seconds, default=3600.0,
                       help="simulated seconds of the memory run (default 3600: an hour)")
    every.add_argument("--runs", type=arg_types.whole(1, 100), default=3,
                       help="runs of each sim case and of its reference, in turn (default 3): the fastest of "
                            "each is the figure, as timeit takes it")
    every.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    every.set_defaults(func=run_all)
    build = _speed_parser(bench_sub, "build", "time the compiled build beside its Python source (CBTC_PURE=1)")
    build.add_argument("--duration", type=arg_types.seconds, default=10.0,
                       help="simulated seconds of the simulation and of the zone's replay (default 10)")
    build.add_argument("--seed", type=arg_types.seed, default=0, help="random seed of the runs measured (default 0)")
    build.set_defaults(func=run_build)
    start = _speed_parser(bench_sub, "startup", "measure the time and memory of commands that do little, beside python")
    start.add_argument("--runs", type=arg_types.whole(1, 100), default=5, help="runs of each, in turn (default 5)")
    start.set_defaults(func=run_startup)


def _speed_parser(bench_sub, name, help_text):
    """A `cbtc bench` measure of experiments/speed.py, with its `--json`."""
    p = bench_sub.add_parser(name, help=help_text, description=module_doc("cbtc.experiments.speed"),
                             formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    return p


def run_latency(args):
    from cbtc.experiments import latency
    if shown(args):   # no bar: its drawing would take the very CPU and time this measures
        seconds = 2 * (args.warmup + args.duration)
        print(f"bench latency: about {seconds:.0f} s with start-up ({args.warmup:g} s warm-up and {args.duration:g} s "
              f"measured, for the zone and then the ping-pong reference)", file=sys.stderr, flush=True)
    result = latency.run_latency(args)
    if args.json:
        print_json(result)
    else:
        _print(result)
    return 0


def _machine() -> dict:
    """Where the figures were measured: cores, Python, and how many cbtc modules ran compiled (0: plain Python)."""
    import os
    import platform

    import cbtc
    compiled = len(cbtc.compiled_modules())
    return {"cores": os.cpu_count(), "python": platform.python_version(), "machine": platform.machine(),
            "build": "compiled" if compiled else "plain", "compiled_modules": compiled}


def _build_words(compiled_modules: int) -> str:
    return f"compiled build, {compiled_modules} modules" if compiled_modules else \
        "plain Python build (CBTC_COMPILE=1 pip install . compiles)"


def _emit(args, name, figures, printer):
    """Print one measure's figures: as JSON with the machine under `--json`, else by `printer`."""
    if args.json:
        print_json({"machine": _machine(), name: figures})
    else:
        printer(figures)
    return 0


def run_sim(args):
    from cbtc.experiments import speed
    if (args.layout is None) != (args.trains is None):
        raise ConfigError("bench sim: give --layout and --trains together, or neither (the three standard cases)")
    cases = speed.SIM_CASES if args.layout is None else ((args.layout, args.trains),)
    with steps("bench sim", len(cases), shown(args)) as step:
        rows = [step(f"{n} trains on {layout}", speed.sim_speed, layout, n, args.duration, args.seed, args.runs)
                for layout, n in cases]
    return _emit(args, "sim", rows, _print_sim)


def _print_sim(rows):
    machine = _machine()
    print(f"simulation speed ({machine['cores']} cores, {_build_words(machine['compiled_modules'])}): simulated "
          f"seconds per wall second, the full run beside the same world with a do-nothing controller; the fastest of "
          f"{rows[0]['runs']} runs of each, every run's figure beside it")
    rows = [dict(row, every_run=" / ".join(f"{x:g}" for x in row["real_time_factors"])) for row in rows]
    print(format_table(rows, [("layout", "layout"), ("trains", "trains"), ("simulated_s", "simulated s"),
                              ("wall_s", "wall s"), ("real_time_factor", "x real time"), ("every_run", "every run"),
                              ("reference_real_time_factor", "x, no controller"),
                              ("controller_share", "controller share"), ("reports_per_train_s", "reports/train/s"),
                              ("commands_per_report", "commands/report"), ("us_per_report", "us/report"),
                              ("collisions", "collisions"),
                              ("authority_overruns", "overruns"), ("emergency_trips", "trips")]))


def run_fusion(args):
    from cbtc.experiments import speed
    row = speed.fusion_speed(args.trains, args.steps, args.seed)
    return _emit(args, "fusion", row, _print_fusion)


def _print_fusion(row):
    print(f"fusion, {row['trains']} filters x {row['steps']} updates (predict 50 ms, odometer, IPS fix): ours "
          f"{row['ours_us']} us a train-update, filterpy {row['filterpy_us']} us: {row['speedup']}x; largest "
          f"difference {row['max_state_difference']:.1e} (state), {row['max_covariance_difference']:.1e} (covariance)")


def run_controller(args):
    from cbtc.experiments import speed
    counts = (args.trains,) if args.trains else (11, 50)
    with steps("bench controller", len(counts), shown(args)) as step:
        rows = [step(f"{n} trains", speed.controller_speed, n, args.duration, args.seed) for n in counts]
    return _emit(args, "controller", rows, _print_controller)


def _print_controller(rows):
    print("zone controller, replaying a simulated run's reports (its cycles included), beside decoding them alone:")
    print(format_table(rows, [("layout", "layout"), ("trains", "trains"), ("reports", "reports"),
                              ("commands", "commands"), ("zone_us_per_report", "zone us/report"),
                              ("decode_us_per_report", "decode us/report"), ("zone_over_decode", "ratio")]))


def run_memory(args):
    from cbtc.experiments import speed
    if args.trains > 11:
        raise ConfigError(f"bench memory: --trains {args.trains}: lego_oval holds up to 11 trains")
    row = speed.memory_growth(args.trains, args.duration, args.seed)
    return _emit(args, "memory", row, _print_memory)


def _print_memory(row):
    print(f"memory, {row['trains']} trains on {row['layout']} for {row['simulated_s']:g} simulated s: resident "
          f"{row['warm_mib']} MiB after a tenth, {row['end_mib']} MiB at the end: {row['growth_mib_per_hour']} MiB a "
          f"simulated hour (keeping every sample: {row['reference_growth_mib_per_hour']} MiB an hour), extrapolated "
          f"from the growth over the last {row['simulated_s'] * 0.9:g} simulated s; a longer --duration measures it "
          f"closer")


def run_all(args):
    """Every figure the simulation-speed work is judged by, measured one after the other in one process's run."""
    from cbtc.experiments import speed
    with steps("bench all", len(speed.SIM_CASES) + 5, shown(args)) as step:
        out = {"sim": [step(f"sim, {n} trains on {layout}", speed.sim_speed, layout, n, args.duration, args.seed,
                            args.runs) for layout, n in speed.SIM_CASES],
               "fusion": step("fusion", speed.fusion_speed, 50, 40, args.seed),
               "controller": [step(f"controller, {n} trains", speed.controller_speed, n, args.controller_duration,
                                   args.seed) for n in (11, 50)],
               "memory": step("memory", speed.memory_growth, 6, args.memory_duration, args.seed),
               "startup": step("start-up", speed.startup, 5)}
    out["machine"] = _machine()   # after the measures: the modules they ran are loaded, compiled or not
    if args.json:
        print_json(out)
        return 0
    _print_sim(out["sim"])
    _print_fusion(out["fusion"])
    _print_controller(out["controller"])
    _print_memory(out["memory"])
    _print_startup(out["startup"], 5)
    return 0


def run_build(args):
    from cbtc.experiments import speed
    if shown(args):
        print(f"bench build: four fresh processes in turn, {args.duration:g} simulated s each", file=sys.stderr,
              flush=True)
    row = speed.build_speed(args.duration, args.seed)
    return _emit(args, "build", row, _print_build)


def _print_build(row):
    if not row["compiled_modules"]:
        print("this install is plain Python (the default, an editable install, or no C compiler at install): nothing "
              "to compare; `CBTC_COMPILE=1 pip install .` with a C compiler builds the compiled modules")
        return
    print(f"compiled build ({row['compiled_modules']} modules) beside its Python source (CBTC_PURE=1):")
    print(f"  simulation, {row['sim_trains']} trains on {row['sim_layout']}: {row['sim_real_time_factor']}x real time, "
          f"source {row['pure_sim_real_time_factor']}x: {row['sim_speedup']}x faster; the same simulation: "
          f"{'yes' if row['same_simulation'] else 'NO'}")
    print(f"  zone, {row['zone_trains']} trains: {row['zone_us_per_report']} us a report, source "
          f"{row['pure_zone_us_per_report']} us: {row['zone_speedup']}x faster; the same commands: "
          f"{'yes' if row['same_commands'] else 'NO'}")


def run_startup(args):
    from cbtc.experiments import speed
    rows = speed.startup(args.runs)
    return _emit(args, "startup", rows, lambda found: _print_startup(found, args.runs))


def _print_startup(rows, runs):
    print(f"start-up, median of {runs} runs each, peak resident memory:")
    print(format_table(rows, [("command", "command"), ("wall_s", "wall s"), ("resident_mib", "resident MiB"),
                              ("vs_python", "x python -c pass")]))


def _print(f):
    print(f"{f['trains']} trains on {f['layout']} through {f['broker']}, reports at {f['report_hz']} Hz a train, "
          f"controller cycle {f['controller_cycle_hz']} Hz, {f['duration_s']} s measured; the zone's build: "
          f"{_build_words(f['compiled_modules'])}")
    rows = [("transport_rtt_ms", "transport round trip (uplink + downlink)"),
            ("uplink_ms", "  report published -> controller handles it"),
            ("downlink_ms", "  command published -> train handles it"),
            ("answer_wait_ms", "controller: report received -> its command published"),
            ("report_to_cmd_ms", "report published -> its command received"),
            ("event_answer_ms", "report -> triggered command to the train behind"),
            ("cycle_compute_ms", "controller cycle compute"),
            ("on_report_compute_ms", "controller on_report compute")]
    for key, label in rows:
        s = f[key]
        p50 = "       -" if s["p50"] is None else f"{s['p50']:8.3f}"
        p99 = "       -" if s["p99"] is None else f"{s['p99']:8.3f}"
        print(f"  {label:52s} p50 {p50} ms  p99 {p99} ms  (n={s['n']})")
    print(f"  reports {f['reports_received']}/{f['reports_published']} received ({f['reports_dropped']} dropped), "
          f"{f['reports_answered']} answered ({f['reports_unanswered']} unanswered); trains moving: "
          f"{f['moving_trains']}/{f['trains']}; controller process CPU {100 * f['controller_cpu_core_share']:.0f} % "
          f"of a core")
    r = f["reference"]
    rt = r["round_trip_ms"]
    print(f"reference, raw paho ping-pong with {f['trains']} clients at {f['rate_hz']:g} Hz through the same broker: "
          f"p50 {rt['p50']} ms, p99 {rt['p99']} ms, max {rt['max']} ms ({r['pings_lost']} of {r['pings_sent']} lost; "
          f"answering CPU {100 * r['answering_cpu_core_share']:.0f} % of a core)")
    print(f"report -> command over the reference: p50 {f['p50_over_reference']}x, p99 {f['p99_over_reference']}x")
