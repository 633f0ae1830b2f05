"""The default position estimator: a track-constrained UKF per train on encoder, IPS and RFID
(cbtc.estimation.track_ukf), with OdometryEstimator's interface (`on_report(report, board_clock)`, `estimate(now_s)`).

Each measurement is stamped with its own board time (the encoder at the report's `t_ms`, an IPS fix at its receive
time less the IPS latency, a tag at its read time) and kept `history_s` in time order with the filter state after it;
a late one is inserted at its time and the newer ones re-run, so a better clock offset never reorders anything. A
train is placed by its first balise read, or where `locate_fixes` IPS fixes agree (cbtc.estimation.fix_consensus),
and `confirmed` once a second, independent reference agrees; until then the estimate covers the placement's lasting
bias, and a balise the filter gates places it afresh. Gated fixes that agree among themselves mean the sensors
disagree (multipath, or a wheel that slipped, spun or was lifted): only a balise can tell which, and until they agree
the estimate covers both (`Estimate.ahead_m` / `behind_m`); a gated balise agreeing with the fixes moves it there.
"""

from bisect import bisect_right
from math import sqrt

from cbtc.estimation.balise_reads import BaliseReads
from cbtc.estimation.estimate import Estimate
from cbtc.estimation.ips_agreement import IpsAgreement
from cbtc.estimation.track_ukf import TrackUkf
from cbtc.estimation.ukf_history import FilterEvent, FilterState
from cbtc.estimation.ukf_model import D, K, S, V
from cbtc.estimation.ukf_params import make_params, noise_model
from cbtc.estimation.ukf_placement import placement
from cbtc.estimation.wheel_watch import WheelWatch
from cbtc.railway.balise import BaliseReader
from cbtc.railway.geometry import circular_offset_m
from cbtc.railway.ips_frame import ips_to_track

_SLIP_STORY_M = 0.3   # a gated balise read this close (m) may tell of a wheel that slipped or spun since the last one
_ROLL_MPS = 0.05     # a train braked to a stand rolls no faster than this (m/s, 1-sigma)


