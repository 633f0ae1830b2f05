"""`cbtc zone`: the zone controller on a real MQTT broker, on the wall clock.

It subscribes to every configured train's reports, runs its 10 Hz cycle and publishes sealed commands; it prints a
status table per second (a row per train, at most 100 columns, a legend first). Ctrl-C stops it cleanly: every train
is first commanded to stop (speed 0, authority at its braking distance), then, half a second later, the controller
publishes its retained `offline` status and leaves.
"""

import secrets
import sys
import textwrap

from cbtc.authority.policy import policy_names
from cbtc.commands import arg_types
from cbtc.commands.common import (
    ReportRecording,
    add_connection_args,
    add_fleet_args,
    apply_setup,
    fleet_from_args,
    fmt,
    login_source,
    write_json,
)
from cbtc.live.keys import credentials

STOP_GRACE_S = 0.5


EXAMPLES = (
    "cbtc zone --broker mqtt://127.0.0.1:1883 --layout itb_square --trains 2 --duration 2 --status-json zone.json",
    "cbtc zone --broker mqtt://127.0.0.1:1883 --scenario lego_oval_mixed --duration 2 --quiet",
)


def register(sub):
    p = sub.add_parser("zone", help="run the zone controller against a real MQTT broker", description=__doc__)
    add_connection_args(p, setup=True)
    add_fleet_args(p)
    p.add_argument("--zone-id", type=arg_types.zone_id, default="zc1",
                   help="zone id in cbtc/zc/<id>/status and /info (default zc1)")
    p.add_argument("--policy", choices=policy_names(), default=None,
                   help="authority policy (default: moving_block, or the scenario's)")
    p.add_argument("--estimator", choices=("ukf", "odometry"), default=None,
                   help="position estimator (default: ukf, or the scenario's)")
    p.add_argument("--seed", type=arg_types.seed, default=None,
                   help="seed of the session id and dwell times (default: random, so a restart is a new session)")
    p.add_argument("--duration", type=arg_types.seconds, default=None,
                   help="stop after this many seconds (default: until Ctrl-C)")
    p.add_argument("--report-budget-hz", type=arg_types.number(above=0.0, example="400"), default=400.0, metavar="HZ",
                   help="reports a second this machine can answer (default 400: 20 trains at 20 Hz on two cores, "
                        "cbtc bench latency); followed trains are asked for 50 Hz reports within it")
    p.add_argument("--clear-track", type=arg_types.track_spans, default=None, metavar="all|FROM-TO,...",
                   help="you have looked at the table: no vehicle but this zone's trains stands on the whole track "
                        "(all) or on these stretches (metres along it); track neither cleared nor swept by a located "
                        "train is occupied, and no authority reaches into it (default: none cleared)")
    p.add_argument("--ips-modem", default=None, metavar="PORT",
                   help="the IPS modem's serial port (e.g. /dev/ttyACM0): the fixes of each train's tail beacon check "
                        "its configured length (with --tail-beacons)")
    p.add_argument("--tail-beacons", type=arg_types.tail_beacons, default=None, metavar="TRAIN=ADDRESS,...",
                   help="the beacon on each train's last car, by its address (e.g. A=5,B=6); those trains' tails are "
                        "not vouched for until their beacon is heard")
    p.add_argument("--summary-json", type=arg_types.output_file, default=None, metavar="FILE",
                   help="the controller's figures, rewritten at every status period and at exit")
    p.add_argument("--record", type=arg_types.output_file, default=None, metavar="FILE",
                   help="write every accepted report as a JSON line (what cbtc calibrate reads)")
    p.add_argument("--status-json", type=arg_types.output_file, default=None, metavar="FILE",
                   help="every train's position, speed, end of authority, data age, stale flag and faults, rewritten "
                        "(atomically) at every status period")
    p.set_defaults(func=run)


