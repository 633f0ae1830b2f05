"""The simple estimator: odometry anchored on RFID balises, localised and nudged by the IPS.

Kept as the fusion baseline (the UKF in cbtc.estimation.ukf_estimator is the default). Position = anchor + odometer
travel since the anchor; each balise read re-anchors exactly; an IPS fix projected onto the track corrects the anchor
with a scalar Kalman gain, after an innovation gate. Uncertainty grows with the distance since the anchor (encoder
drift).
"""

import math

from cbtc.estimation.estimate import Estimate, declared_at, span_offsets_m
from cbtc.estimation.fix_consensus import agreeing_anchor
from cbtc.protocol import wire
from cbtc.railway.balise import BaliseReader
from cbtc.railway.geometry import circular_offset_m
from cbtc.railway.ips_frame import ips_to_track


class OdometryEstimator:
    name = "odometry"

    def __init__(self, layout, profile, drift_frac: float = 0.03, gate_sigma: float = 3.0):
        self.layout = layout
        self.profile = profile
        self.drift_frac = drift_frac
        self.gate_sigma = gate_sigma
        self.localized = False
        self._tag_anchored = False   # a balise (or an operator's declaration it agrees with) has anchored it
        self._declared = None        # (s_m, tol_m) declared by an operator (declare_position)
        self._s_ref_m = 0.0        # unwrapped s at the anchor
        self._odo_ref_mm = 0
        self._var_ref_m2 = 0.0
        self._last = None          # (t_s, odo_mm, v_mps) of the newest report
        self.rejected_ips = 0
        self.speed_steps = 0       # speed steps are not looked for here (the UKF estimator counts them)
        self.locate_fixes = 3      # IPS fixes that must agree before the IPS alone places the train
        self._fix_anchors = []     # fix position less odometer (m) of the fixes seen while unplaced
        self.balises = BaliseReader(layout)   # tag reads -> positions, from their telegrams or the layout
        self._doubt_span = None    # (low, high) track positions from before a fresh start (keep_doubt)
        self._doubt = None         # (behind <= 0, ahead >= 0) of the position it was placed at by the IPS alone

    def _s_and_var(self, odo_mm):
        travel_m = (odo_mm - self._odo_ref_mm) / 1000.0
        var = self._var_ref_m2 + (self.drift_frac * travel_m) ** 2
        return self._s_ref_m + travel_m, var

    @property
    def unknown_tags(self):
        return self.balises.counts["unknown"]

    def odometer_per_m_low(self, k_sigma: float) -> float:
        """A lower bound of odometer metres per true metre: this estimator does not learn the encoder's scale, so it
        takes the drift fraction as the scale's 1-sigma."""
        return 1.0 - k_sigma * self.drift_frac

    def keep_doubt(self, low_s_m: float, high_s_m: float) -> None:
        """As UkfEstimator.keep_doubt: placed by the IPS alone, the estimate also covers [low_s_m, high_s_m] (where
        the train was when this estimator was started afresh) until a balise read re-anchors it. The zone hands a
        span over only from an estimate whose sensors disagreed, which this baseline does not report."""
        if not self.localized:
            self._doubt_span = (low_s_m, high_s_m)

    def declare_position(self, s_m: float, tol_m: float, odo_m: float = None) -> None:
        """As UkfEstimator.declare_position: an IPS placement within `tol_m` (and 3 sigma) of `s_m`, carried on by the
        odometer from `odo_m`, is confirmed."""
        if not self.localized:
            self._declared = (s_m, tol_m, odo_m)

    @property
    def confirmed(self) -> bool:
        """Located, and anchored on a balise since (the IPS alone may carry a lasting bias)."""
        return self.localized and self._tag_anchored

    @property
    def doubt_kept(self) -> bool:
        """The estimate still covers the span `keep_doubt` gave it (until a balise re-anchors it)."""
        return self._doubt is not None

    def distrust_wheel(self) -> None:
        """Nothing to re-open: this estimator learns no scale and always takes `drift_frac` as its doubt."""

    def on_report(self, report: dict, clock) -> None:
        t_s = clock.to_controller_s(report["t_ms"])
        odo_mm = report["odo_mm"]
        v_mps = report["v_mmps"] / 1000.0
        for entry in report["tags"]:
            tag_s_m = self.balises.position_m(entry[0], entry[4] if len(entry) > 4 else None)
            if tag_s_m is None:
                continue
            self._s_ref_m = tag_s_m
            self._odo_ref_mm = entry[1]
            self._var_ref_m2 = (self.profile.rfid_range_m ** 2) / 3.0
            self.localized = True
            self._tag_anchored = True
            self._doubt = None
        if report["ips"] is not None:
            self._ips_update(report, clock, odo_mm, v_mps)
        self._last = (t_s, odo_mm, v_mps)

    def _ips_update(self, report, clock, odo_mm, v_mps):
        fix_t_ms, x_mm, y_mm = report["ips"]
        x_m, y_m = ips_to_track(x_mm / 1000.0, y_mm / 1000.0, self.layout.ips)
        # the fix was sampled latency before it reached the board
        age_s = wire.wrap_diff(report["t_ms"], fix_t_ms) / 1000.0 + self.profile.ips_latency_s
        odo_fix_mm = odo_mm - v_mps * age_s * 1000.0
        r_m2 = self.profile.ips_sigma_m ** 2
        if not self.localized:
            # placed only where `locate_fixes` fixes agree: one fix in a hundred is an outlier
            # (cbtc.estimation.fix_consensus)
            # the newest 2 n - 1 fixes, as the UKF takes them: n agreeing ones outvote the rest
            keep = 2 * self.locate_fixes - 1
            self._fix_anchors = (self._fix_anchors + [self.layout.project(x_m, y_m) - odo_fix_mm / 1000.0])[-keep:]
            found = agreeing_anchor(self._fix_anchors, self.profile.ips_sigma_m, self.locate_fixes,
                                    self.layout.loop_length_m)
            if found is not None:
                self._s_ref_m = found[0] + odo_fix_mm / 1000.0
                self._odo_ref_mm = odo_fix_mm
                self._var_ref_m2 = 4.0 * r_m2 / found[1]
                self.localized = True
                if self._declared is not None:
                    d_s_m, tol_m = declared_at(self._declared, odo_fix_mm / 1000.0)
                    off_m = circular_offset_m(self.layout.wrap(self._s_ref_m), self.layout.wrap(d_s_m),
                                              self.layout.loop_length_m)
                    self._tag_anchored = abs(off_m) <= tol_m + 3.0 * self._var_ref_m2 ** 0.5
                if self._doubt_span is not None:
                    self._doubt = span_offsets_m(self.layout, self._doubt_span, self._s_ref_m)
            return
        s_pred, var = self._s_and_var(odo_fix_mm)
        s_meas = self.layout.project(x_m, y_m, s_hint_m=self.layout.wrap(s_pred))
        innov = circular_offset_m(s_meas, self.layout.wrap(s_pred), self.layout.loop_length_m)
        if innov * innov > self.gate_sigma ** 2 * (var + r_m2):
            self.rejected_ips += 1
            return
        gain = var / (var + r_m2)
        self._s_ref_m = s_pred + gain * innov
        self._odo_ref_mm = odo_fix_mm
        self._var_ref_m2 = (1.0 - gain) * var

    def healthy(self) -> bool:
        """Always: its state is a few floats checked as they come (same interface as UkfEstimator.healthy)."""
        return True

    def position_m(self, now_s: float):
        """`estimate(now_s).s_m` alone (None while unlocated), as UkfEstimator.position_m."""
        est = self.estimate(now_s)
        return None if est is None else est.s_m

    def estimate(self, now_s: float):
        if not self.localized or self._last is None:
            return None
        t_s, odo_mm, v_mps = self._last
        s_m, var = self._s_and_var(odo_mm)
        dt_s = now_s - t_s
        sigma_v = 0.02 + 0.05 * abs(v_mps)
        s_now = s_m + v_mps * dt_s
        var_now = var + (sigma_v * dt_s) ** 2
        behind_m, ahead_m = (0.0, 0.0) if self._doubt is None else (-self._doubt[0], self._doubt[1])
        return Estimate(s_m=self.layout.wrap(s_now), v_mps=v_mps, sigma_s_m=math.sqrt(var_now),
                        sigma_v_mps=sigma_v, t_s=now_s, data_t_s=t_s, ahead_m=ahead_m, behind_m=behind_m)
