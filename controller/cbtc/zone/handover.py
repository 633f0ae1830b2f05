"""A train's state as a value: what another zone controller needs to take the train over, exported by one zone and
imported by another (or by the same zone after a restart). The indexes (ranks, heaps, fast-report slots) stay each
zone's own.

The record holds the board's boot and the reports it has left behind (so the importing zone refuses their replays as
the exporting one did), the newest report's sequence and odometer, the position envelope (head, 1-sigma, how far
ahead and behind the sensors' disagreement reaches, whether two references confirmed it), the encoder's learnt scale,
the command the board holds (its end of authority, which the importing zone never extends from stale data) and the
stop plan. Times are kept as ages, so zones whose clocks differ can hand a train on. The importing zone takes the
envelope, carried forward by the odometer to its first report of the train, as a declared position: the train's own
placement there is confirmed when it agrees (cbtc.estimation.ukf_estimator.UkfEstimator.declare_position).
"""

from dataclasses import asdict, dataclass

from cbtc.errors import ConfigError

_CARRY_SHARE = 0.05   # of the odometer's travel since the export, added to the envelope: the scale's doubt
_CARRY_FLOOR_M = 0.02  # and this, for the rest (m)


@dataclass(frozen=True, slots=True)
class TrainRecord:
    train_id: str
    boot: int | None             # the board's boot id (None: never heard)
    report_seq: int | None       # the newest report taken of that boot
    left_boots: tuple            # boots the train has left: their reports are replays
    odo_mm: int | None           # the odometer of the newest report taken
    s_m: float | None            # estimated head position at the export (None: not located)
    sigma_s_m: float | None
    ahead_m: float               # how much further ahead / behind the head may be: the sensors' disagreement
    behind_m: float
    confirmed: bool              # placed on two independent references
    odometer_per_m: float | None  # the encoder's learnt scale (odometer m per true m)
    command: tuple | None        # the newest command sent (records.Command fields, in the table's order)
    cmd_seq: int
    next_stop: str | None
    leaving: str | None          # the station whose dwell just ended, until the train is past it
    dwell_left_s: float | None   # how much of its dwell was left at the export
    dwells: int

    def as_dict(self) -> dict:
        """JSON-ready: what a zone would send another."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "TrainRecord":
        """The record of `as_dict`; ConfigError naming what is missing or unknown."""
        names = set(cls.__dataclass_fields__)
        if not isinstance(data, dict) or set(data) != names:
            got = set(data) if isinstance(data, dict) else set()
            raise ConfigError(f"a train record needs exactly the fields {', '.join(sorted(names))}; missing: "
                              f"{', '.join(sorted(names - got)) or 'none'}, unknown: "
                              f"{', '.join(sorted(got - names)) or 'none'}")
        values = dict(data, left_boots=tuple(data["left_boots"]),
                      command=None if data["command"] is None else tuple(data["command"]))
        return cls(**values)


def export_train(state, now_s: float) -> TrainRecord:
    """The record of zone state `state` (a TrainState) at `now_s`."""
    est = state.newest_estimate() if state.report is not None and state.estimator.localized else None
    dwell_left_s = None if state.dwell_until_s is None else max(0.0, state.dwell_until_s - now_s)
    return TrainRecord(
        state.train_id, state.boots.boot, state.boots.last_seq, tuple(state.boots.left),
        None if state.report is None else state.report["odo_mm"],
        None if est is None else est.s_m, None if est is None else est.sigma_s_m,
        0.0 if est is None else est.ahead_m, 0.0 if est is None else est.behind_m,
        est is not None and state.estimator.confirmed,
        None if est is None else state.odometer_per_m_low(0.0),
        None if state.command is None else tuple(state.command), state.cmd_seq,
        state.next_stop, state.leaving, dwell_left_s, state.dwells)


def import_train(state, record: TrainRecord, now_s: float, command_type) -> None:
    """Zone state `state` takes `record` over at `now_s`: the boots and their replays, the sequence, the command
    held, the plan; the position waits for the train's first report here (declare_handed)."""
    if record.train_id != state.train_id:
        raise ConfigError(f"the record of train {record.train_id} cannot be taken as train {state.train_id}")
    boots = state.boots
    boots.boot, boots.last_seq, boots.left = record.boot, record.report_seq, tuple(record.left_boots)
    state.cmd_seq = record.cmd_seq
    state.command = None if record.command is None else command_type(*record.command)
    state.eoa_mm = None if state.command is None else state.command.eoa_mm
    state.next_stop, state.leaving, state.dwells = record.next_stop, record.leaving, record.dwells
    state.dwell_until_s = None if record.dwell_left_s is None else now_s + record.dwell_left_s
    state.handed = record if record.s_m is not None and record.odo_mm is not None else None


def declare_handed(state, report) -> None:
    """Before the first report of a handed-over train reaches its estimator: the record's envelope, carried forward
    by the odometer since the export, declared as the train's position (once; a zone that has located it already
    ignores it)."""
    record, state.handed = state.handed, None
    travelled_m = (report["odo_mm"] - record.odo_mm) / 1000.0 / (record.odometer_per_m or 1.0)
    tol_m = (3.0 * record.sigma_s_m + max(record.ahead_m, record.behind_m) + _CARRY_SHARE * abs(travelled_m)
             + _CARRY_FLOOR_M)
    if record.confirmed:
        state.estimator.declare_position(record.s_m + travelled_m, tol_m, report["odo_mm"] / 1000.0)
