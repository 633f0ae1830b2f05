"""Latency of the live system: report -> command round trips through a real MQTT broker, and the controller's
compute time.

The zone controller runs in this process, N virtual trains in child ones (each train its own MQTT connection,
reporting at `--rate`, the board's 20 Hz by default, or 50 Hz when the controller asks a followed train for fast
reports within its report budget; report phases spread over the period as independent boards have them), all through
the broker on the wall clock; `--broker embedded` starts a private Mosquitto on a free loopback port. Then, on the same
broker, the reference: a raw paho ping-pong with as many clients at the same rate (experiments/ping_pong.py).
What the controller does: it answers a train's report in its next 10 Hz cycle (the command carries that report's
seq as `rseq`), and it also answers a report at once by extending the authority of the train behind. So the figures:

  transport_rtt    report published -> received by the controller, plus command published -> received by the train
                   (the two trips through the broker and both MQTT stacks, the cycle wait left out)
  answer_wait      report received -> command for that report published (compute; plus the wait for a cycle when
                   the controller is not event-driven)
  report_to_cmd    report published -> command for that report received by the train (the sum: what a train sees)
  event_answer     report of a train published -> the command it triggered for the train behind received
  cycle_compute    one controller cycle (all trains), on_report_compute: handling one report
  reports_dropped  published in the window and never received by the controller; reports_unanswered: never answered
  controller_cpu_core_share   the controller process's CPU time over the window (its bus and these probes' time-keeping
                   included) per wall second: 1.0 is a whole core
  reference        the ping-pong's round trip, lost pings and answering CPU; p50/p99_over_reference: ours over it

All times in ms, p50 and p99, from time.monotonic(), which on Linux is CLOCK_MONOTONIC and so one clock for both
processes. A message is timed when the receiving side's handler starts, so waiting in the receiver's queue counts.
The first `--warmup` seconds are left out.
"""

import math
import multiprocessing
import re
import resource
import tempfile
import time

import numpy as np

import cbtc
from cbtc.bus.broker_config import MosquittoProcess
from cbtc.bus.clients import start_bus
from cbtc.errors import BusError
from cbtc.experiments.ping_pong import ping_pong
from cbtc.layout_files import load_layout
from cbtc.live.loop import LiveLoop
from cbtc.protocol import wire, wire_zc
from cbtc.railway.layout_dict import layout_from_dict
from cbtc.sim.virtual_train import VirtualTrain
from cbtc.zone.config import queue_scenario, train_key
from cbtc.zone.factory import build_zone

STRAIGHT_M = 0.128        # LEGO straight, 16 studs
CURVES_M = 2 * math.pi * 0.32
ROOM_PER_TRAIN_M = 0.55   # train length + safety margin + slack for queue_scenario
TAIL_S = 0.3              # run on after the window so its last commands arrive


def bench_oval(n_trains: int):
    """A LEGO oval (straights and R40 curves) with room for `n_trains` trains following each other."""
    sides = max(4, math.ceil((n_trains * ROOM_PER_TRAIN_M - CURVES_M) / (2 * STRAIGHT_M)))
    side_m = sides * STRAIGHT_M
    return layout_from_dict({
        "name": f"bench_oval_{n_trains}", "closed": True,
        "segments": [{"piece": "straight", "count": sides}, {"piece": "curve_r40", "turn": "left", "count": 8},
                     {"piece": "straight", "count": sides}, {"piece": "curve_r40", "turn": "left", "count": 8}],
        "ips": {"beacons": [[0.0, 0.0, 1.2], [side_m, 0.0, 1.2], [side_m, 0.64, 1.2], [0.0, 0.64, 1.2]]},
    }, source="bench oval")


_SEQ = re.compile(rb'"seq":(\d+)')
_RSEQ = re.compile(rb'"rseq":(\d+)')
_ID = re.compile(rb'"id":"([^"]+)"')


