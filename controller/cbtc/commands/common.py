"""Helpers shared by sub-commands: printing tables and JSON, the options of live commands."""

import functools
import json
import os
import sys
from dataclasses import replace

from cbtc.bus.clients import MQTT_CLIENTS
from cbtc.commands import arg_types
from cbtc.errors import ConfigError
from cbtc.live.keys import ENV_PASSWORD, ENV_USERNAME, train_keys
from cbtc.zone.config import fleet_config


@functools.lru_cache(maxsize=None)
def module_doc(name: str) -> str:
    """The docstring of module `name`, read from its source without importing it (so `--help` stays light)."""
    import ast
    import importlib.util
    with open(importlib.util.find_spec(name).origin, encoding="utf-8") as fh:
        return ast.get_docstring(ast.parse(fh.read())) or ""


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
    """Run a scenario, draw `args.plot` if set, print the per-train table or `--json`; exit 1 on any safety violation
    (a collision, an authority overrun, an authority reaching beyond the train ahead)."""
    import time

    from cbtc.commands.progress_bar import shown, simulation_bar
    from cbtc.sim.recorder import violations
    from cbtc.sim.simulation import Simulation

    started = time.perf_counter()
    sim = Simulation(config, keep_samples=bool(args.plot))   # samples only for the picture
    recording = ReportRecording(args.record) if getattr(args, "record", None) else None
    if recording is not None:
        sim.record_reports(recording)
    try:
        with simulation_bar("sim", 1, shown(args)):
            recorder = sim.run()
    finally:
        if recording is not None:
            recording.close()
    wall_s = time.perf_counter() - started
    summary = recorder.summary()
    if args.plot:
        from cbtc.experiments.plots import distance_time_png  # matplotlib: only when a plot is asked for
        distance_time_png([recorder], args.plot)
    if args.json:
        print_json(summary)
    else:
        print(f"{title}: {summary['simulated_s']} s simulated in {wall_s:.1f} s "
              f"(policy {summary['policy']}, estimator {summary['estimator']})")
        print(format_table(summary["trains"], TRAIN_COLUMNS))
        beyond = summary["granted_beyond_m"]
        print(f"collisions {summary['collisions']}, authority overruns {summary['authority_overruns']}, "
              f"rolled onto a standing train {summary['rolled_onto']} (onto it: among the collisions), "
              f"authority beyond the train ahead {'-' if beyond is None else f'{beyond:+.3f} m'} (worst; > 0 is a "
              f"violation), emergency trips {summary['emergency_trips']}, stranded trains {summary['stranded']}")
        if summary["all_standing_at_end_s"] > 20.0 or summary["gridlocked"]:
            print("warning: every train stood still (or crept less than 5 cm) for the last 20 s or more: gridlock? "
                  "(a loop filled so that each train is held by the one ahead: give fewer trains or a longer layout; "
                  "fixed block: give more blocks than the trains can fill, cbtc sim --blocks)", file=sys.stderr)
        if args.plot:
            print(f"distance-time plot: {args.plot}")
        if recording is not None:
            print(f"{recording.lines} reports recorded in {args.record} (cbtc calibrate reads them)")
    return 1 if violations(summary) else 0


def write_json(path: str, data) -> None:
    """Write `data` as JSON to `path` atomically (readers never see half a file)."""
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(data, fh, indent=2, sort_keys=True)
    os.replace(tmp, path)


