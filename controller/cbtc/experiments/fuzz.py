"""`cbtc fuzz`: bad payloads thrown at a live zone controller and live virtual trains over a real Mosquitto, then
truth and the controller's own state say whether anything got through.

The paper scenario runs live (two virtual trains, each the firmware's OnboardUnit on its own MQTT connection; the
zone controller on another) while a stranger publishes `payloads` messages on the trains' report and command topics,
in two halves: between them the stranger is silent for SILENCE_S and train B reboots, so the second half's replays
come from before the silence and from B's previous boot. Classes (CLASSES):

- garbage: random bytes, broken JSON, a kilobyte of one byte, empty;
- truncated: a recorded real report or command cut short;
- forged: a recorded one with a byte of its body changed, or a valid message sealed with a wrong key;
- replayed: a recorded real one sent again;
- extreme: reports sealed with the train's own key, every field in range, most at an extreme (what a broken board
  could send), and commands sealed with the key but of another boot or an old report (what a recorder could send).

Figures: uncaught_exceptions (escaping the controller's or a board's handling), accepted_invalid (a garbage,
truncated or forged report the controller took, a report it took twice, or a command a board took that the
controller never sent),
moved_without_authority (trains that drove, motor under power, past the end of authority they held; their odometer
may also slide past it braked, in `moved_past_eoa_mm`, when a command cuts the authority behind a moving train: a
report that lies about its own odometer, sealed with the train's key, can make the controller do that, and the board
trips), controller_alive (after
the attack every train is located again, commanded in this controller's session and moving), and whether the
controller's picture stayed finite.
"""

import random
import tempfile

import numpy as np

from cbtc.bus.broker_config import MosquittoProcess
from cbtc.bus.clients import start_bus
from cbtc.bus.paho_bus import PahoBus
from cbtc.layout_files import load_layout
from cbtc.live.loop import LiveLoop
from cbtc.protocol import fast_wire, wire, wire_zc
from cbtc.sim.truth import TruthMonitor
from cbtc.sim.virtual_train import VirtualTrain
from cbtc.zone.config import paper_scenario, train_key
from cbtc.zone.factory import build_zone

CLASSES = ("garbage", "truncated", "forged", "replayed", "extreme")
WARMUP_S = 6.0          # the trains are located and running before the first bad payload
RATE_HZ = 1000.0        # bad payloads a second
SILENCE_S = 3.0         # between the halves: replays after it are of traffic this old at least
RECOVERY_S = 10.0       # after the attack: every train must be located, commanded and moving again
INT31 = 2 ** 31 - 1


class Traffic:
    """The real reports and commands seen on the broker, with their time, for truncation, forgery and replay."""

    def __init__(self, limit: int = 4000):
        self.messages = []      # (t_s, topic, payload)
        self.limit = limit
        self.now_s = lambda: 0.0
        self.skip = {}          # payloads not to record (the stranger's own)

    def record(self, topic, payload):
        payload = bytes(payload)
        if len(self.messages) < self.limit and payload not in self.skip:
            self.messages.append((self.now_s(), topic, payload))

    def pick(self, rng, before_s=None, topic_part=None):
        chosen = [m for m in self.messages if (before_s is None or m[0] <= before_s)
                  and (topic_part is None or topic_part in m[1])]
        return rng.choice(chosen) if chosen else None


