"""The paper's Table 1 from a recorded run: each fusion variant replayed offline on the same reports, against truth.

Variants (the reports are the same; each variant sees only its sensors):

- dead reckoning: the raw encoder odometer from the true position at the first report (no correction at all);
- IPS alone: every raw fix, compared with the truth at the instant the beacon sampled it;
- UKF encoder + IPS: the UKF estimator fed the reports with their tag reads removed;
- UKF encoder + IPS + RFID: the UKF estimator fed the reports as they are;
- UKF encoder + IPS + wayside ranging: tags removed, a two-way TOA range to the nearest wayside radio added per
  report (cbtc.ranging.wayside_fusion);
- odometry estimator: the simple baseline (cbtc.estimation.odometry_estimator) on the full reports, for reference.

Estimators are evaluated at each report's sampling instant, with the estimate the controller would use then. Errors
are layout-frame x and y (the paper's RMSE) and along the track (what the movement authority consumes).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from cbtc.estimation.estimate import BoardClock
from cbtc.estimation.odometry_estimator import OdometryEstimator
from cbtc.estimation.ukf_estimator import UkfEstimator
from cbtc.railway.geometry import circular_offset_m
from cbtc.railway.ips_frame import ips_to_track
from cbtc.ranging.wayside_fusion import ranged_estimator

# (key, label, paper RMSE x cm, paper RMSE y cm): Table 1 of the source paper, mean of its trains A and B
METHODS = (
    ("dead_reckoning", "dead reckoning (encoder only)", 34.5, 27.6),
    ("ips", "IPS alone", 27.2, 25.1),
    ("ukf_enc_ips", "UKF encoder + IPS", 13.2, 11.6),
    ("ukf_enc_ips_rfid", "UKF encoder + IPS + RFID", 0.66, 0.57),
    ("ukf_enc_ips_toa", "UKF encoder + IPS + wayside ranging", None, None),
    ("odometry", "odometry estimator (baseline)", None, None),
)


@dataclass
class TrainRecord:
    """What a run recorded of one train: its reports as received, and the truth (simulator only)."""

    train_id: str
    profile: object
    reports: list                 # (receive time s, decoded report dict), in receive order
    truth_s: object               # callable: controller times (s, array) -> true head s (m, unwrapped)
    board_offset_s: float         # board clock minus controller clock (s): maps report stamps to truth times


@dataclass
class Trace:
    """One variant's estimates of one train, with their errors against truth."""

    t_s: list = field(default_factory=list)         # controller time of each estimate (s)
    x_m: list = field(default_factory=list)         # estimated layout-frame position (m)
    y_m: list = field(default_factory=list)
    x_err_m: list = field(default_factory=list)
    y_err_m: list = field(default_factory=list)
    along_err_m: list = field(default_factory=list)

    def add(self, t_s, x_m, y_m, x_err_m, y_err_m, along_err_m):
        self.t_s.append(t_s)
        self.x_m.append(x_m)
        self.y_m.append(y_m)
        self.x_err_m.append(x_err_m)
        self.y_err_m.append(y_err_m)
        self.along_err_m.append(along_err_m)

    def rmse_cm(self):
        """{'x_cm', 'y_cm', 'along_cm', 'n'}: root mean square errors in centimetres."""
        def rms(values):
            return round(100.0 * math.sqrt(float(np.mean(np.square(values)))), 3) if values else None
        return {"x_cm": rms(self.x_err_m), "y_cm": rms(self.y_err_m), "along_cm": rms(self.along_err_m),
                "n": len(self.t_s)}


def signed_along_m(layout, s_from_m, s_to_m):
    """Signed along-track distance from `s_from_m` to `s_to_m` (m): the short way round on a loop."""
    return circular_offset_m(s_to_m, s_from_m, layout.loop_length_m)


def records_from_recorder(recorder):
    """TrainRecords of a cbtc.sim.simulation run.

    The recorder samples the truth once per onboard loop, after every train's tick, so the first sample at or after a
    tick holds the state of that tick exactly; reports, tag reads and IPS samples are all stamped at ticks.
    """
    t_rec = np.asarray(recorder.t_s)
    records = []
    for i, train in enumerate(recorder.sim.trains):
        travelled = np.asarray(recorder.travelled_m[i])

        def truth_s(t_s, travelled=travelled, s0_m=train.s0_m):
            idx = np.clip(np.searchsorted(t_rec, np.asarray(t_s) - 1e-9, side="left"), 0, len(t_rec) - 1)
            return s0_m + travelled[idx]

        records.append(TrainRecord(train.train_id, train.profile, list(recorder.reports[i]), truth_s,
                                   train.clock_offset_ms / 1000.0))
    return records


def _strip_tags(report):
    out = dict(report)
    out["tags"] = []
    return out


def _errors(layout, s_est_m, s_true_m, xy_est):
    x_true, y_true = layout.xy(s_true_m)
    return float(xy_est[0] - x_true), float(xy_est[1] - y_true), signed_along_m(layout, layout.wrap(s_true_m), s_est_m)


