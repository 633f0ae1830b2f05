"""The shell of a live run on a real broker: wall-clock loop, keys, credentials, fleet, truth, status lines.

Shared by `cbtc zone`, `cbtc trains` and `cbtc bench`. A `LiveLoop` runs an `InboxScheduler` in the main thread:
messages that paho receives on its thread are queued in the bus `Inbox`, which wakes the scheduler; the scheduler
runs them while it waits for its next task, so they are handled at once, in the scheduler's thread, never during
a controller cycle or a train's loop. Ctrl-C (SIGINT) or SIGTERM ends the loop cleanly after the running task.
"""

import binascii
import json
import os
import secrets
import signal
import sys
import threading
import time

from cbtc.bus.paho_bus import Inbox
from cbtc.errors import ConfigError
from cbtc.firmware_modules import wire
from cbtc.scheduler import RealtimeScheduler
from cbtc.sim.simulation import paper_scenario, queue_scenario, train_key

ENV_USERNAME = "CBTC_MQTT_USERNAME"
ENV_PASSWORD = "CBTC_MQTT_PASSWORD"
KEY_BYTES = 16


class InboxScheduler(RealtimeScheduler):
    """The wall-clock scheduler (scheduler.RealtimeScheduler, unchanged in order and timing of its tasks) that,
    while waiting for the next task, runs the calls other threads put in its `inbox`, woken by each put."""

    def __init__(self, start_s: float = 0.0):
        super().__init__(start_s)
        self._woken = threading.Event()
        self.inbox = Inbox(notify=self._woken.set)

    def _wait_until(self, t_s: float) -> None:
        while True:
            self._woken.clear()
            self.inbox.drain()
            remaining_s = t_s - (time.monotonic() - self._t0)
            if remaining_s <= 0 or self._stopped:
                return
            self._woken.wait(remaining_s)


class LiveLoop:
    """An InboxScheduler and the way to run it until Ctrl-C or for a duration."""

    def __init__(self, gil_switch_s: float = 0.0005):
        # paho's network threads must get the GIL soon after a publish from this thread (default 5 ms is a
        # whole extra latency budget); a shorter switch interval costs little in a process that mostly waits
        sys.setswitchinterval(gil_switch_s)
        self.scheduler = InboxScheduler()
        self.inbox = self.scheduler.inbox
        self.stopping = False

    def now_s(self) -> float:
        return self.scheduler.now_s()

    def install_signal_handlers(self) -> None:
        """Ctrl-C and SIGTERM end `run` after the running task (no KeyboardInterrupt in the middle of a cycle)."""
        signal.signal(signal.SIGINT, self.request_stop)
        signal.signal(signal.SIGTERM, self.request_stop)

    def request_stop(self, *_signal_args) -> None:
        self.stopping = True
        self.scheduler.stop()

    def run(self, duration_s: float = None) -> None:
        """Run until stopped, or for `duration_s` seconds of wall time from now."""
        end_s = None if duration_s is None else self.now_s() + duration_s
        while not self.stopping:
            until_s = self.now_s() + 0.25
            if end_s is not None:
                if until_s >= end_s:
                    self.scheduler.run_until(end_s)
                    return
            self.scheduler.run_until(until_s)

    def pause(self, wait_s: float) -> None:
        """Keep handling messages and tasks for `wait_s` seconds, even while stopping."""
        self.stopping = False
        self.run(wait_s)


# --- keys and credentials ---------------------------------------------------------------------------------------

def new_keys(train_ids) -> dict:
    """{train_id: 32 hex characters}: a fresh random 16-byte key per train."""
    return {wire.check_train_id(t): secrets.token_bytes(KEY_BYTES).hex() for t in train_ids}


def load_keys(path: str) -> dict:
    """{train_id: key bytes} from a JSON keys file {train_id: hex key}."""
    try:
        with open(path) as fh:
            data = json.load(fh)
    except OSError as exc:
        raise ConfigError(f"keys file {path}: {exc.strerror}; "
                          f"make one with `cbtc keys new --trains A,B --out {path}`") from None
    except ValueError as exc:
        raise ConfigError(f"keys file {path} is not JSON ({exc}); make one with `cbtc keys new`") from None
    if not isinstance(data, dict) or not data:
        raise ConfigError(f"keys file {path} must be a JSON object {{train_id: hex key}} with at least one train")
    keys = {}
    for train_id, text in data.items():
        try:
            wire.check_train_id(train_id)
        except wire.WireError as exc:
            raise ConfigError(f"keys file {path}: {exc.reason}") from None
        try:
            key = binascii.unhexlify(text) if isinstance(text, str) else b""
        except (binascii.Error, ValueError):
            key = b""
        if len(key) != KEY_BYTES:
            raise ConfigError(f"keys file {path}: key of train {train_id!r} must be {2 * KEY_BYTES} hex characters "
                              f"({KEY_BYTES} bytes)")
        keys[train_id] = key
    return keys