def run(args):
    from cbtc.bus.clients import start_bus
    from cbtc.live.loop import LiveLoop
    from cbtc.protocol import wire_zc
    from cbtc.zone.factory import build_zone

    apply_setup(args)
    seed = secrets.randbits(31) if args.seed is None else args.seed
    config, keys = fleet_from_args(args)
    layout = config.layout
    config.policy = args.policy or config.policy
    config.estimator = args.estimator or config.estimator
    _check_spans(args.clear_track, layout)
    beacons = _tail_beacons(args, config)
    username, password = credentials("zc", args.username, args.password, args.credentials)
    loop = LiveLoop()
    modem = None
    if beacons:   # the port opened before any connection: a wrong one is said at once
        from cbtc.live.ips_modem import IpsModem
        latency_s = max(spec.profile.ips_latency_s for spec in config.trains)
        modem = IpsModem.open(args.ips_modem, beacons, None, loop.now_s, latency_s)
    bus = start_bus(args.mqtt_client, args.broker, f"zc-{args.zone_id}", loop.net,
                    status_topic=wire_zc.topic_zone_status(args.zone_id), username=username, password=password,
                    login=login_source(args, "zc"))
    zc = build_zone(config, keys, bus, loop.now_s, zone_id=args.zone_id, seed=seed,
                    report_budget_hz=args.report_budget_hz)
    if modem is not None:
        from cbtc.live.ips_modem import POLL_S
        modem.zone = zc
        loop.scheduler.call_every(POLL_S, modem.poll, start_s=loop.now_s() + POLL_S)
    zc.key_source = f"keys file {args.keys}" if args.keys else \
        f"--sim-seed {args.sim_seed} (the keys cbtc trains derives from that seed)"
    if args.clear_track is not None:
        zc.clear_track(None if args.clear_track == "all" else args.clear_track, by="the operator (--clear-track)")
    recording = None
    if args.record:
        recording = ReportRecording(args.record)
        zc.reports.subscribe(recording)
    zc.start()
    _publish_info(bus, args.zone_id, zc.session_id, layout, keys)
    cycle = loop.scheduler.call_every(config.cycle_s, zc.cycle, start_s=loop.now_s() + 0.05)
    zc.views.subscribe(lambda view: _status(view, bus, loop, args))
    loop.scheduler.call_every(args.status_period, zc.publish_view, start_s=loop.now_s() + args.status_period)
    ids = [spec.train_id for spec in config.trains]
    print(f"zone {args.zone_id}: {len(ids)} trains {ids} on {layout.name}, broker "
          f"{bus.host}:{bus.port}, session {zc.session_id}", flush=True)
    if not args.quiet:
        print(textwrap.fill(STATUS_LEGEND, 100), flush=True)
    loop.install_signal_handlers()
    loop.run(args.duration)
    return _shut_down(args, zc, bus, loop, cycle, modem, recording)


def _shut_down(args, zc, bus, loop, cycle, modem, recording):
    """No more cycles or event-driven answers that could extend an authority; every train stopped; the zone offline,
    the recording closed and the summary written."""
    from cbtc.protocol import wire_zc

    cycle.cancel()
    bus.unsubscribe(wire_zc.REPORT_FILTER)
    zc.stop_all(loop.now_s())
    bus.publish(wire_zc.topic_zone_info(args.zone_id), b"", retain=True, qos=1)   # cleared: no zone runs here now
    loop.pause(STOP_GRACE_S)
    bus.disconnect()
    if modem is not None:
        modem.close()
    summary = _summary(zc.view(loop.now_s()), bus, loop)
    if recording is not None:
        recording.close()
        print(f"zone {args.zone_id}: {recording.lines} reports recorded in {args.record}", flush=True)
    if args.summary_json:
        write_json(args.summary_json, summary)
    print(f"zone {args.zone_id}: stopped every train and went offline after {summary['cycles']} cycles", flush=True)
    return _unauthenticated(zc, summary)


def _publish_info(bus, zone_id, session_id, layout, keys):
    """The zone's retained info (protocol version, layout, a check of each train's key): a trains process started
    beside it refuses to run on another version, layout or keys (cbtc.protocol.zone_info)."""
    from cbtc.protocol import wire_zc, zone_info

    payload = zone_info.encode_info(zone_id, session_id, layout.name, layout.digest(), keys)
    bus.publish(wire_zc.topic_zone_info(zone_id), payload, retain=True, qos=1)


def _unauthenticated(zc, summary) -> int:
    """1, with one line each, when a train whose reports came never sent one the zone could take because its key is
    not the zone's, or its board speaks another protocol version; 0 otherwise. The zone ran on regardless: a wrong
    key may be a stranger's, not a board's."""
    from cbtc.protocol import wire

    def never(klass):
        return [t for t, row in summary["trains"].items()
                if row["data_age_s"] is None and summary["refusals"].get(f"{t}/{klass}")]

    def trains(ids):
        return f"train{'s' if len(ids) > 1 else ''} {', '.join(ids)}"

    wrong, other = never("wrong key"), never("other version")
    if wrong:
        print(f"cbtc zone: error: {trains(wrong)} reported, but never with a report this zone could authenticate: "
              f"its keys ({zc.key_source}) are not the boards'; give both the same keys (one `cbtc setup` folder, "
              f"--setup DIR, or the same --keys FILE)", file=sys.stderr)
    if other:
        print(f"cbtc zone: error: {trains(other)} reported, but in another protocol version than this zone's "
              f"({wire.VERSION}): flash the boards with this version's firmware (cbtc flash), or run trains and "
              f"zone from one install", file=sys.stderr)
    return 1 if wrong or other else 0


