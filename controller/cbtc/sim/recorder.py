"""The recorder of a simulated run: truth, reports and authority limits, and the figures computed from them."""

import math

import numpy as np

from cbtc.authority.rules import following_reach_m
from cbtc.protocol import wire
from cbtc.railway.geometry import circular_offset_m
from cbtc.sim.truth import head_inside, train_ahead
from cbtc.zone.config import train_key


class Recorder:
    """Truth, reports and authority limits of a run, and the figures computed from them."""

    def __init__(self, sim):
        self.sim = sim
        self.layout = sim.config.layout
        n = len(sim.trains)
        self.t_s = []
        self.travelled_m = [[] for _ in range(n)]
        self.head_s_m = [[] for _ in range(n)]
        self.v_mps = [[] for _ in range(n)]
        self.gap_m = [[] for _ in range(n)]       # true gap to the train ahead (head to its tail)
        self.est_s_m = [[] for _ in range(n)]
        self.est_sigma_m = [[] for _ in range(n)]
        self.constrained = [[] for _ in range(n)]  # the train ahead limits this train's speed now
        self.collisions = [0] * n
        self.overruns = [0] * n
        self._colliding = [False] * n
        self._overrun = [False] * n
        self.reports = [[] for _ in range(n)]     # (recv_s, report dict)
        self._index = {t.train_id: i for i, t in enumerate(sim.trains)}
        self._sniffer = sim.broker.connect("recorder")
        self._sniffer.subscribe(wire.REPORT_FILTER, self._on_report)

    def _on_report(self, topic, payload):
        try:
            train_id = wire.train_id_of(topic)
            i = self._index[train_id]
            report = wire.decode_report(train_key(self.sim.config.seed, train_id), topic, payload)
        except (wire.WireError, KeyError):
            return
        self.reports[i].append((self.sim.scheduler.now_s(), report))

    def sample(self, now_s):
        layout = self.layout
        trains = self.sim.trains
        self.t_s.append(now_s)
        heads = [t.head_s for t in trains]
        spans = [(t.train_id, t.head_s, t.tail_s) for t in trains]
        ahead = train_ahead(layout, heads)
        for i, train in enumerate(trains):
            self.travelled_m[i].append(train.travelled_m)
            self.head_s_m[i].append(heads[i])
            self.v_mps[i].append(train.v_mps)
            if i in ahead:
                j = ahead[i]
                gap = layout.ahead_m(heads[i], trains[j].tail_s)
                inside = head_inside(layout, heads[i], trains[j].tail_s, trains[j].profile.length_m)
                if inside and not self._colliding[i]:
                    self.collisions[i] += 1
                self._colliding[i] = inside
                self.gap_m[i].append(-layout.ahead_m(trains[j].tail_s, heads[i]) if inside else gap)
            state = self.sim.zc.trains[train.train_id]
            self.constrained[i].append(state.safe_m is not None and state.safe_m < following_reach_m(train.profile))
            over = self.sim.policy.protected_m(layout, train.train_id, spans) < -0.001
            if over and not self._overrun[i]:
                self.overruns[i] += 1
            self._overrun[i] = over
            est = None
            if state.report is not None and state.estimator.localized:
                est = state.estimator.estimate(now_s)
            self.est_s_m[i].append(math.nan if est is None else est.s_m)
            self.est_sigma_m[i].append(math.nan if est is None else est.sigma_s_m)

    # --- figures --------------------------------------------------------------------------------------------------

    def lap_times(self, i):
        """Times (s) of each completed lap of train i, counted at its start position."""
        if not self.layout.closed:
            return []
        length = self.layout.length_m
        times, crossings = [], []
        next_mark = length
        for t_s, d in zip(self.t_s, self.travelled_m[i]):
            if d >= next_mark:
                crossings.append(t_s)
                next_mark += length
        last = 0.0
        for t in crossings:
            times.append(t - last)
            last = t
        return times

    def laps(self, i):
        if not self.layout.closed or not self.travelled_m[i]:
            return 0
        return int(self.travelled_m[i][-1] // self.layout.length_m)

    def estimation_error(self, i):
        """RMSE and max of the controller's estimate against truth along the track (m), while located."""
        errs = []
        for s_est, s_true in zip(self.est_s_m[i], self.head_s_m[i]):
            if s_est == s_est:
                errs.append(circular_offset_m(s_est, s_true, self.layout.loop_length_m))
        if not errs:
            return None
        arr = np.asarray(errs)
        return {"rmse_m": float(np.sqrt(np.mean(arr ** 2))), "max_abs_m": float(np.max(np.abs(arr)))}

    def summary(self):
        trains = []
        for i, train in enumerate(self.sim.trains):
            laps = self.lap_times(i)
            gaps = np.asarray(self.gap_m[i]) if self.gap_m[i] else None
            state = self.sim.zc.trains[train.train_id]
            err = self.estimation_error(i)
            trains.append({
                "train": train.train_id,
                "laps": len(laps),
                "mean_lap_s": round(float(np.mean(laps)), 3) if laps else None,
                "distance_m": round(self.travelled_m[i][-1], 3) if self.travelled_m[i] else 0.0,
                "mean_gap_m": None if gaps is None else round(float(np.mean(gaps)), 3),
                "min_gap_m": None if gaps is None else round(float(np.min(gaps)), 3),
                "collisions": self.collisions[i],
                "authority_overruns": self.overruns[i],
                "station_stops": state.dwells,
                "estimation_rmse_m": None if err is None else round(err["rmse_m"], 4),
                "estimation_max_error_m": None if err is None else round(err["max_abs_m"], 4),
                "commands_rejected_onboard": train.obu.rejected,
                "emergency_trips": train.obu.trips,
                "encoder_trips": train.obu.enc_fails,
                "reports_rejected": state.reports_rejected,
            })
        return {
            "layout": self.layout.name,
            "policy": self.sim.policy.name,
            "estimator": self.sim.config.estimator,
            "seed": self.sim.config.seed,
            "simulated_s": round(self.t_s[-1], 3) if self.t_s else 0.0,
            "trains": trains,
            "collisions": sum(self.collisions),
            "authority_overruns": sum(self.overruns),
            "emergency_trips": sum(t.obu.trips for t in self.sim.trains),
            "encoder_trips": sum(t.obu.enc_fails for t in self.sim.trains),
            "all_standing_at_end_s": round(all_standing_s(self.t_s, self.v_mps), 3),
        }


def all_standing_s(t_s, v_mps_by_train):
    """How long (s) every train had been standing still at the last sample (sample times `t_s`, speeds per train):
    long means gridlock."""
    for k in range(len(t_s) - 1, -1, -1):
        if any(v[k] > 0.0 for v in v_mps_by_train):
            return t_s[-1] - t_s[k]
    return t_s[-1] - t_s[0] if t_s else 0.0