def fmt(value, digits=2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def add_connection_args(p, broker_default=None, setup: bool = False) -> None:
    """--broker, --username, --password, --credentials: how a live command reaches the broker; with `setup`, also
    --setup DIR, which gives them (and the fleet) from `cbtc setup`'s live.json (apply_setup)."""
    if setup:
        p.add_argument("--setup", type=arg_types.setup_folder, default=None, metavar="DIR",
                       help="a folder from `cbtc setup`: the broker, layout or scenario, trains, keys and "
                            "credentials of the run, as the other side reads them")
    p.add_argument("--broker", type=arg_types.broker_url, required=broker_default is None and not setup,
                   default=broker_default, metavar="URL",
                   help="MQTT broker, mqtt://HOST:PORT" + (" (or --setup DIR)" if setup else ""))
    p.add_argument("--username", default=None, help=f"broker user name (default: ${ENV_USERNAME})")
    p.add_argument("--password", default=None, help=f"broker password (default: ${ENV_PASSWORD})")
    p.add_argument("--credentials", type=arg_types.input_file, default=None, metavar="FILE",
                   help="credentials.json from `cbtc broker config`: each client logs in as its own user")
    add_mqtt_client_arg(p)


def add_mqtt_client_arg(p) -> None:
    """--mqtt-client: the lean client (default) or paho, the reference (cbtc.bus.clients)."""
    p.add_argument("--mqtt-client", choices=MQTT_CLIENTS, default=MQTT_CLIENTS[0],
                   help="MQTT client: lean (default; a fraction of paho's work per message) or paho (the reference)")


def add_fleet_args(p) -> None:
    """--layout, --trains/--train-ids, --scenario, --keys/--sim-seed: which trains, where, with which keys."""
    p.add_argument("--layout", type=arg_types.layout, default=None,
                   help="layout file or packaged name, e.g. itb_square (required unless --scenario FILE names it)")
    p.add_argument("--trains", type=arg_types.train_count, default=None, metavar="N",
                   help="number of trains, named by the scenario (default 2, or as many as --train-ids)")
    p.add_argument("--train-ids", type=arg_types.train_ids, default=None, metavar="A,B",
                   help="the trains' ids, in the scenario's order, e.g. A,B")
    arg_types.renamed(p, "--count", "--trains N")
    p.add_argument("--scenario", type=arg_types.fleet_scenario, default="auto", metavar="NAME|FILE",
                   help="the trains' ids, start positions, stops and profiles: paper (2 trains, stations main/A/B), "
                        "queue (N trains spread along the layout), auto (paper when it fits; default), or a "
                        "scenario file or packaged name (cbtc scenario list)")
    p.add_argument("--keys", type=arg_types.input_file, default=None, metavar="FILE",
                   help="JSON keys file {train_id: hex key} (cbtc keys new)")
    p.add_argument("--sim-seed", type=arg_types.seed, default=0,
                   help="without --keys: derive the keys as the simulator does from this seed (default 0)")
    p.add_argument("--status-period", type=arg_types.seconds, default=1.0,
                   help="seconds between status lines (default 1)")
    p.add_argument("--quiet", action="store_true", help="no status lines")


def fleet_from_args(args, seed: int = 0):
    """(ScenarioConfig, {train_id: key}) from the fleet options."""
    if not isinstance(args.scenario, str):   # a scenario file: it names the layout and the trains
        config = args.scenario
        for flag, value in (("--trains", args.trains), ("--train-ids", args.train_ids)):
            if value is not None:
                raise ConfigError(f"{flag}: the scenario {config.name} sets the trains; leave {flag} out or edit it")
        from cbtc.layout_files import load_layout
        if args.layout is not None and load_layout(args.layout).source != config.layout.source:
            raise ConfigError(f"--layout {args.layout}: the scenario {config.name} runs on {config.layout.name}; "
                              f"leave --layout out or give that one")
        if config.faults:
            print(f"note: the faults of scenario {config.name} are for cbtc sim; a real broker runs without them",
                  file=sys.stderr)
        train_ids = [spec.train_id for spec in config.trains]
        return config, train_keys(train_ids, args.keys, args.sim_seed)
    if args.layout is None:
        raise ConfigError("--layout: give the layout (a file or a packaged name such as itb_square), or a "
                          "--scenario FILE that names it")
    from cbtc.layout_files import load_layout
    layout = load_layout(args.layout)
    ids = args.train_ids
    if ids and args.trains is not None and args.trains != len(ids):
        raise ConfigError(f"--trains {args.trains} and --train-ids {','.join(ids)} disagree: give one of them, or "
                          f"as many ids as trains")
    count = args.trains if args.trains is not None else (None if ids else 2)
    config = fleet_config(layout, ids, count, args.scenario, seed=seed)
    train_ids = [spec.train_id for spec in config.trains]
    return config, train_keys(train_ids, args.keys, args.sim_seed)


SCENARIO_HELP = "a scenario file or packaged name (cbtc scenario list): layout, trains, stops, seed, duration, faults"


def add_paper_or_scenario_args(p) -> None:
    """--scenario FILE, or the paper scenario on --layout; --laps: what compare and demo run."""
    p.add_argument("--scenario", type=arg_types.scenario, default=None, metavar="FILE",
                   help=SCENARIO_HELP + " (default: the paper's two trains)")
    p.add_argument("--layout", type=arg_types.layout, default=None,
                   help="layout file or packaged name for the paper scenario (default: itb_square)")
    p.add_argument("--laps", type=arg_types.whole(1), default=None,
                   help="laps each train completes (default: 5, or the scenario's)")


def with_scenario(args, defaults: dict, fixed=(), overrides=None):
    """With `args.scenario` (a ScenarioConfig): refuse the flags in `fixed` (the file sets them) and return the
    scenario with the flags given of `overrides` ({args attribute: config field}) put over it; else None. Then fill
    `args`' unset values (None) from `defaults`."""
    config = getattr(args, "scenario", None)
    if config is not None:
        for name in fixed:
            if getattr(args, name, None) not in (None, [], ""):
                flag = "--" + name.replace("_", "-")
                raise ConfigError(f"{flag}: the scenario {config.name} sets it; leave {flag} out or edit the file")
        changes = {field: getattr(args, name) for name, field in (overrides or {}).items()
                   if getattr(args, name, None) is not None}
        config = replace(config, **changes)
    for name, value in defaults.items():
        if getattr(args, name, None) is None:
            setattr(args, name, value)
    return config


class ReportRecording:
    """Every report a zone accepts, as JSON lines ({"id", "recv_s", and the report's fields}: what `cbtc calibrate`
    reads), flushed a line at a time so a kill loses at most the line being written."""

    def __init__(self, path: str):
        self.path = path
        self.lines = 0
        self._fh = open(path, "w", encoding="utf-8")   # noqa: SIM115 -- closed by close()

    def __call__(self, train_id, report, recv_s):
        self._fh.write(json.dumps({"id": train_id, "recv_s": round(recv_s, 4), **report}, sort_keys=True) + "\n")
        self._fh.flush()
        self.lines += 1

    def close(self):
        self._fh.close()


def login_source(args, user: str) -> str:
    """Where `user`'s broker login came from, for the line that says the broker refused it."""
    if args.credentials:
        return f"the credentials file {args.credentials} (user {user}): is it the one `cbtc broker config` wrote " \
               f"for this broker?"
    from cbtc.bus.reach import LOGIN_OPTIONS
    return LOGIN_OPTIONS


def apply_setup(args) -> None:
    """Fill the connection and fleet options from `args.setup`'s live.json; one the folder gives that is also on the
    command line is refused, naming it (but --train-ids naming some of the folder's trains). Without --setup,
    --broker is required."""
    setup = args.setup
    if setup is None:
        if args.broker is None:
            raise ConfigError("--broker: give the broker, mqtt://HOST:PORT, or --setup DIR from `cbtc setup`")
        return
    folder, values = setup
    given = {"broker": args.broker, "credentials": args.credentials, "keys": args.keys, "layout": args.layout,
             "train_ids": args.train_ids, "scenario": None if isinstance(args.scenario, str) else args.scenario}
    if args.train_ids is not None and "train_ids" in values and set(args.train_ids) <= set(values["train_ids"]):
        values = {**values, "train_ids": args.train_ids}   # some of the setup's trains (one alone, to calibrate)
        given["train_ids"] = None
    for name, value in given.items():
        if value is not None and name in values:
            raise ConfigError(f"--{name.replace('_', '-')}: --setup {folder} gives it; leave it out (or run without "
                              f"--setup)")
    args.broker = values["broker"]
    args.credentials, args.keys = values["credentials"], values["keys"]
    if "scenario" in values:
        args.scenario = values["scenario"]
    else:
        args.layout, args.train_ids = values["layout"], values["train_ids"]
