"""The wayside-ranging row of the fusion table: UKF on encoder + IPS + two-way TOA ranges to wayside radios
(the BART radio ATC).

The recorded reports carry no ranges (the boards have no wayside radio yet), so the replay synthesises one exchange per
report from the truth at the report's sampling instant, with the nearest surveyed radio (cbtc.ranging.toa), and hands it
to the estimator at that board time. Tags are stripped: the row shows what ranging adds to encoder + IPS.
"""

import numpy as np

from cbtc.estimation.ukf_estimator import UkfEstimator
from cbtc.ranging.toa import WaysideRanging, survey_radios

RADIO_SPACING_M = 1.0     # wayside radios every metre of track
RADIO_LATERAL_M = 0.15    # beside the track, to the left


class RangedEstimator:
    """A UkfEstimator fed, after each report, the range the train's radio measured at that report's instant."""

    def __init__(self, layout, record, ranging: WaysideRanging, rng, **params):
        self._inner = UkfEstimator(layout, record.profile, **params)
        self._record = record
        self._ranging = ranging
        self._rng = rng
        self.ranges_used = 0

    @property
    def localized(self):
        return self._inner.localized

    @property
    def confirmed(self):
        return self._inner.confirmed

    def declare_position(self, s_m, tol_m, odo_m=None):
        self._inner.declare_position(s_m, tol_m, odo_m)

    def estimate(self, now_s):
        return self._inner.estimate(now_s)

    def position_m(self, now_s):
        return self._inner.position_m(now_s)

    def on_report(self, report, board_clock):
        self._inner.on_report(report, board_clock)
        t_board_s = report["t_ms"] / 1000.0
        s_true = float(self._record.truth_s(t_board_s - self._record.board_offset_s))
        measured = self._ranging.measure(s_true, self._rng, t1_s=t_board_s)
        if measured is not None:
            radio, range_m = measured
            self._inner.update_range(t_board_s, (radio.x_m, radio.y_m), range_m, self._ranging.sigma_m)
            self.ranges_used += 1


def ranged_estimator(layout, record, seed=0, **params):
    """The estimator of the wayside-ranging row for one train's record (seeded per train)."""
    ranging = WaysideRanging(layout, survey_radios(layout, RADIO_SPACING_M, RADIO_LATERAL_M))
    rng = np.random.default_rng([seed, sum(record.train_id.encode())])
    return RangedEstimator(layout, record, ranging, rng, **params)