def _tail_beacons(args, config):
    """--ips-modem and --tail-beacons, checked together and against the fleet: {address: train id} ({} without
    them); the trains given a beacon get `tail_beacon` in their profile (unvouched tails until heard)."""
    from dataclasses import replace

    from cbtc.errors import ConfigError
    if (args.ips_modem is None) != (args.tail_beacons is None):
        raise ConfigError("--ips-modem and --tail-beacons go together: give the modem's port and which beacon rides "
                          "on which train's last car (e.g. --ips-modem /dev/ttyACM0 --tail-beacons A=5)")
    if args.ips_modem is None:
        return {}
    beacons = args.tail_beacons
    ids = [spec.train_id for spec in config.trains]
    unknown = sorted(set(beacons.values()) - set(ids))
    if unknown:
        raise ConfigError(f"--tail-beacons: train {', '.join(unknown)} is not in this zone; its trains: "
                          f"{', '.join(ids)}")
    fitted = set(beacons.values())
    config.trains = [replace(spec, profile=spec.profile.with_changes(tail_beacon=1)) if spec.train_id in fitted
                     else spec for spec in config.trains]
    return beacons


def _check_spans(spans, layout):
    """--clear-track's stretches lie on `layout` (ConfigError naming the stretch and the track's length)."""
    from cbtc.errors import ConfigError
    for from_m, to_m in spans if isinstance(spans, list) else ():
        if max(from_m, to_m) > layout.length_m or (not layout.closed and to_m < from_m):
            raise ConfigError(f"--clear-track {from_m:g}-{to_m:g}: not on layout {layout.name}, whose track runs "
                              f"from 0 to {layout.length_m:.2f} m" + ("" if layout.closed else
                                                                     " forward (FROM below TO)"))


def _status(view, bus, loop, args):
    """Each ZoneView the zone publishes (every status period): the status table, and the status and summary files (a
    kill loses at most one period)."""
    if args.status_json:
        write_json(args.status_json, {"zone_id": view.zone_id, "session_id": view.session_id,
                                      "t_s": round(view.t_s, 3), "broker_connected": bus.connected,
                                      "trains": view.status()})
    if args.summary_json:
        write_json(args.summary_json, _summary(view, bus, loop))
    if not args.quiet:
        print("\n".join(status_table(view, bus.connected)), flush=True)


STATUS_LEGEND = ("status, a row per train: s = head position along the track (m), v = speed (m/s), limit = end of "
                 "authority on the track (m), data = age of its newest report (s; STALE: older than the zone "
                 "accepts, figures as last heard), mode = the board's, next = next stop, authority = what limits "
                 "it (held: why it has none), notes = the board's faults and the zone's doubts")
STATUS_COLUMNS = (("train", 6, "<"), ("s m", 6, ">"), ("v m/s", 6, ">"), ("limit m", 7, ">"), ("data s", 9, ">"),
                  ("mode", 5, "<"), ("next", 6, "<"), ("authority", 30, "<"), ("notes", 17, "<"))   # 100 columns


def status_table(view, broker_up):
    """The status of a ZoneView as lines of at most 100 characters: a heading, then a row per train
    (STATUS_LEGEND)."""
    lines = [f"t={view.t_s:.1f} s, broker {'up' if broker_up else 'DOWN'}",
             " ".join(_cell(name, width, align) for name, width, align in STATUS_COLUMNS).rstrip()]
    for row in view.trains:
        age = row.data_age_s
        data = "-" if age is None else (f"{age:.1f} STALE" if row.stale else f"{age:.2f}")
        notes = list(row.faults)
        if row.ahead_m or row.behind_m:   # its sensors disagree: the authority covers both stories
            notes.append(f"doubt-{row.behind_m:.2f}+{row.ahead_m:.2f}")
        if row.speed_steps:   # the wheel's scale was re-opened: it slipped or spun
            notes.append(f"slip x{row.speed_steps}")
        v_mps = row.v_mps
        if v_mps is not None and abs(v_mps) < 0.005:
            v_mps = 0.0   # standing: not "-0.00"
        cells = (row.train_id, fmt(row.s_m), fmt(v_mps), fmt(row.limit_s_m), data,
                 row.mode or "-", row.next_stop or "-", row.limited_by or "-", ",".join(notes) or "-")
        lines += _row(cells)
    return lines


def _row(cells):
    """A row's lines: a cell wider than its column wraps at its spaces (or its commas) onto lines below, never cut."""
    import textwrap

    wrapped = [textwrap.wrap(str(value).replace(",", ", "), width, break_on_hyphens=False) or [""]
               for value, (_name, width, _align) in zip(cells, STATUS_COLUMNS)]
    wrapped = [[part.replace(", ", ",") for part in parts] for parts in wrapped]
    return [" ".join(_cell(parts[i] if i < len(parts) else "", width, align)
                     for parts, (_name, width, align) in zip(wrapped, STATUS_COLUMNS)).rstrip()
            for i in range(max(len(parts) for parts in wrapped))]


def _cell(text, width, align):
    return text.ljust(width) if align == "<" else text.rjust(width)


def _summary(view, bus, loop):
    """The `--summary-json` of a ZoneView, with the broker's and the network loop's counts."""
    return {**view.summary(), "broker_connects": bus.connects, "broker_losses": bus.losses,
            "callback_errors": loop.net.errors}