def train_keys(train_ids, keys_path: str = None, sim_seed: int = 0) -> dict:
    """{train_id: key}: from the keys file, or derived from `sim_seed` as the simulator does (scenario.train_key)."""
    if keys_path is None:
        return {t: train_key(sim_seed, t) for t in train_ids}
    keys = load_keys(keys_path)
    missing = [t for t in train_ids if t not in keys]
    if missing:
        raise ConfigError(f"keys file {keys_path} has no key for trains {missing}; it holds {sorted(keys)}")
    return {t: keys[t] for t in train_ids}


def credentials(user: str, username: str = None, password: str = None, credentials_path: str = None):
    """(username, password) for broker user `user`: a credentials file wins, then the options, then the
    environment (CBTC_MQTT_USERNAME / CBTC_MQTT_PASSWORD); (None, None) for an open broker."""
    if credentials_path:
        from cbtc.bus.broker_config import load_credentials
        table = load_credentials(credentials_path)
        if user not in table:
            raise ConfigError(f"credentials file {credentials_path} has no user {user!r}; it holds {sorted(table)}")
        return user, table[user]
    username = username if username is not None else os.environ.get(ENV_USERNAME)
    password = password if password is not None else os.environ.get(ENV_PASSWORD)
    return username, password


# --- the fleet -----------------------------------------------------------------------------------------------------

def parse_ids(text: str) -> list:
    """'A,B' -> ['A', 'B'] (each a valid train id, no duplicates)."""
    from cbtc.bus.broker_config import checked_train_ids

    return checked_train_ids([t.strip() for t in text.split(",") if t.strip()], f"--trains {text!r}")


def fleet_config(layout, train_ids=None, count: int = None, scenario: str = "auto", seed: int = 0, **overrides):
    """The ScenarioConfig both sides of a live run share: start positions and station stops per train.

    `paper`: scenario.paper_scenario (two trains, stations main/A/B); `queue`: scenario.queue_scenario (N trains
    spread along the loop, stopping everywhere); `auto`: paper for two trains on a layout that has its stations.
    Given `train_ids`, the scenario's trains take those ids in order."""
    n = len(train_ids) if train_ids else count
    if not n or n < 1:
        raise ConfigError("give the trains: --trains A,B or --count N (N >= 1)")
    if scenario == "auto":
        names = {st.name for st in layout.stations}
        scenario = "paper" if n == 2 and {"main", "A", "B"} <= names else "queue"
    if scenario == "paper":
        if n != 2:
            raise ConfigError(f"the paper scenario has 2 trains, not {n}: use --scenario queue")
        config = paper_scenario(layout, seed=seed, **overrides)
    elif scenario == "queue":
        config = queue_scenario(layout, n, seed=seed, **overrides)
    else:
        raise ConfigError(f"unknown scenario {scenario!r}: use auto, paper or queue")
    if train_ids:
        for spec, train_id in zip(config.trains, train_ids):
            spec.train_id = train_id
    return config


# --- truth of the virtual trains ----------------------------------------------------------------------------------

