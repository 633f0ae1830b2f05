"""The recorder of a simulated run: truth, reports and authority limits, and the figures computed from them.

Truth decides: collisions and authority overruns come from the trains' true positions. A collision is a head inside
the span of the train ahead, whoever moved; `rolled_onto` counts those among them, and the entries into the protected
zone, where the train ahead rolled back onto a train standing still. An overrun is a train's own forward motion
taking its head into the protected zone of the train ahead. `granted_beyond_m` is how far
the authority a board held reached past the true tail of the train ahead (or the end of the line); a train is
stranded when it stood still over the run's last STRANDED_S with more than its following reach of true room ahead.
"""

from array import array
from collections import deque
from math import inf, nan, sqrt

from cbtc.authority.rules import following_reach_m
from cbtc.protocol import fast_wire, wire, wire_zc
from cbtc.railway.geometry import circular_offset_m
from cbtc.sim.truth import head_inside, train_ahead
from cbtc.zone.config import train_key

STRANDED_S = 20.0
GRIDLOCK_M = 0.05   # every train crept less than this over the last STRANDED_S: gridlock


_SAMPLES = ("travelled_m", "head_s_m", "v_mps", "gap_m", "est_s_m", "est_sigma_m", "following_gap_m")


class Recorder:
    """Truth, reports and authority limits of a run, and the figures computed from them.

    The figures are kept as running statistics (sums, extremes, lap crossings, the last STRANDED_S of travel), so a
    run of any length holds bounded memory. The samples themselves (every train's travel, position, speed, gap and
    estimate at every loop tick) only when asked (`keep_samples`: plots, the comparison's headway, the fusion table).
    """

    def __init__(self, sim, keep_reports: bool = False, keep_samples: bool = False):
        self.sim = sim
        self.keep_reports = keep_reports   # every report heard, for the fusion table (memory grows with the run)
        self.keep_samples = keep_samples   # every sample (memory grows with the run)
        self.layout = sim.config.layout
        n = len(sim.trains)
        # samples as packed machine numbers (8 bytes a float, 1 a flag), not lists of Python objects
        self._t_s = array("d")
        self._samples = {name: [array("d") for _ in range(n)] for name in _SAMPLES}
        self._samples["constrained"] = [array("b") for _ in range(n)]  # 1: the train ahead limits its speed now
        # running statistics, whatever is kept
        self._t_first_s = self._t_last_s = None
        self._moving_last_s = None             # the newest sample at which some train moved
        self._crossings = [[] for _ in range(n)]   # times its travel passed each whole lap
        self._gap = [[0, 0.0, inf] for _ in range(n)]    # true gap to the train ahead: count, sum, least
        self._following = [[0, 0.0] for _ in range(n)]       # ... while the train ahead limits it: count, sum
        self._error = [[0, 0.0, 0.0] for _ in range(n)]      # estimate less truth: count, sum of squares, worst
        self._window = [deque() for _ in range(n)]            # (t_s, travelled_m) over the last STRANDED_S
        self._ever_constrained = [False] * n
        self._reach_m = [following_reach_m(t.profile) for t in sim.trains]   # within it the train ahead limits one
        self.collisions = [0] * n
        self.overruns = [0] * n
        self.rolled_onto = [0] * n               # the train ahead rolled back into this standing train's zone or
        #                                          onto it (the latter counted as collisions too)
        self._travelled_before = [0.0] * n
        self.granted_beyond_m = [-inf] * n   # worst (highest) granted room less true room while authorised
        self.room_m = [inf] * n             # true room ahead at the newest sample
        self._colliding = [False] * n
        self._overrun = [False] * n
        self._heard = [[] for _ in range(n)]      # (recv_s, topic, payload) of every report heard: decoded when asked
        self._reports = [[] for _ in range(n)]    # (recv_s, report dict) of those decoded so far
        self._index = {t.train_id: i for i, t in enumerate(sim.trains)}
        self._sniffer = sim.broker.connect("recorder")
        if keep_reports:
            self._sniffer.subscribe(wire_zc.REPORT_FILTER, self._on_report)

    def _kept(self, name):
        if not self.keep_samples:
            raise ValueError(f"this run kept no samples ({name}): build it with Simulation(config, keep_samples=True)")
        return self._t_s if name == "t_s" else self._samples[name]

    t_s = property(lambda self: self._kept("t_s"), doc="Sample times (s), when samples are kept.")
    travelled_m = property(lambda self: self._kept("travelled_m"), doc="Per train, distance travelled (m).")
    head_s_m = property(lambda self: self._kept("head_s_m"), doc="Per train, true head position (m).")
    v_mps = property(lambda self: self._kept("v_mps"), doc="Per train, true speed (m/s).")
    gap_m = property(lambda self: self._kept("gap_m"), doc="Per train, true gap to the train ahead (head to tail, m).")
    est_s_m = property(lambda self: self._kept("est_s_m"), doc="Per train, the zone's estimate (m; nan: unlocated).")
    est_sigma_m = property(lambda self: self._kept("est_sigma_m"), doc="Per train, its 1-sigma (m).")
    constrained = property(lambda self: self._kept("constrained"), doc="Per train, 1 where the train ahead limits it.")
    following_gap_m = property(lambda self: self._kept("following_gap_m"),
                               doc="Per train, the true gap at the samples where the train ahead limits it (m).")

    @property
    def ever_constrained(self):
        """Per train, whether the train ahead ever limited its speed."""
        return list(self._ever_constrained)

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
                    self._reports[i].append((recv_s, fast_wire.decode_report(key, topic, payload)))
                except wire.WireError:
                    pass
            heard.clear()
        return self._reports

    def sample(self, now_s):
        layout = self.layout
        zc = self.sim.zc
        trains = self.sim.trains
        keep = self.keep_samples
        first = self._t_first_s is None   # a train that starts inside a zone has not entered it
        if first:
            self._t_first_s = now_s
        self._t_last_s = now_s
        if keep:
            self._t_s.append(now_s)
        strays = self.sim.strays
        everyone = trains + strays if strays else trains   # truth: a board the zone does not know is a train too
        heads = [t.head_s for t in everyone]
        tails = [t.tail_s for t in everyone]
        spans = [(t.train_id if k < len(trains) else f"stray {k}", head, tail)
                 for k, (t, head, tail) in enumerate(zip(everyone, heads, tails))]
        ahead = train_ahead(layout, heads)
        protected = self.sim.policy.protected_all_m(layout, spans)
        lap_m = layout.length_m if layout.closed else None
        any_moving = False
        for i, train in enumerate(trains):
            travelled_m = train.travelled_m
            moved = travelled_m > self._travelled_before[i] + 1e-4   # forward since the last sample
            self._travelled_before[i] = travelled_m
            any_moving = any_moving or train.v_mps > 0.0
            self._granted(i, train, now_s, heads, tails, ahead, everyone)
            crossings = self._crossings[i]
            if lap_m is not None and travelled_m >= lap_m * (len(crossings) + 1):
                crossings.append(now_s)
            window = self._window[i]
            window.append((now_s, travelled_m))
            while len(window) > 1 and now_s - window[1][0] >= STRANDED_S:
                window.popleft()   # keeps the newest sample at least STRANDED_S old
            gap_m = self._gap_to_ahead(i, heads, tails, ahead, everyone, moved, first) if i in ahead else None
            safe_m = zc.authority_m(train.train_id)
            constrained = safe_m is not None and safe_m < self._reach_m[i]
            self._ever_constrained[i] = self._ever_constrained[i] or constrained
            if gap_m is not None and constrained:
                self._following[i][0] += 1
                self._following[i][1] += gap_m
            over = protected[i] < -0.001
            if over and not self._overrun[i] and not first:
                if moved:
                    self.overruns[i] += 1
                else:
                    self.rolled_onto[i] += 1
            self._overrun[i] = over
            est = self._estimate_error(i, train, now_s, heads[i])
            if keep:
                self._keep(i, train, travelled_m, heads[i], gap_m, constrained, est)
        if any_moving:
            self._moving_last_s = now_s

    def _gap_to_ahead(self, i, heads, tails, ahead, everyone, moved, first):
        """Train i's gap (m) to the tail of the train ahead in truth (negative: inside it), counting a collision when
        its head has entered that train since the last sample."""
        layout = self.layout
        j = ahead[i]
        tail_s = tails[j]
        inside = head_inside(layout, heads[i], tail_s, everyone[j].length_m)
        if inside and not self._colliding[i] and not first:
            self.collisions[i] += 1   # a collision whoever moved
            if not moved:
                self.rolled_onto[i] += 1
        self._colliding[i] = inside
        gap_m = -layout.ahead_m(tail_s, heads[i]) if inside else layout.ahead_m(heads[i], tail_s)
        stats = self._gap[i]
        stats[0] += 1
        stats[1] += gap_m
        stats[2] = min(stats[2], gap_m)
        return gap_m

    def _estimate_error(self, i, train, now_s, head_s_m):
        """The zone's estimate of train i against its true head; the Estimate when samples are kept (else None)."""
        zc = self.sim.zc
        est = None
        if self.keep_samples:   # its sigma is kept too
            est = zc.estimate_at(train.train_id, now_s)
            est_s_m = None if est is None else est.s_m
        else:
            est_s_m = zc.estimate_at(train.train_id, now_s, position_only=True)
        if est_s_m is not None and est_s_m == est_s_m:
            err_m = circular_offset_m(est_s_m, head_s_m, self.layout.loop_length_m)
            stats = self._error[i]
            stats[0] += 1
            stats[1] += err_m * err_m
            stats[2] = max(stats[2], abs(err_m))
        return est

    def _keep(self, i, train, travelled_m, head_s_m, gap_m, constrained, est):
        samples = self._samples
        samples["travelled_m"][i].append(travelled_m)
        samples["head_s_m"][i].append(head_s_m)
        samples["v_mps"][i].append(train.v_mps)
        if gap_m is not None:
            samples["gap_m"][i].append(gap_m)
        samples["constrained"][i].append(constrained)
        if gap_m is not None and constrained:
            samples["following_gap_m"][i].append(gap_m)
        samples["est_s_m"][i].append(nan if est is None else est.s_m)
        samples["est_sigma_m"][i].append(nan if est is None else est.sigma_s_m)

    def _granted(self, i, train, now_s, heads, tails, ahead, everyone):
        """True room ahead of train i now, and how far the authority its board holds reaches beyond it."""
        layout = self.layout
        if i in ahead:
            tail_s = tails[ahead[i]]
            room_m = layout.ahead_m(heads[i], tail_s)
            if head_inside(layout, heads[i], tail_s, everyone[ahead[i]].length_m):
                room_m = -layout.ahead_m(tail_s, heads[i])
        elif layout.closed:
            room_m = layout.length_m - train.length_m
        else:
            room_m = layout.length_m - heads[i]
        self.room_m[i] = room_m
        granted_m = board_granted_m(train, now_s)
        if granted_m is not None:
            self.granted_beyond_m[i] = max(self.granted_beyond_m[i], granted_m - room_m)

    def stranded(self, i) -> bool:
        """Train i stood still over the last STRANDED_S of a run at least twice that long, with more than its following
        reach of true room ahead, and not because the world stopped it dead."""
        moved_m = self._moved_lately_m(i)
        return moved_m is not None and moved_m < 0.01 and \
            self.room_m[i] > self._reach_m[i] + self.sim.config.params.margin_m

    def gridlocked(self) -> bool:
        """Every train moved less than GRIDLOCK_M over the last STRANDED_S of a run at least twice that long, none
        stopped dead by the world: each is held by another (a loop filled with trains, blocks all taken), though they
        may creep a few mm at a time as the edges of their authorities move."""
        for i in range(len(self.sim.trains)):
            moved_m = self._moved_lately_m(i)
            if moved_m is None or moved_m >= GRIDLOCK_M:
                return False
        return True

    def _moved_lately_m(self, i):
        """How far train i moved over the last STRANDED_S (m); None for a run shorter than twice that, or a train the
        world stopped dead (it stands for a reason of its own)."""
        if self._t_first_s is None or self._t_last_s - self._t_first_s < 2 * STRANDED_S or \
                self.sim.trains[i].stopped_dead:
            return None
        travel = [d for _t, d in self._window[i]]
        return max(travel) - min(travel)

    # --- figures --------------------------------------------------------------------------------------------------

    def lap_times(self, i):
        """Times (s) of each completed lap of train i, counted at its start position."""
        times, last = [], 0.0
        for t in self._crossings[i]:
            times.append(t - last)
            last = t
        return times

    def laps(self, i):
        return len(self._crossings[i])

    def estimation_error(self, i):
        """RMSE and max of the controller's estimate against truth along the track (m), while located."""
        count, squares, worst = self._error[i]
        if not count:
            return None
        return {"rmse_m": sqrt(squares / count), "max_abs_m": worst}

    def summary(self):
        trains = []
        view = self.sim.zc.view(self.sim.scheduler.now_s())
        for i, train in enumerate(self.sim.trains):
            laps = self.lap_times(i)
            gap_n, gap_sum, gap_min = self._gap[i]
            state = view.train(train.train_id)
            err = self.estimation_error(i)
            trains.append({
                "train": train.train_id,
                "laps": len(laps),
                "mean_lap_s": round(sum(laps) / len(laps), 3) if laps else None,
                "distance_m": round(self._travelled_before[i], 3) if self._t_first_s is not None else 0.0,
                "mean_gap_m": round(gap_sum / gap_n, 3) if gap_n else None,
                "min_gap_m": round(gap_min, 3) if gap_n else None,
                "collisions": self.collisions[i],
                "authority_overruns": self.overruns[i],
                "rolled_onto": self.rolled_onto[i],
                "granted_beyond_m": _metres(self.granted_beyond_m[i]),
                "stranded": self.stranded(i),
                "station_stops": state.station_stops,
                "estimation_rmse_m": None if err is None else round(err["rmse_m"], 4),
                "estimation_max_error_m": None if err is None else round(err["max_abs_m"], 4),
                "commands_rejected_onboard": train.obu.rejected,
                "emergency_trips": train.obu.trips,
                "encoder_trips": train.obu.enc_fails,
                "reports_rejected": state.reports_rejected,
            })
        gap_n = sum(g[0] for g in self._gap)
        follow_n = sum(f[0] for f in self._following)
        laps = [t for i in range(len(self.sim.trains)) for t in self.lap_times(i)]
        beyond = [b for b in self.granted_beyond_m if b > -inf]
        started = self._t_first_s is not None
        return {
            "layout": self.layout.name,
            "policy": self.sim.policy.name,
            "estimator": self.sim.config.estimator,
            "seed": self.sim.config.seed,
            "simulated_s": round(self._t_last_s, 3) if started else 0.0,
            "trains": trains,
            "collisions": sum(self.collisions),
            "authority_overruns": sum(self.overruns),
            "rolled_onto": sum(self.rolled_onto),
            "granted_beyond_m": _metres(max(beyond)) if beyond else None,
            "stranded": sum(t["stranded"] for t in trains),
            "mean_following_gap_m": round(sum(f[1] for f in self._following) / follow_n, 3) if follow_n else None,
            "min_gap_m": round(min(g[2] for g in self._gap), 3) if gap_n else None,
            "mean_lap_s": round(sum(laps) / len(laps), 3) if laps else None,
            "emergency_trips": sum(t.obu.trips for t in self.sim.trains),
            "encoder_trips": sum(t.obu.enc_fails for t in self.sim.trains),
            "all_standing_at_end_s": round(self._t_last_s - (self._t_first_s if self._moving_last_s is None
                                                              else self._moving_last_s), 3) if started else 0.0,
            "gridlocked": self.gridlocked(),
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
    return None if value == -inf else round(float(value), 4)


def board_granted_m(train, now_s):
    """In truth, how far ahead of its head the authority `train`'s board holds reaches, or None while it holds no
    valid one: odometer mm to true m at the rate the wheel counts now (its error, and a slip or spin fault)."""
    obu = train.obu
    if not obu.command_valid(train.board_ms(now_s)) or obu.way != train.cab:
        return None   # none, or the board has just turned standing and its authority lies the way truth turns next
    counts_per_true_m = (1.0 + train.profile.encoder_scale_error) * train.encoder.scale_fault
    return (obu.eoa_mm - obu.odo_mm) / 1000.0 / counts_per_true_m
