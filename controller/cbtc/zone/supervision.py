"""The supervision read-model: frozen pictures of the zone and of each train as the controller sees them, and the
subscribers they are published to. The status table, `cbtc zone --status-json` and `--summary-json` read these and
nothing else of the controller; a page or a recorder subscribes the same way."""

import logging
from dataclasses import asdict, dataclass

log = logging.getLogger("cbtc.zone")


def _r(value, digits):
    return None if value is None else round(value, digits)


@dataclass(frozen=True, slots=True)
class TrainView:
    """One train as the zone sees it at `t_s`. A train not heard from for longer than the zone's leader age is
    `stale`: its figures are where its last report put it, not extrapolated."""
    train_id: str
    located: bool                # the zone has a position for it
    data_age_s: float | None     # since its newest report was received (None: never heard)
    stale: bool
    s_m: float | None            # estimated head position along the track (m)
    v_mps: float | None          # estimated speed (m/s; at its last report when stale)
    sigma_s_m: float | None      # one sigma of the position estimate (m)
    ahead_m: float | None        # how much further ahead its head may be than s_m: its sensors disagree (m)
    behind_m: float | None       # how much further back (m)
    limit_s_m: float | None      # its end of authority on the track (m)
    limited_by: str | None       # the authority's reason, or why it is held
    leader_data_age_s: float | None   # age of the train-ahead data its authority rests on (s)
    mode: str | None             # the board's mode (wire_zc.MODES)
    faults: tuple                # the board's faults (wire_zc.FAULTS)
    next_stop: str | None
    reports_rejected: int
    gated_fixes: int             # IPS fixes the estimator refused as outliers
    speed_steps: int             # reported speeds that changed faster than the train can (slip, spin)
    gap_measured_m: float | None   # its own ranging to the train ahead (m)
    gap_disagrees: bool          # that measurement and the zone's picture disagree
    station_stops: int
    stop_overruns: int
    commands_sent: int
    last_reject: str             # why its newest refused report was refused
    odometer_jumps: int
    encoder_failures: int
    handling_failures: int       # reports whose handling raised (the train is held; the zone goes on)
    measurements_dropped: int
    command_age_s: float | None  # since its newest command was sent (None: none yet)
    estimate_finite: bool        # its estimate holds finite numbers (the fuzzing checks nothing broke it)
    authority_m: float | None    # how far its safety limit allowed at its newest command (None: held) (m)
    gap_alarms: int              # times its own ranging disagreed with the zone's picture

    def status(self) -> dict:
        """The JSON-ready row of `--status-json`, figures rounded as a table shows them."""
        return {"located": self.located, "data_age_s": _r(self.data_age_s, 3), "stale": self.stale,
                "s_m": _r(self.s_m, 4), "v_mps": _r(self.v_mps, 4), "sigma_s_m": _r(self.sigma_s_m, 4),
                "limit_s_m": _r(self.limit_s_m, 4), "leader_data_age_s": _r(self.leader_data_age_s, 3),
                "limited_by": self.limited_by, "mode": self.mode, "faults": list(self.faults),
                "next_stop": self.next_stop, "reports_rejected": self.reports_rejected,
                "ahead_m": _r(self.ahead_m, 4), "behind_m": _r(self.behind_m, 4), "gated_fixes": self.gated_fixes,
                "speed_steps": self.speed_steps, "gap_measured_m": _r(self.gap_measured_m, 4),
                "gap_disagrees": self.gap_disagrees}

    def summary(self) -> dict:
        """The row of `--summary-json`: the status and the counts of the run so far."""
        return {**self.status(), "station_stops": self.station_stops, "stop_overruns": self.stop_overruns,
                "commands_sent": self.commands_sent, "last_reject": self.last_reject,
                "odometer_jumps": self.odometer_jumps, "encoder_failures": self.encoder_failures,
                "handling_failures": self.handling_failures, "measurements_dropped": self.measurements_dropped}


def train_view(st, now_s: float, max_age_s: float) -> TrainView:
    """The TrainView of zone state `st` (a TrainState) at `now_s`; stale when not heard from for `max_age_s`."""
    age_s = None if st.report_recv_s is None else max(0.0, now_s - st.report_recv_s)
    stale = age_s is not None and age_s > max_age_s
    est = None
    if st.report is not None and st.estimator.localized:
        est = st.estimator.estimate(st.report_t_s if stale else now_s)
    located = est is not None
    return TrainView(
        st.train_id, located, age_s, stale, est.s_m if located else None, est.v_mps if located else None,
        est.sigma_s_m if located else None, est.ahead_m if located else None, est.behind_m if located else None,
        st.limit_s, st.limited_by, None if st.leader_data_t_s is None else now_s - st.leader_data_t_s,
        None if st.report is None else st.report["mode"], () if st.report is None else tuple(st.report["flt"]),
        st.next_stop or None, st.reports_rejected, st.estimator.rejected_ips, st.estimator.speed_steps,
        None if st.rng_gap is None else st.rng_gap[1], st.gap_alarm, st.dwells, st.stop_overruns, st.cmd_seq,
        st.last_reject, st.odometer_jumps, st.encoder_failures, st.failures, st.measurements_dropped,
        None if st.answered_s is None else now_s - st.answered_s, st.estimator.healthy(), st.safe_m,
        st.gap_alarms)


@dataclass(frozen=True, slots=True)
class ZoneView:
    """The zone at `t_s`: each train's view, in the zone's order, and the zone's own counts."""
    zone_id: str
    session_id: int
    t_s: float
    trains: tuple                # TrainView, one per train
    cycles: int
    unknown_reports: int         # reports on the topic of a train the zone does not govern
    invalid_reports: int         # reports refused (seal, fields, boot, sequence)
    refusals: tuple              # ((train, class), count) of the refusals logged, sorted

    def train(self, train_id: str) -> TrainView:
        for view in self.trains:
            if view.train_id == train_id:
                return view
        raise KeyError(train_id)

    def status(self) -> dict:
        """{train id: status row}."""
        return {view.train_id: view.status() for view in self.trains}

    def summary(self) -> dict:
        return {"session_id": self.session_id, "cycles": self.cycles, "unknown_reports": self.unknown_reports,
                "invalid_reports": self.invalid_reports,
                "trains": {view.train_id: view.summary() for view in self.trains},
                "refusals": {f"{train}/{klass}": n for (train, klass), n in self.refusals}}

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, slots=True)
class CommandSent:
    """A command the zone has just published, and what it rested on."""
    train_id: str
    t_s: float
    command: tuple               # records.Command: its fields by name
    limited_by: str | None       # the authority's reason, or why the train is held
    leader_data_t_s: float | None   # when the train-ahead data it rests on was sampled (s)
    sigma_m: float | None        # the combined uncertainty taken off the gap (m)
    confirmed: bool              # the train's position rests on two independent references


class Subscribers(list):
    """Callables handed each event in turn (a view, a command, a report), any number of them; one that raises is
    dropped with an error logged, and the zone goes on. A list, so that asking whether there are any costs the zone
    nothing on its hot path."""

    def __init__(self, what: str):
        super().__init__()
        self.what = what

    def subscribe(self, callback):
        """Hand `callback` every event from now; returns the callable that unsubscribes it."""
        self.append(callback)
        return lambda: self.remove(callback) if callback in self else None

    def publish(self, *event) -> None:
        for callback in tuple(self):
            try:
                callback(*event)
            except Exception as exc:
                log.error("a subscriber to the zone's %s failed (%s: %s): it is dropped, the zone goes on", self.what,
                          type(exc).__name__, exc)
                if callback in self:
                    self.remove(callback)