def estimator_trace(layout, record, estimator, report_filter=None):
    """Feed `record`'s reports to `estimator` as the zone controller does; its estimate at each report's instant."""
    clock = BoardClock()
    trace = Trace()
    for recv_s, report in record.reports:
        if report_filter is not None:
            report = report_filter(report)
        clock.observe(report["t_ms"], recv_s)
        estimator.on_report(report, clock)
        if not estimator.localized:
            continue
        est = estimator.estimate(clock.to_controller_s(report["t_ms"]))
        t_true_s = report["t_ms"] / 1000.0 - record.board_offset_s
        s_true = float(record.truth_s(t_true_s))
        xy = layout.xy(est.s_m)
        trace.add(t_true_s, float(xy[0]), float(xy[1]), *_errors(layout, est.s_m, s_true, xy))
    return trace


def dead_reckoning_trace(layout, record):
    """Position = true position at the first report + raw odometer travel since: what the encoder alone gives."""
    trace = Trace()
    first = None
    for _recv_s, report in sorted(record.reports, key=lambda item: item[1]["t_ms"]):
        t_true_s = report["t_ms"] / 1000.0 - record.board_offset_s
        s_true = float(record.truth_s(t_true_s))
        if first is None:
            first = (s_true, report["odo_mm"])
        s_est = layout.wrap(first[0] + (report["odo_mm"] - first[1]) / 1000.0)
        xy = layout.xy(s_est)
        trace.add(t_true_s, float(xy[0]), float(xy[1]), *_errors(layout, s_est, s_true, xy))
    return trace


def ips_trace(layout, record):
    """Every raw IPS fix (layout frame) against the truth when the beacon sampled it; along-track by projection."""
    trace = Trace()
    latency_s = record.profile.ips_latency_s
    for _recv_s, report in record.reports:
        if report["ips"] is None:
            continue
        fix_t_ms, x_mm, y_mm = report["ips"]
        x_m, y_m = ips_to_track(x_mm / 1000.0, y_mm / 1000.0, layout.ips)
        t_true_s = fix_t_ms / 1000.0 - latency_s - record.board_offset_s
        s_true = float(record.truth_s(t_true_s))
        x_true, y_true = layout.xy(s_true)
        s_fix = layout.project(x_m, y_m, s_hint_m=layout.wrap(s_true))
        trace.add(t_true_s, x_m, y_m, x_m - float(x_true), y_m - float(y_true),
                  signed_along_m(layout, layout.wrap(s_true), s_fix))
    return trace


def method_traces(layout, record, ukf_params=None):
    """{method key: Trace} of one train."""
    params = ukf_params or {}
    return {
        "dead_reckoning": dead_reckoning_trace(layout, record),
        "ips": ips_trace(layout, record),
        "ukf_enc_ips": estimator_trace(layout, record, UkfEstimator(layout, record.profile, **params), _strip_tags),
        "ukf_enc_ips_rfid": estimator_trace(layout, record, UkfEstimator(layout, record.profile, **params)),
        "ukf_enc_ips_toa": estimator_trace(layout, record, ranged_estimator(layout, record, **params), _strip_tags),
        "odometry": estimator_trace(layout, record, OdometryEstimator(layout, record.profile)),
    }


def fusion_table(layout, records, ukf_params=None):
    """(rows, traces): one row per method with per-train and mean RMSE (cm) beside the paper's;
    traces[train][method]."""
    traces = {rec.train_id: method_traces(layout, rec, ukf_params) for rec in records}
    rows = []
    for key, label, paper_x, paper_y in METHODS:
        per_train = {train_id: traces[train_id][key].rmse_cm() for train_id in traces}
        row = {"method": key, "label": label, "paper_x_cm": paper_x, "paper_y_cm": paper_y, "trains": per_train}
        for axis in ("x_cm", "y_cm", "along_cm"):
            values = [t[axis] for t in per_train.values() if t[axis] is not None]
            row[axis] = round(float(np.mean(values)), 3) if values else None
        rows.append(row)
    return rows, traces


def paper_ordering_holds(rows) -> dict:
    """The checks of the paper's result on our rows: each criterion and whether it holds."""
    by = {row["method"]: row for row in rows}

    def xy(key):
        return 0.5 * (by[key]["x_cm"] + by[key]["y_cm"])

    return {
        "dead_reckoning > ips": xy("dead_reckoning") > xy("ips"),
        "ips > ukf_enc_ips": xy("ips") > xy("ukf_enc_ips"),
        "ukf_enc_ips > ukf_enc_ips_rfid": xy("ukf_enc_ips") > xy("ukf_enc_ips_rfid"),
        "ukf_enc_ips <= ips / 2": xy("ukf_enc_ips") <= 0.5 * xy("ips"),
        "ukf_enc_ips_rfid along <= 1 cm": by["ukf_enc_ips_rfid"]["along_cm"] <= 1.0,
    }
