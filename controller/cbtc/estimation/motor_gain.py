"""A train's motor as it is today: its no-load speed as a share of the profile's, learnt while the train is driven.

A battery that runs down, a stiff gear or a heavier train change what a duty gives by more than a wheel that spins
or slides by a tenth, so a fixed band around the profile's motor (`motor_tol`) leaves such a wheel unseen by the
speed envelope (cbtc.estimation.speed_envelope). Learnt, the motor is known to a few percent (`learnt_tol`) and the
envelope narrows to that. Pure: reports in (board time, true speed as the filter reads it, duty), a gain out.

The first-order motor of cbtc.railway.physics, dv/dt = (gain duty v_noload - v) / tau - friction, averaged over a
window of driven reports, gives gain = (mean v + tau (friction + dv / T)) / (mean duty v_noload): exact whatever the
speed loop does within the window, as long as traction does not limit the train. So a window counts only when every
report in it is driven, fast enough, short of the traction limit, and read by a wheel whose scale is settled. The
gain is the median of the newest windows (`learn_s` of driving): a window that caught a wheel beginning to spin or
slide does not move it, and a battery that runs down is followed.
"""

import statistics
from collections import deque

WINDOW_S = 1.0          # a window of reports gives one sample of the gain
LEAST_MPS = 0.15        # slower, the speed measure's resolution and friction's share say too little of the motor
GAP_S = 0.1             # reports further apart break the window
GAIN_BAND = (0.5, 1.5)  # a motor outside this share of the profile's is another motor: not learnt, the profile kept


class MotorGain:
    """The motor's gain (its no-load speed over the profile's) and the band it is known within."""

    def __init__(self, profile, motor_tol: float, learnt_tol: float, learn_s: float, needed_s: float):
        self.profile = profile
        self.motor_tol = motor_tol      # the band while nothing is learnt: the profile's motor within this share
        self.learnt_tol = learnt_tol    # ... and once `needed_s` of driving is learnt
        self._needed = max(1, round(needed_s / WINDOW_S))   # windows before the learnt band is used
        self._samples = deque(maxlen=max(self._needed, round(learn_s / WINDOW_S)))
        self.reset()

    def reset(self) -> None:
        """Forget what was learnt (a wheel found spinning or sliding: the speeds before may hold some of it)."""
        self.gain = 1.0
        self._samples.clear()
        self._window = None   # [v0_mps, duty seconds, speed metres, seconds, newest v_mps] since the window began
        self._last_t_s = None

    @property
    def learnt_s(self) -> float:
        """Seconds of driving the gain rests on."""
        return len(self._samples) * WINDOW_S

    @property
    def tol(self) -> float:
        """The share of the gain the motor is known within."""
        return self.learnt_tol if len(self._samples) >= self._needed else self.motor_tol

    def observe(self, t_s: float, v_mps: float, duty_pct: float, settled: bool) -> None:
        """Offer a report: board time `t_s`, the true speed as the filter reads it `v_mps`, the mean duty over the
        interval since the report before (0 unless driven throughout); `settled`: the wheel's scale is learnt and
        nothing disagrees with it."""
        last_t_s, self._last_t_s = self._last_t_s, t_s
        p = self.profile
        # short of traction: the motor's pull at this duty, as strong as the band allows, is below the traction limit
        pull_mps2 = (duty_pct / 100.0 * p.v_noload_mps * self.gain * (1.0 + self.motor_tol) - v_mps) / p.motor_tau_s
        usable = settled and duty_pct > 0 and v_mps >= LEAST_MPS and pull_mps2 - p.friction_mps2 < p.accel_max_mps2
        window = self._window
        if not usable or window is None or not 0.0 < t_s - last_t_s <= GAP_S:
            # a window begins at a usable report after one that was not (or after a gap): not with the interval before
            self._window = [v_mps, 0.0, 0.0, 0.0, v_mps] if usable else None
            return
        dt_s = t_s - last_t_s
        window[1] += duty_pct / 100.0 * dt_s
        window[2] += 0.5 * (window[4] + v_mps) * dt_s   # the speed's mean over the interval, by the trapezoid
        window[3] += dt_s
        window[4] = v_mps
        v0_mps, duty_s, speed_m, span_s, _v = window
        if span_s < WINDOW_S:
            return
        self._window = [v_mps, 0.0, 0.0, 0.0, v_mps]
        sample = (speed_m / span_s + p.motor_tau_s * (p.friction_mps2 + (v_mps - v0_mps) / span_s)) \
            / (duty_s / span_s * p.v_noload_mps)
        if GAIN_BAND[0] <= sample <= GAIN_BAND[1]:
            self._samples.append(sample)
            self.gain = statistics.median(self._samples)