def _extreme(rng, lo, hi, near=None, small=False):
    """A value in [lo, hi] at an extreme: a bound, zero, halfway, or far from `near`; with `small`, also next to it
    (for times and counters, where a step of one is the board's own; an odometer a few cm off is a fault class of
    its own, not an extreme)."""
    values = [lo, hi, 0, 1, -1, hi // 2, lo // 2]
    if near is not None:
        values += [near, near + 2 ** 29 - 1, near - 2 ** 29, near + 1000000]
        if small:
            values += [near + 1, near - 1]
    return max(lo, min(hi, rng.choice(values)))


def extreme_report(rng, key, train_id, last, session_id):
    """A report of `train_id` sealed with its key, every field in range and most at an extreme, near `last` (the
    controller's newest report of it, or None)."""
    last = last or {}
    w = wire.WRAP_MASK
    t, odo = last.get("t_ms", 0), last.get("odo_mm")
    fields = dict(
        boot=last.get("boot", 1), seq=(last.get("seq", 0) + rng.choice([1, 1, 2, 1000, 2 ** 29])) & w,
        t_ms=_extreme(rng, 0, w, t, small=True) & w, odo_mm=_extreme(rng, -INT31, INT31, odo),
        v_mmps=_extreme(rng, -20000, 20000), duty_pct=_extreme(rng, -100, 100), mode=rng.choice(wire_zc.MODES),
        cseq=_extreme(rng, -1, w), csid=rng.choice([session_id, -1, _extreme(rng, -1, INT31)]),
        ips=rng.choice([None, [_extreme(rng, 0, w, t, small=True) & w, _extreme(rng, -10 ** 6, 10 ** 6),
                               _extreme(rng, -10 ** 6, 10 ** 6)]]),
        tags=rng.choice([[], [["04A1B2C3", _extreme(rng, -INT31, INT31, odo), _extreme(rng, 0, w, t, True) & w]]]),
        faults=rng.choice([[], [], ["enc_fail"]]),
        rng=rng.choice([None, [_extreme(rng, 0, w, t, small=True) & w, _extreme(rng, -100000, 10 ** 6)]]))
    return fast_wire.encode_report(key, train_id, **fields)


def bad_payload(rng, klass, traffic, keys, last_reports, session_id, replay_before_s):
    """(topic, payload) of one bad message of `klass`."""
    train_id = rng.choice(sorted(keys))
    topic = rng.choice([wire.topic_report(train_id), wire.topic_command(train_id)])
    recorded = traffic.pick(rng, replay_before_s if klass == "replayed" else None)
    if klass in ("truncated", "forged", "replayed") and recorded is not None:
        _t, topic, payload = recorded
        if klass == "truncated":
            return topic, payload[:rng.randrange(0, len(payload))]
        if klass == "replayed":
            return topic, payload
        cut = payload.rfind(b"#")
        if rng.random() < 0.5 and cut > 0:
            i = rng.randrange(cut)
            return topic, payload[:i] + bytes([payload[i] ^ (1 << rng.randrange(8))]) + payload[i + 1:]
        body = payload[:cut] if cut > 0 else payload
        return topic, fast_wire.seal(rng.randbytes(16), topic, body)
    if klass == "extreme":
        if topic.endswith("/report"):
            return topic, extreme_report(rng, keys[train_id], train_id, last_reports.get(train_id), session_id)
        # of another boot, or resting on a report long gone (the controller's newest report of the train may be a
        # few ahead of the board's, after an extreme report it took: so 2^20 back, never 13)
        last = last_reports.get(train_id) or {"boot": 1, "seq": 0}
        boot = rng.choice([last["boot"] ^ 1 or 2, last["boot"]])
        rseq = (last["seq"] - rng.choice([0, 20, 2 ** 20] if boot != last["boot"] else [2 ** 20, 2 ** 25])) \
            & wire.WRAP_MASK
        return topic, fast_wire.encode_command(keys[train_id], train_id, boot, rng.randrange(wire.WRAP_MASK),
                                          rng.choice([session_id, rng.randrange(INT31)]), rseq, 5000, INT31, 10000,
                                          10000, 1, INT31, 20, wire.ODO_MM_PER_M_MIN)
    kind = rng.randrange(5)
    if kind == 0:
        return topic, rng.randbytes(rng.randrange(1, 1100))
    if kind == 1:
        return topic, b'{"v":1,"k":"rep","id":"' + train_id.encode() + b'","mode":"' + b"x" * 600 + b'"}#' + b"0" * 32
    if kind == 2:
        return topic, bytes([rng.randrange(256)]) * 1024
    if kind == 3:
        return topic, b""
    return topic, b"{" * rng.randrange(1, 900)


class Watch:
    """What got through: wraps the controller's report handling and the cycle, and checks the boards' commands."""

    def __init__(self, zc, trains):
        self.zc = zc
        self.trains = trains
        self.classes = {}            # bad payload -> its class
        self.uncaught = 0
        self.accepted_invalid = 0
        self.sent = {t.train_id: set() for t in trains}   # (seq, rseq, eoa_mm) of every command the zone sent
        self._invalid_seen = set()
        self._taken = set()          # (train, boot, seq) of every report the controller took
        self.drove_past_eoa_mm = [0] * len(trains)
        self._odo_mm = [None] * len(trains)
        self._eoa_mm = [0] * len(trains)
        self._driving = [False] * len(trains)
        self.examples = []           # what got through, in words (the first few)
        handle = zc.on_report
        cycle = zc.cycle
        publish = zc.client.publish

        handling = [None]   # the payload the zone is handling now

        def on_report(topic, payload):
            handling[0] = payload
            try:
                handle(topic, payload)
            except Exception:
                self.uncaught += 1
            handling[0] = None

        def took(train_id, report, _recv_s):
            # taken: never garbage, a truncation or a forgery, and never a report taken before (a replay of one the
            # controller never took, its original refused or lost, is the board's own data, late)
            klass = None if handling[0] is None else self.classes.get(bytes(handling[0]))
            taken = (train_id, report["boot"], report["seq"])
            if klass in ("garbage", "truncated", "forged") or taken in self._taken:
                self.accepted_invalid += 1
                self.examples.append(f"controller took a {klass or 'real'} report of train {train_id} "
                                     f"(boot {taken[1]} seq {taken[2]})")
            self._taken.add(taken)

        def guarded_cycle(now_s):
            try:
                cycle(now_s)
            except Exception:
                self.uncaught += 1

        def recording_publish(topic, payload, *args, **kwargs):
            if topic.endswith("/cmd"):
                msg = fast_wire.loads(payload[:payload.rfind(b"#")])   # the zone's own, sealed by it
                self.sent[topic.split("/")[2]].add((msg["seq"], msg["rseq"], msg["eoa_mm"]))
            return publish(topic, payload, *args, **kwargs)

        zc.on_report = on_report
        zc.reports.subscribe(took)
        self.cycle = guarded_cycle
        zc.client.publish = recording_publish

    def ticking(self, i):
        """Train i's tick, watched: the motion of a tick's physics step happens under the motor command and the end
        of authority the board's step left at the previous tick; counted when the motor drove beyond that end."""
        train = self.trains[i]

        def tick(now_s):
            train.tick(now_s)
            odo_mm, before_mm = train.obu.odo_mm, self._odo_mm[i]
            if before_mm is not None and odo_mm > before_mm and self._driving[i]:
                self.drove_past_eoa_mm[i] += max(0, odo_mm - max(self._eoa_mm[i], before_mm))
            self._odo_mm[i] = odo_mm
            self._eoa_mm[i] = train.obu.eoa_mm
            self._driving[i] = train.motor.mode == "drive"
        return tick

    def check_boards(self, _now_s=None):
        """Every command a board holds is one the controller sent, in its session."""
        for train in self.trains:
            cmd = train.obu.cmd
            if cmd is None:
                continue
            key = (train.train_id, train.obu.boot_id, cmd["sid"], cmd["seq"])
            if key in self._invalid_seen:
                continue
            if cmd["sid"] != self.zc.session_id or (cmd["seq"], cmd["rseq"], cmd["eoa_mm"]) not in \
                    self.sent[train.train_id]:
                self._invalid_seen.add(key)
                self.accepted_invalid += 1
                self.examples.append(f"board {train.train_id} took a command the controller never sent: "
                                     f"session {cmd['sid']} seq {cmd['seq']} rseq {cmd['rseq']}")


def run_fuzz(payloads: int, seed: int, broker_url: str = None, progress=None, client: str = "lean") -> dict:
    """Run the campaign (see the module) with the controller, the trains and the listener on MQTT client `client`
    (cbtc.bus.clients); `progress(elapsed_s, total_s, payloads_sent)` is called four times a second (it takes
    warm-up + attack + silence + recovery seconds of wall time)."""
    broker = None
    if broker_url is None:
        broker = MosquittoProcess.open_broker(tempfile.mkdtemp(prefix="cbtc-fuzz-")).start()
        broker_url = broker.url
    buses = []
    try:
        return _campaign(payloads, seed, broker_url, progress, buses, client)
    finally:
        for bus in buses:
            bus.disconnect()
        if broker is not None:
            broker.kill()


def _connect(config, keys, seed, url, client, loop, traffic, buses):
    """(the zone's bus, the virtual trains on theirs, the stranger that throws), each bus kept in `buses`; a
    listener records the traffic the replays are drawn from."""
    zc_bus = start_bus(client, url, "zc-fuzz", loop.net, status_topic=wire_zc.topic_zone_status("fuzz"))
    buses.append(zc_bus)
    trains = []
    for index, spec in enumerate(config.trains):
        bus = start_bus(client, url, "train-" + spec.train_id, loop.net, status_topic=wire.topic_status(spec.train_id))
        buses.append(bus)
        train_rng = np.random.default_rng([seed, index])
        trains.append(VirtualTrain(spec.train_id, keys[spec.train_id], config.layout, spec.profile, spec.s0_m, bus,
                                   train_rng, int(train_rng.integers(0, 10_000_000))))
    listener = start_bus(client, url, "fuzz-listener", loop.net)
    buses.append(listener)
    listener.subscribe("cbtc/train/+/report", traffic.record)
    listener.subscribe("cbtc/train/+/cmd", traffic.record)
    stranger = PahoBus(url, "stranger").start()   # paho's own thread: it throws while the loop runs
    buses.append(stranger)
    return zc_bus, trains, stranger


def _campaign(payloads, seed, url, progress, buses, client):
    layout = load_layout("itb_square")
    config = paper_scenario(layout, seed=seed, laps=1000)
    keys = {s.train_id: train_key(seed, s.train_id) for s in config.trains}
    loop = LiveLoop()
    rng = random.Random(seed)
    traffic = Traffic()
    traffic.now_s = loop.now_s
    zc_bus, trains, stranger = _connect(config, keys, seed, url, client, loop, traffic, buses)
    zc = build_zone(config, keys, zc_bus, loop.now_s, zone_id="fuzz", seed=seed)
    zc.clear_track(None, by="the fuzz run, from its truth,")   # its trains alone stand on the track
    watch = Watch(zc, trains)
    traffic.skip = watch.classes
    zc.start()
    monitor = TruthMonitor(layout, trains)
    t0 = loop.now_s()
    for index in range(len(trains)):
        loop.scheduler.call_every(config.loop_s, watch.ticking(index), start_s=t0 + 0.001 * (index + 1))
    loop.scheduler.call_every(config.loop_s, monitor.sample, start_s=t0 + 0.0105)
    loop.scheduler.call_every(config.loop_s, watch.check_boards, start_s=t0 + 0.0107)
    loop.scheduler.call_every(config.cycle_s, watch.cycle, start_s=t0 + 0.05)

    half = payloads // 2
    attack_s = payloads / RATE_HZ
    start_s = t0 + WARMUP_S
    second_s = start_s + half / RATE_HZ + SILENCE_S
    end_s = second_s + (payloads - half) / RATE_HZ
    sent = {"n": 0, "by_class": {k: 0 for k in CLASSES}}

    def throw(now_s):
        due = payloads if now_s >= end_s else (
            min(half, int((now_s - start_s) * RATE_HZ)) if now_s < second_s
            else half + int((now_s - second_s) * RATE_HZ))
        replay_before_s = None if now_s < second_s else second_s - SILENCE_S
        last_reports = {t: st.report for t, st in zc.trains.items()}
        while sent["n"] < min(due, payloads):
            klass = CLASSES[sent["n"] % len(CLASSES)]
            topic, payload = bad_payload(rng, klass, traffic, keys, last_reports, zc.session_id, replay_before_s)
            watch.classes[bytes(payload)] = klass
            stranger.publish(topic, payload)
            sent["n"] += 1
            sent["by_class"][klass] += 1

    loop.scheduler.call_every(0.01, throw, start_s=start_s)
    total_s = end_s - t0 + 0.5 + RECOVERY_S
    if progress is not None:
        loop.scheduler.call_every(0.25, lambda now_s: progress(min(now_s - t0, total_s), total_s, sent["n"]),
                                  start_s=t0)

    def reboot():
        trains[-1].reboot(loop.now_s())
        monitor.rebooted(len(trains) - 1)
        watch._odo_mm[-1] = None

    loop.scheduler.call_at(second_s - SILENCE_S / 2, reboot)
    loop.run(end_s - t0 + 0.5)
    moved_before = [t.travelled_m for t in trains]
    loop.run(RECOVERY_S)
    return _figures(zc, watch, monitor, trains, moved_before, sent, attack_s, loop, t0, seed)


def _figures(zc, watch, monitor, trains, moved_before, sent, attack_s, loop, t0, seed):
    """What a fuzz run found, once its trains have had RECOVERY_S to recover: what got through, truth, and whether
    the zone still locates, commands and moves every train."""
    now_s = loop.now_s()
    view = zc.view(now_s)
    seen = [view.train(t.train_id) for t in trains]
    located = [v.located for v in seen]
    commanded = [v.command_age_s is not None and v.command_age_s < 1.0 for v in view.trains]
    in_session = [t.obu.sid == zc.session_id for t in trains]
    moved = [t.travelled_m - m > 0.5 for t, m in zip(trains, moved_before)]
    healthy = all(v.estimate_finite for v in view.trains)
    truth = monitor.summary(now_s - t0)
    return {
        "payloads": sent["n"],
        "by_class": sent["by_class"],
        "attack_s": round(attack_s + SILENCE_S, 1),
        "uncaught_exceptions": watch.uncaught + loop.net.errors,
        "accepted_invalid": watch.accepted_invalid,
        "accepted_invalid_examples": watch.examples[:5],
        "moved_without_authority": sum(1 for mm in watch.drove_past_eoa_mm if mm > 0),
        "drove_past_eoa_mm": list(watch.drove_past_eoa_mm),
        "moved_past_eoa_mm": list(monitor.moved_past_eoa_mm),
        "collisions": truth["collisions"],
        "controller_alive": all(located) and all(commanded) and all(in_session) and all(moved) and healthy,
        "trains_located": sum(located),
        "trains_moving_after": sum(moved),
        "picture_finite": healthy,
        "trains": [{"train": t.train_id, "located": loc, "moving_after": mv, "board_mode": t.obu.mode,
                    "board_faults": list(t.obu.faults), "last_refusal": v.last_reject,
                    "odometer_jumps": v.odometer_jumps, "encoder_failures": v.encoder_failures,
                    "handling_failures": v.handling_failures}
                   for t, v, loc, mv in zip(trains, seen, located, moved)],
        "reports_refused": zc.refusals.total(),
        "commands_refused_onboard": sum(t.obu.rejected for t in trains),
        "seed": seed,
    }
