"""`cbtc trains`: N virtual trains on a real MQTT broker, each the firmware's own OnboardUnit over a physics model.

Each train has its own MQTT connection (client id and broker user `train-<id>`, retained status with a last will)
and speaks exactly the firmware's protocol. Start positions and station stops come from the same scenario as
`cbtc zone` uses. A status line per second shows the trains' true positions, speeds, onboard modes and faults; at
the end (Ctrl-C or --duration) the truth-based figures (distance, collisions, rejected commands) can be written
as JSON.
"""

import sys

from cbtc.commands import arg_types
from cbtc.commands.common import (
    add_connection_args,
    add_fleet_args,
    apply_setup,
    fleet_from_args,
    login_source,
    write_json,
)
from cbtc.live.keys import credentials
from cbtc.live.zone_match import ZoneMatch

ZONE_INFO_WAIT_S = 0.3   # for a running zone's retained info before the first tick (a later zone is heard as it comes)

EXAMPLES = (
    "cbtc trains --broker mqtt://127.0.0.1:1883 --layout itb_square --trains 2 --duration 2",
)


def register(sub):
    p = sub.add_parser("trains", help="run virtual trains against a real MQTT broker", description=__doc__)
    add_connection_args(p, setup=True)
    add_fleet_args(p)
    p.add_argument("--seed", type=arg_types.seed, default=0,
                   help="seed of the sensor noise and board clocks (default 0)")
    p.add_argument("--duration", type=arg_types.seconds, default=None,
                   help="stop after this many seconds (default: until Ctrl-C)")
    p.add_argument("--summary-json", type=arg_types.output_file, default=None, metavar="FILE",
                   help="the truth-based figures, rewritten at every status period and at exit")
    p.add_argument("--status-json", type=arg_types.output_file, default=None, metavar="FILE",
                   help="rewrite the truth-based figures into FILE at every status period")
    p.set_defaults(func=run)


def run(args):
    from cbtc.live.board_notes import BoardNotes
    from cbtc.live.loop import LiveLoop
    from cbtc.sim.truth import TruthMonitor

    apply_setup(args)
    config, keys = fleet_from_args(args, seed=args.seed)
    layout = config.layout
    loop = LiveLoop()
    trains = _connected_trains(args, config, keys, loop)
    monitor = TruthMonitor(layout, trains)
    notes = BoardNotes(trains, f"keys file {args.keys}" if args.keys else f"--sim-seed {args.sim_seed}")
    match = ZoneMatch(trains[0].client, layout, keys, notes.key_source, loop.request_stop)
    loop.pause(ZONE_INFO_WAIT_S)   # a zone already running says what it runs (retained) before a train moves
    if match.problems:
        return _mismatched(match, trains)
    start_s = loop.now_s()
    loop.scheduler.call_every(1.0, notes.check, start_s=start_s + 1.0)
    for index, train in enumerate(trains):
        loop.scheduler.call_every(config.loop_s, train.tick, start_s=start_s + 0.001 * (index + 1))
    loop.scheduler.call_every(config.loop_s, monitor.sample, start_s=start_s + 0.0105)
    loop.scheduler.call_every(args.status_period, lambda now_s: _status(monitor, args, now_s),
                              start_s=start_s + args.status_period)
    print(f"trains: {[t.train_id for t in trains]} on {layout.name}, broker {trains[0].client.host}:"
          f"{trains[0].client.port}", flush=True)
    loop.install_signal_handlers()
    loop.run(args.duration)
    if match.problems:
        return _mismatched(match, trains)
    summary = monitor.summary(loop.now_s() - start_s)
    for train in trains:
        train.client.disconnect()
    if args.summary_json:
        write_json(args.summary_json, summary)
    distances = ", ".join("%s %.2f m" % (t["train"], t["distance_m"]) for t in summary["trains"])
    print(f"trains: stopped; collisions {summary['collisions']}, distance {distances}", flush=True)
    silent = [t["train"] for t in summary["trains"] if t["cseq"] <= 0]
    if len(silent) == len(summary["trains"]):
        # not one command taken: no zone (a run of the trains alone is no error), or a zone with other keys
        print(f"cbtc trains: warning: no train took a command ({', '.join(silent)}): is `cbtc zone` running on this "
              f"broker with these trains' keys ({notes.key_source})? Start both from one `cbtc setup` folder "
              f"(--setup DIR)", file=sys.stderr)
    return 0 if summary["collisions"] == 0 else 1


def _connected_trains(args, config, keys, loop):
    """A VirtualTrain per train of the fleet, each on its own connection to the broker (user train-<id>)."""
    import numpy as np

    from cbtc.bus.broker_config import train_user
    from cbtc.bus.clients import start_bus
    from cbtc.protocol import wire
    from cbtc.sim.virtual_train import VirtualTrain

    trains = []
    try:
        for index, spec in enumerate(config.trains):
            user = train_user(spec.train_id)
            username, password = credentials(user, args.username, args.password, args.credentials)
            bus = start_bus(args.mqtt_client, args.broker, user, loop.net,
                            status_topic=wire.topic_status(spec.train_id), username=username, password=password,
                            login=login_source(args, user))
            rng = np.random.default_rng([args.seed, index])
            offset_ms = int(rng.integers(0, 10_000_000))
            trains.append(VirtualTrain(spec.train_id, keys[spec.train_id], config.layout, spec.profile, spec.s0_m,
                                       bus, rng, offset_ms))
    except Exception:
        for train in trains:
            train.client.disconnect()
        raise
    return trains


def _mismatched(match, trains) -> int:
    """2, with a line per mismatch between these trains and a zone on the broker (ZoneMatch), every train offline."""
    for train in trains:
        train.client.disconnect()
    for problem in match.problems:
        print(f"cbtc trains: error: {problem}", file=sys.stderr)
    return 2


def _status(monitor, args, now_s):
    summary = monitor.summary(now_s)
    if args.status_json:
        write_json(args.status_json, summary)
    if args.summary_json:   # kept current, so a killed run leaves its figures
        write_json(args.summary_json, summary)
    if args.quiet:
        return
    parts = [f"{t['train']} s={t['head_s_m']:.2f} v={t['v_mps']:.2f} {t['mode']} rej={t['commands_rejected_onboard']} "
             f"flt={','.join(t['faults']) or '-'}{'' if t['connected'] else ' OFFLINE'}" for t in summary["trains"]]
    print(f"t={now_s:6.1f}s | " + " | ".join(parts) + f" | collisions {summary['collisions']}", flush=True)