def _seq(payload) -> int:
    """The `seq` of a sealed report or command, read off its JSON without decoding it all: the probes must cost the
    controller's process as little as they can, since its CPU time is one of the figures."""
    return int(_SEQ.search(payload).group(1))


def _command_keys(payload):
    """(train id, seq, rseq) of a sealed command."""
    return _ID.search(payload).group(1).decode(), _seq(payload), int(_RSEQ.search(payload).group(1))


class TrainProbe:
    """Trains' side: when each report was published and each command reached the train's handler."""

    def __init__(self):
        self.report_pub = {}     # (train, seq) -> t
        self.cmd_recv = {}       # (train, cmd seq) -> t

    def wrap(self, bus, train_id):
        publish, subscribe = bus.publish, bus.subscribe

        def probed_publish(topic, payload, retain=False, qos=0):
            if topic.endswith("/report"):
                self.report_pub[(train_id, _seq(payload))] = time.monotonic()
            publish(topic, payload, retain, qos)

        def probed_subscribe(topic_filter, callback):
            def on_message(topic, payload):
                self.cmd_recv[(train_id, _seq(payload))] = time.monotonic()
                callback(topic, payload)
            subscribe(topic_filter, on_message)

        bus.publish, bus.subscribe = probed_publish, probed_subscribe
        return bus


class ZcProbe:
    """Controller's side: report arrivals, command departures (with the report that triggered an event-driven one),
    compute times of cycles and of report handling. While the controller runs it only keeps times and the raw
    messages (its CPU time is one of the figures); `decode` reads their keys afterwards."""

    def __init__(self):
        self.report_recv = {}    # (train, seq) -> t
        self.cmd_pub = {}        # (train, cmd seq) -> (t, rseq, trigger (train, seq) or None)
        self.cycles = []         # (t, compute s)
        self.on_report = []      # (t, compute s)
        self._reports = []       # (t, topic, payload) as received
        self._commands = []      # (t, payload, index in _reports of the report being handled, or -1)
        self._trigger = -1

    def wrap(self, bus):
        publish, subscribe = bus.publish, bus.subscribe
        reports, commands, clock = self._reports, self._commands, time.monotonic

        def probed_publish(topic, payload, retain=False, qos=0):
            if topic.endswith("/cmd"):
                commands.append((clock(), payload, self._trigger))
            publish(topic, payload, retain, qos)

        def probed_subscribe(topic_filter, callback):
            def on_message(topic, payload):
                t0 = clock()
                self._trigger = len(reports)
                reports.append((t0, topic, payload))
                callback(topic, payload)
                self._trigger = -1
                self.on_report.append((t0, clock() - t0))
            subscribe(topic_filter, on_message)

        bus.publish, bus.subscribe = probed_publish, probed_subscribe
        return bus

    def decode(self):
        """Fill `report_recv` and `cmd_pub` from the raw messages kept."""
        keys = []
        for t, topic, payload in self._reports:
            key = (wire.train_id_of(topic), _seq(payload))
            keys.append(key)
            self.report_recv[key] = t
        for t, payload, trigger in self._commands:
            train_id, seq, rseq = _command_keys(payload)
            self.cmd_pub[(train_id, seq)] = (t, rseq, keys[trigger] if trigger >= 0 else None)

    def timed_cycle(self, zc):
        def cycle(now_s):
            t0 = time.monotonic()
            zc.cycle(now_s)
            self.cycles.append((t0, time.monotonic() - t0))
        return cycle