class TruthMonitor:
    """Collisions counted from the trains' true positions, as scenario.Recorder counts them: a collision starts when
    a train's head enters the span of the train ahead. And how far each board's odometer ever moved past the end of
    authority it held at the time (`moved_past_eoa_mm`): an end of authority set behind a standing train (an
    estimate corrected by a few mm) is no overrun unless the train then moves."""

    def __init__(self, layout, trains):
        self.layout = layout
        self.trains = trains
        self.collisions = [0] * len(trains)
        self._inside = [False] * len(trains)
        self.moved_past_eoa_mm = [0] * len(trains)
        self._odo_mm = [None] * len(trains)

    def sample(self, _now_s=None) -> None:
        trains = self.trains
        for i, train in enumerate(trains):
            odo_mm, before_mm = train.obu.odo_mm, self._odo_mm[i]
            if before_mm is not None and odo_mm > before_mm:
                past_mm = odo_mm - max(train.obu.eoa_mm, before_mm)
                if past_mm > 0:
                    self.moved_past_eoa_mm[i] += past_mm
            self._odo_mm[i] = odo_mm
        if len(trains) < 2:
            return
        order = sorted(range(len(trains)), key=lambda i: trains[i].head_s)
        for rank, i in enumerate(order):
            ahead = trains[order[(rank + 1) % len(order)]]
            if not self.layout.closed and rank == len(order) - 1:
                continue
            inside = self.layout.ahead_m(ahead.tail_s, trains[i].head_s) <= ahead.profile.length_m
            if inside and not self._inside[i]:
                self.collisions[i] += 1
            self._inside[i] = inside

    def train_summary(self, i) -> dict:
        train = self.trains[i]
        obu = train.obu
        return {
            "train": train.train_id,
            "head_s_m": round(train.head_s, 4),
            "distance_m": round(train.travelled_m, 4),
            "laps": int(train.travelled_m // self.layout.length_m) if self.layout.closed else 0,
            "v_mps": round(train.v_mps, 4),
            "mode": obu.mode,
            "odo_mm": obu.odo_mm,
            "eoa_mm": obu.eoa_mm,
            "sid": obu.sid,
            "cseq": obu.cseq,
            "commands_rejected_onboard": obu.rejected,
            "last_reject": obu.last_reject,
            "faults": list(obu.faults),
            "collisions": self.collisions[i],
            "moved_past_eoa_mm": self.moved_past_eoa_mm[i],
            "trips": obu.trips,
            "connected": train.client.connected,
        }

    def summary(self, now_s: float) -> dict:
        trains = [self.train_summary(i) for i in range(len(self.trains))]
        return {"t_s": round(now_s, 3), "layout": self.layout.name, "trains": trains,
                "collisions": sum(self.collisions)}


def write_json(path: str, data) -> None:
    """Write `data` as JSON to `path` atomically (readers never see half a file)."""
    tmp = path + ".tmp"
    with open(tmp, "w") as fh:
        json.dump(data, fh, indent=2, sort_keys=True)
    os.replace(tmp, path)


def fmt(value, digits=2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def add_connection_args(p, broker_default=None) -> None:
    """--broker, --username, --password, --credentials: how a live command reaches the broker."""
    p.add_argument("--broker", required=broker_default is None, default=broker_default, metavar="URL",
                   help="MQTT broker, mqtt://HOST:PORT")
    p.add_argument("--username", default=None, help=f"broker user name (default: ${ENV_USERNAME})")
    p.add_argument("--password", default=None, help=f"broker password (default: ${ENV_PASSWORD})")
    p.add_argument("--credentials", default=None, metavar="FILE",
                   help="credentials.json from `cbtc broker config`: each client logs in as its own user")


def add_fleet_args(p) -> None:
    """--layout, --trains/--count, --scenario, --keys/--sim-seed: which trains, where, with which keys."""
    p.add_argument("--layout", required=True, help="layout file or packaged name, e.g. itb_square")
    p.add_argument("--trains", default=None, metavar="IDS", help="train ids, e.g. A,B")
    p.add_argument("--count", type=int, default=None, help="number of trains (ids from the scenario), default 2")
    p.add_argument("--scenario", choices=("auto", "paper", "queue"), default="auto",
                   help="start positions and stops: paper (2 trains, stations main/A/B) or queue; auto picks paper "
                        "when it fits")
    p.add_argument("--keys", default=None, metavar="FILE", help="JSON keys file {train_id: hex key} (cbtc keys new)")
    p.add_argument("--sim-seed", type=int, default=0,
                   help="without --keys: derive the keys as the simulator does from this seed (default 0)")
    p.add_argument("--status-period", type=float, default=1.0, help="seconds between status lines (default 1)")
    p.add_argument("--quiet", action="store_true", help="no status lines")


def fleet_from_args(args, layout, seed: int = 0):
    """(ScenarioConfig, {train_id: key}) from the fleet options."""
    ids = parse_ids(args.trains) if args.trains else None
    count = args.count if args.count is not None else (None if ids else 2)
    config = fleet_config(layout, ids, count, args.scenario, seed=seed)
    train_ids = [spec.train_id for spec in config.trains]
    return config, train_keys(train_ids, args.keys, args.sim_seed)
