"""The recorder of a simulated run: truth, reports and authority limits, and the figures computed from them.

Truth decides: collisions and authority overruns come from the trains' true positions, counted when a train's own
forward motion takes its head into the span or the protected zone of the train ahead; when the train ahead rolls back
onto a train standing still, that is counted apart (`rolled_onto`): no authority can move a standing train out of
the way. `granted_beyond_m` is how far
the authority a board held reached past the true tail of the train ahead (or the end of the line); a train is
stranded when it stood still over the run's last STRANDED_S with more than its following reach of true room ahead.
"""

import math
from array import array

import numpy as np

from cbtc.authority.rules import following_reach_m
from cbtc.protocol import wire
from cbtc.railway.geometry import circular_offset_m
from cbtc.sim.truth import head_inside, protected_m, train_ahead
from cbtc.zone.config import train_key

STRANDED_S = 20.0


class Recorder:
    """Truth, reports and authority limits of a run, and the figures computed from them."""

    def __init__(self, sim, keep_reports: bool = False):
        self.sim = sim
        self.keep_reports = keep_reports   # every report heard, for the fusion table (memory grows with the run)
        self.layout = sim.config.layout
        n = len(sim.trains)
        # samples as packed machine numbers (8 bytes a float, 1 a flag), not lists of Python objects
        self.t_s = array("d")
        self.travelled_m = [array("d") for _ in range(n)]
        self.head_s_m = [array("d") for _ in range(n)]
        self.v_mps = [array("d") for _ in range(n)]
        self.gap_m = [array("d") for _ in range(n)]       # true gap to the train ahead (head to its tail)
        self.est_s_m = [array("d") for _ in range(n)]
        self.est_sigma_m = [array("d") for _ in range(n)]
        self.constrained = [array("b") for _ in range(n)]  # 1: the train ahead limits this train's speed now
        self.following_gap_m = [array("d") for _ in range(n)]  # true gap at the samples where it is so limited
        self.collisions = [0] * n
        self.overruns = [0] * n
        self.rolled_onto = [0] * n               # the train ahead rolled back into this standing train's zone or span
        self._travelled_before = [0.0] * n
        self.granted_beyond_m = [-math.inf] * n   # worst (highest) granted room less true room while authorised
        self.room_m = [math.inf] * n             # true room ahead at the newest sample
        self._colliding = [False] * n
        self._overrun = [False] * n
        self._heard = [[] for _ in range(n)]      # (recv_s, topic, payload) of every report heard: decoded when asked
        self._reports = [[] for _ in range(n)]    # (recv_s, report dict) of those decoded so far
        self._index = {t.train_id: i for i, t in enumerate(sim.trains)}
        self._sniffer = sim.broker.connect("recorder")
        if keep_reports:
            self._sniffer.subscribe(wire.REPORT_FILTER, self._on_report)

    def _on_report(self, topic, payload):
        try:
            i = self._index[wire.train_id_of(topic)]
        except (wire.WireError, KeyError):
            return
        self._heard[i].append((self.sim.scheduler.now_s(), topic, payload))

    def heard(self):
        """(recv_s, topic, payload) of every report heard and not yet decoded, all trains, in arrival order."""
        return sorted((item for heard in self._heard for item in heard), key=lambda item: item[0])

    @property
    def reports(self):
        """Per train, (recv_s, report dict) of every authentic report heard, in arrival order."""
        if not self.keep_reports:
            raise ValueError("this run kept no reports: build it with Simulation(config, keep_reports=True)")
        for i, heard in enumerate(self._heard):
            key = train_key(self.sim.config.seed, self.sim.trains[i].train_id)
            for recv_s, topic, payload in heard:
                try:
                    self._reports[i].append((recv_s, wire.decode_report(key, topic, payload)))
                except wire.WireError:
                    pass
            heard.clear()
        return self._reports

    def sample(self, now_s):
        layout = self.layout
        trains = self.sim.trains
        self.t_s.append(now_s)
        heads = [t.head_s for t in trains]
        spans = [(t.train_id, t.head_s, t.tail_s) for t in trains]
        ahead = train_ahead(layout, heads)
        first = len(self.t_s) == 1   # a train that starts inside a zone has not entered it
        for i, train in enumerate(trains):
            moved = train.travelled_m > self._travelled_before[i] + 1e-4   # forward since the last sample
            self._travelled_before[i] = train.travelled_m
            self._granted(i, train, now_s, heads, ahead)
            self.travelled_m[i].append(train.travelled_m)
            self.head_s_m[i].append(heads[i])
            self.v_mps[i].append(train.v_mps)
            if i in ahead:
                j = ahead[i]
                gap = layout.ahead_m(heads[i], trains[j].tail_s)
                inside = head_inside(layout, heads[i], trains[j].tail_s, trains[j].profile.length_m)
                if inside and not self._colliding[i] and not first:
                    if moved:
                        self.collisions[i] += 1
                    else:
                        self.rolled_onto[i] += 1
                self._colliding[i] = inside
                self.gap_m[i].append(-layout.ahead_m(trains[j].tail_s, heads[i]) if inside else gap)
            state = self.sim.zc.trains[train.train_id]
            self.constrained[i].append(state.safe_m is not None and state.safe_m < following_reach_m(train.profile))
            if i in ahead and self.constrained[i][-1]:
                self.following_gap_m[i].append(self.gap_m[i][-1])
            over = protected_m(self.sim.policy, layout, train.train_id, spans) < -0.001
            if over and not self._overrun[i] and not first:
                if moved:
                    self.overruns[i] += 1
                else:
                    self.rolled_onto[i] += 1
            self._overrun[i] = over
            est = None
            if state.report is not None and state.estimator.localized:
                est = state.estimator.estimate(now_s)
            self.est_s_m[i].append(math.nan if est is None else est.s_m)
            self.est_sigma_m[i].append(math.nan if est is None else est.sigma_s_m)

    def _granted(self, i, train, now_s, heads, ahead):
        """True room ahead of train i now, and how far the authority its board holds reaches beyond it."""
        layout = self.layout
        if i in ahead:
            tail_s = self.sim.trains[ahead[i]].tail_s
            room_m = layout.ahead_m(heads[i], tail_s)
            if head_inside(layout, heads[i], tail_s, self.sim.trains[ahead[i]].profile.length_m):
                room_m = -layout.ahead_m(tail_s, heads[i])
        elif layout.closed:
            room_m = layout.length_m - train.profile.length_m
        else:
            room_m = layout.length_m - heads[i]
        self.room_m[i] = room_m
        obu = train.obu
        if obu.command_valid(train.board_ms(now_s)):
            # odometer mm to true m at the rate the wheel counts now (its error, and a slip or spin fault)
            counts_per_true_m = (1.0 + train.profile.encoder_scale_error) * train.encoder.scale_fault
            granted_m = (obu.eoa_mm - obu.odo_mm) / 1000.0 / counts_per_true_m
            self.granted_beyond_m[i] = max(self.granted_beyond_m[i], granted_m - room_m)

    def stranded(self, i) -> bool:
        """Train i stood still over the last STRANDED_S of a run at least twice that long, with more than its following
        reach of true room ahead, and not because the world stopped it dead."""
        train = self.sim.trains[i]
        if not self.t_s or self.t_s[-1] - self.t_s[0] < 2 * STRANDED_S or train.stopped_dead:
            return False
        k = next(k for k in range(len(self.t_s) - 1, -1, -1) if self.t_s[-1] - self.t_s[k] >= STRANDED_S)
        moved_m = max(self.travelled_m[i][k:]) - min(self.travelled_m[i][k:])
        return moved_m < 0.01 and self.room_m[i] > following_reach_m(train.profile) + self.sim.config.params.margin_m

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
                "rolled_onto": self.rolled_onto[i],
                "granted_beyond_m": _metres(self.granted_beyond_m[i]),
                "stranded": self.stranded(i),
                "station_stops": state.dwells,
                "estimation_rmse_m": None if err is None else round(err["rmse_m"], 4),
                "estimation_max_error_m": None if err is None else round(err["max_abs_m"], 4),
                "commands_rejected_onboard": train.obu.rejected,
                "emergency_trips": train.obu.trips,
                "encoder_trips": train.obu.enc_fails,
                "reports_rejected": state.reports_rejected,
            })
        gaps = [g for i in range(len(self.sim.trains)) for g in self.gap_m[i]]
        following = [g for i in range(len(self.sim.trains)) for g in self.following_gap_m[i]]
        laps = [t for i in range(len(self.sim.trains)) for t in self.lap_times(i)]
        beyond = [b for b in self.granted_beyond_m if b > -math.inf]
        return {
            "layout": self.layout.name,
            "policy": self.sim.policy.name,
            "estimator": self.sim.config.estimator,
            "seed": self.sim.config.seed,
            "simulated_s": round(self.t_s[-1], 3) if self.t_s else 0.0,
            "trains": trains,
            "collisions": sum(self.collisions),
            "authority_overruns": sum(self.overruns),
            "rolled_onto": sum(self.rolled_onto),
            "granted_beyond_m": _metres(max(beyond)) if beyond else None,
            "stranded": sum(t["stranded"] for t in trains),
            "mean_following_gap_m": round(float(np.mean(following)), 3) if following else None,
            "min_gap_m": round(float(np.min(gaps)), 3) if gaps else None,
            "mean_lap_s": round(float(np.mean(laps)), 3) if laps else None,
            "emergency_trips": sum(t.obu.trips for t in self.sim.trains),
            "encoder_trips": sum(t.obu.enc_fails for t in self.sim.trains),
            "all_standing_at_end_s": round(all_standing_s(self.t_s, self.v_mps), 3),
        }


def violations(summary) -> list:
    """The safety violations truth found in a run (a summary of Recorder.summary): a collision, an authority overrun
    (a head inside the protected zone behind the train ahead), an authority that reached beyond the train ahead."""
    found = []
    if summary["collisions"]:
        found.append("collision")
    if summary["authority_overruns"]:
        found.append("authority_overrun")
    if summary["granted_beyond_m"] is not None and summary["granted_beyond_m"] > 0.0:
        found.append("authority_beyond_reality")
    return found


def _metres(value):
    return None if value == -math.inf else round(float(value), 4)


def all_standing_s(t_s, v_mps_by_train):
    """How long (s) every train had been standing still at the last sample (sample times `t_s`, speeds per train):
    long means gridlock."""
    for k in range(len(t_s) - 1, -1, -1):
        if any(v[k] > 0.0 for v in v_mps_by_train):
            return t_s[-1] - t_s[k]
    return t_s[-1] - t_s[0] if t_s else 0.0