class UkfEstimator:
    name = "ukf"

    def __init__(self, layout, profile, **params):
        self.layout = layout
        self.profile = profile
        self.params = make_params(params)
        self.noise = noise_model(profile, self.params)
        self._ips = IpsAgreement(layout, profile, self.params)   # whether the IPS agrees with the filter
        self._reads = BaliseReads(layout, self.noise, self.params)   # what a balise read tells against it
        self.localized = False
        self.balises = BaliseReader(layout)   # tag reads -> positions, from their telegrams or the layout
        self.late_measurements = 0   # arrived more than history_s after newer ones: dropped
        self._clock = None
        self._events = []            # in time order
        self._keys = []              # _keys[i]: _events[i].sort_key, for bisect
        self._estimate_memo = None   # (state, now_s, clock offset, newest data time, Estimate): asked many times
        self._states = []            # _states[i]: after _events[i]; None while unlocated
        self._base = None            # state before _events[0]
        self._doubt_span = None      # (low, high) track positions from before a fresh start (keep_doubt)
        self._declared = None        # (s_m, tol_m) an operator declared the head stands at (declare_position)
        self._trimmed = False        # once measurements have been forgotten, older ones cannot be placed
        self._filter = None          # the TrackUkf the states are replayed on
        self._filter_holds = None    # the state whose snapshot _filter holds as it stands (no restore needed)
        self._wheel = WheelWatch(profile, self.params)   # what the board's reports say of its wheel
        self._scale_sigma0 = self.params.scale_sigma   # the scale's 1-sigma when the train is located
        self._band0 = None           # the wheel's scale band a turned train brought (carry_wheel)

    def keep_doubt(self, low_s_m: float, high_s_m: float) -> None:
        """The head was in [low_s_m, high_s_m] (track positions) when this estimator was started afresh (its encoder
        failed): located by the IPS alone, the estimate covers that span too until a balise confirms the position
        (fixes that disagreed with the wheel may be the wrong ones). No-op once located."""
        if not self.localized:
            self._doubt_span = (low_s_m, high_s_m)

    @property
    def wheel_band(self):
        """(low, high) odometer m per true m the balises vouch for (FilterState.vouched; None: not yet), or the one
        handed over by carry_wheel until they do."""
        state = self._newest
        band = state.vouched[3:] if state is not None and state.vouched is not None else (None, None)
        return band if band[0] is not None else self._band0

    def carry_wheel(self, band) -> None:
        """The same wheel's band (`wheel_band` of the estimator before: a train turned), until balises vouch anew."""
        self._band0 = band

    @property
    def doubt_kept(self) -> bool:
        """The estimate still covers the span `keep_doubt` gave it: no balise read has confirmed the position yet."""
        state = self._newest
        return state is not None and state.doubt is not None

    def declare_position(self, s_m: float, tol_m: float, odo_m: float = None) -> None:
        """An operator declares that the train's head stands within `tol_m` of `s_m` (at odometer `odo_m`, carried on
        by it; None: standing): a reference of its own, independent of the sensors, for the placement that follows.
        One that agrees is confirmed, its estimate covering the declared span until a balise; one that does not is
        pending as without it. No-op once located."""
        if not self.localized:
            self._declared = (self.layout.wrap(s_m), tol_m, odo_m)

    @property
    def confirmed(self) -> bool:
        """Located, and by two independent references: what placed the train (the IPS or a tag) and a balise where
        the filter expected it (after a tag: a second tag, or `locate_fixes` IPS fixes in a row). Until then the
        estimate covers the placement's bias (`ips_bias_m`, `tag_bias_m`) and the zone lets the train move only at
        restricted speed."""
        state = self._newest
        return state is not None and state.pending is None

    def distrust_wheel(self) -> None:
        """Locate the train with its encoder scale open (1-sigma `step_scale_sigma`): after the board named an encoder
        fault, whatever the wheel read before says nothing of how it reads now. No-op once located or without a
        scale."""
        if not self.localized and self.params.scale_sigma > 0:
            self._scale_sigma0 = max(self.params.scale_sigma, self.params.step_scale_sigma)

    # --- counters of the measurements in use --------------------------------------------------------------------------

    @property
    def _newest(self):
        return self._states[-1] if self._states else self._base

    @property
    def unknown_tags(self):
        """Tag reads with neither a usable telegram nor an entry in the layout."""
        return self.balises.counts["unknown"]

    @property
    def speed_steps(self):   # reported speeds that changed faster than the train can (the wheel slipped or spun)
        return self._newest.speed_steps if self._newest else 0

    @property
    def rejected_ips(self):   # IPS fixes the gate turned away, among those the current state rests on
        return self._newest.ips_rejected if self._newest else 0

    @property
    def scale_error(self):   # the encoder scale error learnt so far (None while unlocated or not estimated)
        return self._wheel.scale_error(self._newest)

    def odometer_per_m_low(self, k_sigma: float) -> float:
        """A lower bound of the encoder's odometer metres per true metre at `k_sigma` (WheelWatch.scale_low): the
        controller turns a distance along the track into odometer units with it."""
        return self._wheel.scale_low(self._newest, k_sigma, self._scale_sigma0)

    def healthy(self) -> bool:
        """The newest state is finite and its covariance positive definite (True while unlocated): the controller
        locates a train afresh when it is not."""
        return self._newest is None or self._newest.healthy()

    def counters(self) -> dict:
        """How the measurements were used: IPS fixes and tags used or gated, unknown tags, relocations, late drops."""
        state = self._newest or FilterState(None)
        return {"ips_used": state.ips_used, "ips_rejected": state.ips_rejected, "tags_used": state.tags_used,
                "tags_rejected": state.tags_rejected, "relocations": state.relocations,
                "disagreements": state.disagreements, "disagreeing": state.disagree is not None,
                "speed_steps": state.speed_steps, "speed_drifts": self._wheel.speed_drifts,
                "motor_gain": round(self._wheel.motor.gain, 4), "motor_learnt_s": round(self._wheel.motor.learnt_s, 1),
                "unknown_tags": self.unknown_tags, "late_measurements": self.late_measurements,
                **{"balise_" + k: v for k, v in self.balises.counts.items() if k != "unknown"}}

    # --- input --------------------------------------------------------------------------------------------------------

    def on_report(self, report: dict, board_clock) -> None:
        """Take one decoded report; `board_clock` (a BoardClock that has observed it) maps board to controller time."""
        self._clock = board_clock
        t_s = board_clock.board_s(report["t_ms"])   # the board's time line, unwrapped
        d_m, v_mps, rolled_m, run_m, step = self._wheel.take(report, t_s, self._newest, self._scale_sigma0)
        new = [FilterEvent(t_s, "odo", (d_m, v_mps))]
        if rolled_m:
            new.append(FilterEvent(t_s, "roll", (rolled_m, run_m, d_m)))
        if step is not None:
            new.append(FilterEvent(t_s, "step", step))
        self._sensor_events(report, board_clock, new)
        self._insert(new)

    def _sensor_events(self, report, board_clock, new):
        """The report's balise reads and IPS fix, each an event at its own board time, appended to `new`."""
        for entry in report["tags"]:
            tag_s_m = self.balises.position_m(entry[0], entry[4] if len(entry) > 4 else None)
            if tag_s_m is None:
                continue
            # read before the train first moved: it may have stood in the reader's field all along
            in_field = self._wheel.first_odo_m is None or entry[1] / 1000.0 <= self._wheel.first_odo_m
            new.append(FilterEvent(board_clock.board_s(entry[2]), "tag",
                              (tag_s_m, entry[1] / 1000.0 - self._wheel.rolled_m, in_field, entry[3] / 1000.0)))
        if report["ips"] is not None:
            fix_t_ms, x_mm, y_mm = report["ips"]
            x_m, y_m = ips_to_track(x_mm / 1000.0, y_mm / 1000.0, self.layout.ips)
            new.append(FilterEvent(board_clock.board_s(fix_t_ms) - self.profile.ips_latency_s, "ips", (x_m, y_m)))

    def update_range(self, t_s: float, radio_xy, range_m: float, sigma_m: float) -> None:
        """Take a two-way TOA range (m, 1-sigma `sigma_m`) to a wayside radio at `radio_xy` (layout frame, m),
        measured at board time `t_s` (s); applied in time order like every other measurement (cbtc.ranging.toa)."""
        data = (float(radio_xy[0]), float(radio_xy[1]), float(range_m), float(sigma_m))
        self._insert([FilterEvent(t_s, "range", data)])

    def _insert(self, new):
        keys = self._keys
        start = len(self._events)
        for event in sorted(new, key=lambda e: e.sort_key):
            if self._trimmed and event.t_s < self._events[0].t_s:
                self.late_measurements += 1
                continue
            index = bisect_right(keys, event.sort_key)
            keys.insert(index, event.sort_key)
            self._events.insert(index, event)
            self._states.insert(index, None)
            start = min(start, index)
        self._replay(start)
        self._trim()

    # --- the filter ---------------------------------------------------------------------------------------------------

    def _replay(self, start):
        state = self._states[start - 1] if start > 0 else self._base
        for i in range(start, len(self._events)):
            state = self._apply(state, self._events[i])
            self._states[i] = state
        self.localized = self._newest is not None

    def _trim(self):
        newest_t = self._events[-1].t_s
        drop = 0
        while drop < len(self._events) - 1 and self._events[drop].t_s < newest_t - self.params.history_s:
            drop += 1
        if drop:
            self._base = self._states[drop - 1]
            self._trimmed = True
            del self._events[:drop]
            del self._keys[:drop]
            del self._states[:drop]

    def _apply(self, state, event):
        """The state after `event`, from `state` (None while unlocated)."""
        if state is None:
            return self._locate(event)
        f = self._load(state)
        self._filter_holds = None   # until this apply has made its state
        f.predict_to(event.t_s)
        new = state.copy_with(None)
        if event.kind == "odo":
            new.reach = self._reads.reckon(f, state.reach, event.data[0], self._scale_sigma0, state.vouched,
                                           state.ips_d_m)
            f.update_odometer(event.data[0])
        elif event.kind == "roll":
            # a roll goes one way all along, whichever it is: its steps add up to the spread, not in quadrature
            step_m, run_m, d_m = event.data
            new.reach, new.vouched = self._reads.widen_reach(state.reach, step_m), None   # travel of no known sign
            f.widen_position(sqrt(step_m * (step_m + 2.0 * run_m)))
            f.hold_still(_ROLL_MPS, d_m)
        elif event.kind == "step":
            # the wheel's scale changed: re-opened, so the position widens with the travel and the IPS and balises
            # learn it again; the travel since the previous report is in doubt by the step's share
            new.speed_steps += 1
            new.reach, new.vouched = self._reads.widen_reach(state.reach, event.data[0]), None
            f.widen_position(event.data[0])
            f.reopen_scale(event.data[1])
        elif event.kind == "tag":
            if not self._take_tag(f, state, new, event.data):
                self._filter_holds = None
                return None
        elif event.kind == "range":
            f.update_range(*event.data)
        else:
            self._take_ips(f, state, new, event.data)
        self._keep_wheel_in_doubt(f)
        new.snap = f.snapshot()
        self._filter_holds = new
        return new

    def _take_tag(self, f, state, new, data):
        """A balise read into `new`, the state after it (`state` before); False when nothing places the train now."""
        if f.update_tag(*data):
            # a balise where the filter expects it: a second, independent reference to what placed the train
            new.tags_used += 1
            new.tag_offset = new.doubt = new.pending = new.tag_story = None
            new.reach = self._reads.reach_at_tag(f, *data)
            new.vouched = self._reads.vouch(f, state.vouched, *data)
        elif state.consensus is not None and self._reads.arbitrate(f, state.consensus, *data):
            new.tags_used += 1
            new.relocations += 1
            new.gated, new.consensus, new.innovations, new.disagree = (), None, (), None
            new.tag_offset = new.doubt = new.pending = new.tag_story = None
            new.reach = self._reads.reach_at_tag(f, *data)
            new.vouched = self._reads.vouch(f, None, *data)   # the wheel was wrong: vouched for afresh
        elif state.pending is not None and not self._reads.within_doubt(f, state.doubt, *data):
            # a balise beyond the pending placement's own bound: nothing places the train now; it is located
            # afresh (and every train held meanwhile), not re-placed at what may be another tag misread
            return False
        elif state.pending is not None or self._reads.story_repeats(f, state.reach, state.tag_story, *data):
            # the placement rests on one reference, and a balise says it is wrong; or a second balise in a row
            # tells the same story of a filter gone astray (a wheel worn long, and no IPS): the train is placed
            # at the balise, covering where it was before, until a second reference confirms one of them
            new.tags_used += 1
            new.relocations += 1
            if state.pending is None and f.n > K:   # the wheel was wrong: its scale is learnt afresh
                f.reopen_scale(3.0 * self.params.scale_sigma)
            new.gated, new.consensus, new.innovations, new.disagree = (), None, (), None
            new.tag_offset = new.tag_story = None
            new.doubt = self._reads.replace_at_tag(f, state.doubt, *data)
            new.pending, new.agreeing = "tag", 0
            new.reach = self._reads.reach_at_tag(f, *data)
            new.vouched = self._reads.vouch(f, None, *data)
        else:
            # a balise the filter gates: the wheel may be wrong, or the tag; covered both ways until one is shown
            new.tags_rejected += 1
            story_m, _var = self._reads.read_story(f, *data)
            new.tag_story = story_m
            if abs(story_m) <= _SLIP_STORY_M:   # further off, it is another tag (misplaced or swapped), not slip
                new.tag_offset = story_m
        return True

    def _take_ips(self, f, state, new, data):
        """An IPS fix (x_m, y_m) into `new`, the state after it (`state` before)."""
        fix_s_m = self.layout.project(*data)
        s_m, d_m = float(f.mean[S]), float(f.mean[D])
        new.innovations = (state.innovations + (circular_offset_m(fix_s_m, s_m, self.layout.loop_length_m),))[
            -max(self.params.relocate_after, self.params.bias_fixes):]
        # while the sensors disagree the IPS is as suspect as the wheel: a fix far from the wheel's position is
        # not taken, however wide the position has grown (a roll, an open scale), or it would take the filter
        # over to the fixes' story and out of the bounds that cover the wheel's
        suspect = state.disagree is not None and abs(new.innovations[-1]) > 3.0 * self.profile.ips_sigma_m
        if not suspect and f.update_ips(*data):
            new.ips_used += 1
            new.gated, new.consensus, new.ips_d_m = (), None, d_m
            if state.pending == "tag":
                # the IPS, independent of the tag, agrees with a tag placement: `locate_fixes` in a row confirm it
                new.agreeing += 1
                if new.agreeing >= self.params.locate_fixes:
                    new.doubt = new.pending = None
        else:
            new.agreeing = 0
            new.ips_rejected += 1
            new.gated = (state.gated + (fix_s_m - d_m,))[-self.params.relocate_after:]
            new.consensus = self._ips.consensus(s_m, d_m, new.gated) or state.consensus
        new.disagree = self._ips.disagreement(new.consensus, new.innovations)
        if new.tag_offset is not None and self._ips.refutes(new.innovations, new.tag_offset):
            new.tag_offset = None
        if new.tag_story is not None and self._ips.refutes(new.innovations, new.tag_story):
            new.tag_story = None
        if new.disagree is not None and state.disagree is None:
            new.disagreements += 1

    def _keep_wheel_in_doubt(self, f):
        """A scale learnt beyond three prior sigmas is a wheel that slips or spins, which stops when it will: the
        scale stays open to a third of its error, so that the position covers a wheel that reads true again."""
        if f.n > K:
            error = abs(float(f.mean[K]))
            if error > 3.0 * self.params.scale_sigma and f.cov[K][K] < (error / 3.0) ** 2:
                f.reopen_scale(error / 3.0)

    def _load(self, state):
        if self._filter is None:
            t_s, x, P = state.snap
            self._filter = TrackUkf(self.layout, self.noise, x, P, t_s)
        elif self._filter_holds is not state:
            self._filter.restore(state.snap)
        return self._filter

    def _locate(self, event):
        """The state `event` places the unlocated train in (cbtc.estimation.ukf_placement), or None."""
        placed = placement(self, event)
        if placed is None:
            return None
        used, self._filter = placed
        self._filter_holds = used
        return used

    # --- output -------------------------------------------------------------------------------------------------------

    def estimate(self, now_s: float):
        """Head position, speed and their 1-sigma at controller time `now_s`, predicted from the newest data."""
        memo = self._estimate_memo
        if memo is not None and memo[1] == now_s and memo[0] is (self._states[-1] if self._states else self._base) \
                and memo[2] == self._clock.offset_s and memo[3] == self._events[-1].t_s:
            return memo[4]
        state = self._newest
        if state is None or self._clock is None:
            return None
        offset_s = self._clock.offset_s
        newest_t_s = self._events[-1].t_s
        t_s, x, P = state.snap
        dt_s = (now_s - offset_s) - t_s
        q = self.noise.accel_psd_m2ps3
        adt = abs(dt_s)
        var_s = P[S][S] + 2.0 * dt_s * P[S][V] + dt_s * dt_s * P[V][V] + q * adt ** 3 / 3.0
        var_v = P[V][V] + q * adt
        sigma_s_m = sqrt(max(var_s, 0.0))
        ahead_m, behind_m = state.covered(x[S], sigma_s_m, self.layout.loop_length_m)
        # by position (a keyword call costs the frozen value's __init__ half as much again): s_m, v_mps, sigma_s_m,
        # sigma_v_mps, t_s, data_t_s, ahead_m, behind_m
        est = Estimate(self._position_m(x, dt_s), float(x[V]), sigma_s_m, sqrt(var_v), now_s,
                       newest_t_s + offset_s, ahead_m, behind_m)
        self._estimate_memo = (state, now_s, offset_s, newest_t_s, est)
        return est

    def position_m(self, now_s: float):
        """`estimate(now_s).s_m` alone (None while unlocated): a simulation's recorder asks for it at every tick."""
        state = self._newest
        if state is None or self._clock is None:
            return None
        t_s, x, _P = state.snap
        return self._position_m(x, (now_s - self._clock.offset_s) - t_s)

    def _position_m(self, x, dt_s):
        return float(self.layout.wrap(x[S] + x[V] * dt_s))
