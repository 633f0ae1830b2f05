"""Wayside radio ranging by two-way time of arrival (the BART radio ATC): radios at surveyed positions, ranges into
the UKF.

Two-way exchange between the train radio and a wayside radio, each stamping on its own free-running clock:
t1 the train sends (train clock), t2 the wayside radio receives (wayside clock), t3 it replies (wayside clock),
t4 the train receives (train clock). Then

    range = c * ((t4 - t1) - (t3 - t2)) / 2

and the unknown offset between the two clocks cancels, because each difference is taken on one clock. Timestamp
jitter sigma_t on each of the four stamps gives a range noise of c * sigma_t (four stamps, halved).

`WaysideRanging` is the measurement model the UKF consumes: h(s) = |p_train(s) - p_radio| with p_train(s) the
layout's `xy(s)`, and its noise sigma. Pure functions; randomness comes from the numpy Generator handed in.
"""

import math
from dataclasses import dataclass

import numpy as np

from cbtc.errors import ConfigError

C_MPS = 299_792_458.0


@dataclass(frozen=True)
class WaysideRadio:
    """A radio at a surveyed position in the layout frame (m)."""

    name: str
    x_m: float
    y_m: float


def two_way_range_m(t1_s, t2_s, t3_s, t4_s, wave_mps=C_MPS):
    """Range (m) of a two-way exchange; t1/t4 on the initiator's clock, t2/t3 on the responder's (s)."""
    return wave_mps * ((t4_s - t1_s) - (t3_s - t2_s)) / 2.0


def exchange_timestamps(range_m, t1_s, offset_s, turnaround_s, rng, stamp_sigma_s=0.0, wave_mps=C_MPS):
    """(t1, t2, t3, t4) of one exchange over `range_m` (m): responder clock = initiator clock + `offset_s`;
    each stamp carries Gaussian jitter `stamp_sigma_s` (s)."""
    flight_s = range_m / wave_mps
    jitter = rng.normal(0.0, stamp_sigma_s, 4) if stamp_sigma_s > 0 else np.zeros(4)
    t2 = t1_s + flight_s + offset_s
    t3 = t2 + turnaround_s
    t4 = t3 - offset_s + flight_s
    return t1_s + jitter[0], t2 + jitter[1], t3 + jitter[2], t4 + jitter[3]


def range_sigma_m(stamp_sigma_s, wave_mps=C_MPS):
    """1-sigma range noise (m) of one exchange with independent stamp jitter `stamp_sigma_s` on all four stamps."""
    return wave_mps * math.sqrt(4.0) * stamp_sigma_s / 2.0


def survey_radios(layout, spacing_m, lateral_m=0.15, first_m=0.0):
    """Radios every `spacing_m` (m) along the layout, `lateral_m` (m) to the left of the track (the wayside)."""
    if spacing_m <= 0:
        raise ConfigError(f"wayside radios: spacing_m must be > 0, got {spacing_m}")
    radios = []
    s_m = first_m
    index = 0
    while s_m < layout.length_m:
        x, y, heading = (float(v) for v in layout.pose(s_m))
        radios.append(WaysideRadio(f"W{index + 1}", x - lateral_m * math.sin(heading),
                                   y + lateral_m * math.cos(heading)))
        s_m += spacing_m
        index += 1
    return radios


class WaysideRanging:
    """The range measurement to wayside radios: model h(s), noise, and a simulated measurement from the truth.

    stamp_sigma_s: timestamp jitter of the radios (default 100 ps, a UWB-class radio: 3 cm of range noise);
    max_range_m: radios farther than this are out of reach.
    """

    def __init__(self, layout, radios, stamp_sigma_s=1e-10, max_range_m=1.5, wave_mps=C_MPS):
        if not radios:
            raise ConfigError("wayside ranging: no radios given")
        self.layout = layout
        self.radios = tuple(radios)
        self.stamp_sigma_s = stamp_sigma_s
        self.max_range_m = max_range_m
        self.wave_mps = wave_mps
        self.sigma_m = range_sigma_m(stamp_sigma_s, wave_mps)
        self._xy = np.array([[r.x_m, r.y_m] for r in self.radios])

    def h(self, s_m, radio):
        """Predicted range (m) from the head at `s_m` to `radio`."""
        x, y = (float(v) for v in self.layout.xy(s_m))
        return math.hypot(x - radio.x_m, y - radio.y_m)

    def nearest(self, x_m, y_m):
        """The radio nearest to (x, y) and its distance (m)."""
        d = np.hypot(self._xy[:, 0] - x_m, self._xy[:, 1] - y_m)
        i = int(np.argmin(d))
        return self.radios[i], float(d[i])

    def measure(self, true_s_m, rng, t1_s=0.0, offset_s=None, turnaround_s=1e-4):
        """(radio, range_m) of one two-way exchange with the nearest radio in reach of the true head position, or
        None when none is in reach. The clock offset is random per exchange: the range must not depend on it."""
        x, y = (float(v) for v in self.layout.xy(true_s_m))
        radio, dist_m = self.nearest(x, y)
        if dist_m > self.max_range_m:
            return None
        if offset_s is None:
            offset_s = float(rng.uniform(-1.0, 1.0))
        stamps = exchange_timestamps(dist_m, t1_s, offset_s, turnaround_s, rng, self.stamp_sigma_s, self.wave_mps)
        return radio, two_way_range_m(*stamps, wave_mps=self.wave_mps)