def figures(zc: ZcProbe, report_pub: dict, cmd_recv: dict, t0: float, t1: float) -> dict:
    """The latency and compute figures of reports published in [t0, t1] (monotonic seconds)."""
    up, down, transport, wait, total, event = [], [], [], [], [], []
    answered = set()
    for (train_id, cseq), (t_pub, rseq, trigger) in zc.cmd_pub.items():
        t_recv = cmd_recv.get((train_id, cseq))
        if trigger is not None and trigger != (train_id, rseq):
            if t_recv is not None and t0 <= report_pub.get(trigger, -1.0) <= t1:
                event.append(t_recv - report_pub[trigger])
            continue
        key = (train_id, rseq)
        if not (t0 <= report_pub.get(key, -1.0) <= t1) or key not in zc.report_recv:
            continue
        answered.add(key)
        if t_recv is None:
            continue
        up.append(zc.report_recv[key] - report_pub[key])
        down.append(t_recv - t_pub)
        transport.append(up[-1] + down[-1])
        wait.append(t_pub - zc.report_recv[key])
        total.append(t_recv - report_pub[key])
    published = [k for k, t in report_pub.items() if t0 <= t <= t1]
    return {
        "transport_rtt_ms": stats_ms(transport), "uplink_ms": stats_ms(up), "downlink_ms": stats_ms(down),
        "answer_wait_ms": stats_ms(wait), "report_to_cmd_ms": stats_ms(total), "event_answer_ms": stats_ms(event),
        "cycle_compute_ms": stats_ms([c for t, c in zc.cycles if t0 <= t <= t1]),
        "on_report_compute_ms": stats_ms([c for t, c in zc.on_report if t0 <= t <= t1]),
        "reports_published": len(published), "reports_received": sum(1 for k in published if k in zc.report_recv),
        "reports_answered": sum(1 for k in published if k in answered),
    }


def stats_ms(values_s):
    """n, p50, p99 and max of durations in seconds, in ms."""
    if not values_s:
        return {"n": 0, "p50": None, "p99": None, "max": None}
    arr = np.asarray(values_s) * 1000.0
    return {"n": int(arr.size), "p50": round(float(np.percentile(arr, 50)), 3),
            "p99": round(float(np.percentile(arr, 99)), 3), "max": round(float(arr.max()), 3)}


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _fleet(layout_name, n_trains, seed):
    layout = load_layout(layout_name) if layout_name else bench_oval(n_trains)
    return layout, queue_scenario(layout, n_trains, seed=seed)


def run_latency(args) -> dict:
    """The figures of one latency measurement (the options of `cbtc bench latency`), on an embedded broker or
    `args.broker`."""
    layout, config = _fleet(args.layout, args.trains, args.seed)
    broker = None
    if args.broker == "embedded":
        broker = MosquittoProcess.open_broker(tempfile.mkdtemp(prefix="cbtc-bench-")).start()
        url = broker.url
    else:
        url = args.broker
    try:
        result = _measure(args, layout, config, url)
        reference = ping_pong(url, args.trains, args.rate, args.duration, args.warmup, args.train_procs)
    finally:
        if broker is not None:
            broker.kill()
    result["reports_dropped"] = result["reports_published"] - result["reports_received"]
    result["reports_unanswered"] = result["reports_published"] - result["reports_answered"]
    ours, ref = result["report_to_cmd_ms"], reference["round_trip_ms"]
    result.update({"broker": "embedded mosquitto" if broker is not None else url, "trains": args.trains,
                   "layout": layout.name, "duration_s": args.duration, "rate_hz": args.rate,
                   "mqtt_client": getattr(args, "mqtt_client", "lean"),
                   "compiled_modules": len(cbtc.compiled_modules()),   # the zone's build (0: plain Python)
                   # measured: the rate asked, or 50 Hz from a followed train within the controller's report budget
                   "report_hz": round(result["reports_published"] / (args.duration * args.trains), 1),
                   "controller_cycle_hz": round(1.0 / config.cycle_s, 3),
                   "reference": reference,
                   "p99_over_reference": _ratio(ours["p99"], ref["p99"]),
                   "p50_over_reference": _ratio(ours["p50"], ref["p50"])})
    return result


def _ratio(a, b):
    return None if a is None or not b else round(a / b, 2)


def _measure(args, layout, config, url):
    loop = LiveLoop()
    probe = ZcProbe()
    keys = {s.train_id: train_key(args.seed, s.train_id) for s in config.trains}
    client = getattr(args, "mqtt_client", "lean")
    zc_bus = start_bus(client, url, "zc-bench", loop.net, status_topic=wire_zc.topic_zone_status("bench"))
    ctx = multiprocessing.get_context("spawn")
    groups = [list(range(k, args.trains, args.train_procs)) for k in range(min(args.train_procs, args.trains))]
    pipes, children = [], []
    for group in groups:
        here, there = ctx.Pipe()
        child = ctx.Process(target=_trains_side, daemon=True,
                            args=(there, url, args.layout, args.trains, group, args.seed, args.rate, client))
        child.start()
        pipes.append(here)
        children.append(child)
    report_pub, cmd_recv, moving = {}, {}, 0
    try:
        zc = build_zone(config, keys, probe.wrap(zc_bus), loop.now_s, zone_id="bench", seed=args.seed)
        zc.clear_track(None, by="the bench, from its truth,")   # its trains alone stand on the track
        zc.start()
        for here in pipes:
            ready = here.recv() if here.poll(30.0) else "no answer within 30 s"
            if ready != "ready":
                raise BusError(f"bench: a trains process failed: {ready}")
        t0 = time.monotonic() + args.warmup
        t1 = t0 + args.duration
        for here in pipes:
            here.send((t0, t1))
        loop.scheduler.call_every(config.cycle_s, probe.timed_cycle(zc), start_s=loop.now_s() + 0.05)
        cpu_s = []    # this process's CPU time (the controller, its bus and the probes) at t0 and at t1
        for t_s in (t0, t1):
            loop.scheduler.call_at(loop.now_s() + t_s - time.monotonic(), lambda: cpu_s.append(_cpu_s()))
        loop.install_signal_handlers()
        loop.run(t1 + TAIL_S - time.monotonic())
        for here in pipes:
            if not here.poll(10.0):
                raise BusError("bench: a trains process sent no results")
            pub, recv, n_moving = here.recv()
            report_pub.update(pub)
            cmd_recv.update(recv)
            moving += n_moving
    finally:
        zc_bus.disconnect()
        for child in children:
            child.join(5.0)
            if child.is_alive():
                child.kill()
    probe.decode()
    result = figures(probe, report_pub, cmd_recv, t0, t1)
    result["moving_trains"] = moving
    result["controller_cpu_core_share"] = round((cpu_s[1] - cpu_s[0]) / args.duration, 3) if len(cpu_s) == 2 else None
    return result


def _trains_side(conn, url, layout_name, n_trains, indices, seed, rate_hz, client):
    """A trains process: the virtual trains `indices` of the fleet, with probes; sends its timestamps to `conn`."""
    buses = []
    try:
        layout, config = _fleet(layout_name, n_trains, seed)
        loop = LiveLoop()
        probe = TrainProbe()
        trains = []
        for index in indices:
            spec = config.trains[index]
            bus = start_bus(client, url, f"train-{spec.train_id}", loop.net,
                            status_topic=wire.topic_status(spec.train_id))
            buses.append(bus)
            rng = np.random.default_rng([seed, index])
            offset_ms = int(rng.integers(0, 10_000_000))
            trains.append(VirtualTrain(spec.train_id, train_key(seed, spec.train_id), layout, spec.profile,
                                       spec.s0_m, probe.wrap(bus, spec.train_id), rng, offset_ms,
                                       obu_overrides={"report_ms": round(1000.0 / rate_hz)}))
        conn.send("ready")
        _t0, t1 = conn.recv()
        start_s = loop.now_s()
        for index, train in zip(indices, trains):
            # independent boards: report phases spread over the report period, not all at once
            loop.scheduler.call_every(config.loop_s, train.tick, start_s=start_s + index / (rate_hz * n_trains))
        loop.run(t1 + TAIL_S - time.monotonic())
        conn.send((probe.report_pub, probe.cmd_recv, sum(1 for t in trains if t.travelled_m > 0.05)))
    except Exception as exc:  # report to the parent instead of dying silently
        conn.send(f"{type(exc).__name__}: {exc}")
    finally:
        for bus in buses:
            bus.disconnect()
