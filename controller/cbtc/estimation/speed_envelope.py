"""Whether a train's reported speeds are ones its motor could have given it: a wheel that spins or slides changes
what the encoder reads by a factor, gradually enough for no single report to show it, but over a second of driving
the speed leaves what traction, the motor and the brake allow.

Pure: reports in (board time, speed as the filter believes it, duty), a verdict out. From anchors laid along the
reports (one per `ANCHOR_S`, kept `window_s`), the speed is carried forward interval by interval under the fastest
and the slowest the train could have gone at the duties it reported (the first-order motor of cbtc.railway.physics,
its no-load speed as learnt by cbtc.estimation.motor_gain, friction and traction known within `motor_tol`); the
caller takes a reported speed outside a band by more than its tolerance for a wheel that no longer reads the travel.
A report's duty is the mean over its interval; the duty of the report before counts as well, since the speed
measure lags the motor. A train braked at a stand anchors only the fastest it can go from there.
"""

from math import exp

ANCHOR_S = 0.1      # a new anchor every this many seconds of reports
JUDGE_S = 0.25      # a band is judged once this old: over shorter spans the speed measure's lag and the duty's
#                   changes between reports would pass for a wheel's
MOTOR_GAP_S = 0.065  # reports further apart than this are held to traction and the brake alone
MOVING_MPS = 0.1    # speeds from here up are steady enough to anchor and to judge (the speed measure lags below)
SPEED_LAG_S = 0.03  # a board's measured speed lags the train's at most this: half its window and a count or two


def ride_mps(v0_mps, dt_s, v_ss_mps, tau_s, up_mps2, down_mps2):
    """Speed after `dt_s` of dv/dt = (v_ss - v) / tau clamped to [-down, up], from `v0_mps` (exact, piecewise)."""
    rate = (v_ss_mps - v0_mps) / tau_s
    if rate > up_mps2:
        v_knee = v_ss_mps - up_mps2 * tau_s
        t_knee = (v_knee - v0_mps) / up_mps2
        if dt_s <= t_knee:
            return v0_mps + up_mps2 * dt_s
        v0_mps, dt_s = v_knee, dt_s - t_knee
    elif rate < -down_mps2:
        v_knee = v_ss_mps + down_mps2 * tau_s
        t_knee = (v0_mps - v_knee) / down_mps2
        if dt_s <= t_knee:
            return v0_mps - down_mps2 * dt_s
        v0_mps, dt_s = v_knee, dt_s - t_knee
    return v_ss_mps + (v0_mps - v_ss_mps) * exp(-dt_s / tau_s)


class SpeedEnvelope:
    """Anchored bounds on a train's speed from its duties; `observe` says by how much a report left them."""

    def __init__(self, profile, motor_tol: float, window_s: float):
        self.profile = profile
        self.motor_tol = motor_tol
        self.window_s = window_s
        self._anchors = []      # [t0_s, low_mps, high_mps]: the band carried from a report at t0_s (low None: not
        #                         carried, from a standstill)
        self._last = None       # (t_s, duty_pct) of the previous report
        self._gain, self._gain_tol = 1.0, motor_tol   # the motor's no-load speed over the profile's, and its band

    def set_motor(self, gain: float, gain_tol: float) -> None:
        """The motor's no-load speed is `gain` times the profile's, within `gain_tol` of it (MotorGain learns them);
        friction and traction stay known within `motor_tol`."""
        self._gain, self._gain_tol = gain, gain_tol

    def reset(self) -> None:
        """Forget the anchors (after a step was found, or speeds that mean nothing: a roll, a burst)."""
        self._anchors = []
        self._last = None

    def observe(self, t_s: float, v_mps: float, duty_pct: float):
        """Carry the bands to board time `t_s`, where the train reports `v_mps` (m/s, as the filter reads the wheel)
        driven at `duty_pct` (0 unless in mode run; None when not known); return (excess m/s, seconds it built over)
        for the largest departure from a band judged, or None while none is."""
        last = self._last
        if last is not None and t_s <= last[0]:
            return None
        worst = None
        fall_mps = rise_mps = 0.0
        if last is not None:
            # a report's duty is the mean over its interval; the speed measure lags the motor by a little of the
            # interval before, so that one's duty counts too
            t0_s, d0_pct = last
            dt_s = t_s - t0_s
            duties = (d0_pct, duty_pct)
            if None in duties or dt_s > MOTOR_GAP_S:
                # the duty is not known, or reports too far apart for their duties to tell what the motor did in
                # between (the speed loop runs every 20 ms): traction and the brake alone
                low, high = self._limits(0, 100)
            else:
                low, high = self._limits(min(duties), max(duties))
            # the measure lags: while the speed falls it reads above the train's, while it rises below, by the
            # change over SPEED_LAG_S at most; an anchor's band opens by that much (a train braked and driven on
            # again must not pass for a wheel's slide)
            fall_mps, rise_mps = _lag_mps(low, v_mps, -1.0), _lag_mps(high, v_mps, 1.0)
            for anchor in self._anchors:
                if anchor[1] is not None:
                    v0 = anchor[1]
                    anchor[1] = max(0.0, ride_mps(v0, dt_s, low[0], low[1], low[2], low[3]) if len(low) > 1
                                     else v0 + low[0] * dt_s)
                v0 = anchor[2]
                anchor[2] = (ride_mps(v0, dt_s, high[0], high[1], high[2], high[3]) if len(high) > 1
                             else v0 + high[0] * dt_s)
                if t_s - anchor[0] < JUDGE_S:
                    continue
                excess = v_mps - anchor[2]
                if v_mps >= MOVING_MPS and anchor[1] is not None:
                    excess = max(excess, anchor[1] - v_mps)
                if worst is None or excess > worst[0]:
                    worst = (excess, t_s - anchor[0])
        # a train braked through this interval and the one before, and standing, anchors the fastest it can go from
        # there (a wheel that spins as it starts); not the slowest, as the speed measure lags a start
        standing = v_mps == 0.0 and duty_pct == 0 and last is not None and last[1] == 0
        self._last = (t_s, duty_pct)
        self._anchors = [a for a in self._anchors if t_s - a[0] <= self.window_s]
        if (v_mps >= MOVING_MPS or standing) and (not self._anchors or t_s - self._anchors[-1][0] >= ANCHOR_S):
            self._anchors.append([t_s, None if standing else max(0.0, v_mps - fall_mps), v_mps + rise_mps])
        return worst

    def _limits(self, d_low_pct, d_high_pct):
        """(slowest, fastest) ways a speed can go over an interval between reports driven at these duties: each the
        arguments of ride_mps after (v0, dt), or (rate m/s^2,) for a speed changing at a constant rate."""
        p, u = self.profile, self.motor_tol
        if d_low_pct > 0:
            # driven all along: the motor pulls towards its steady speed at the duty, within the tolerances
            v_noload_mps, g = p.v_noload_mps * self._gain, self._gain_tol
            v_low = d_low_pct / 100.0 * v_noload_mps * (1.0 - g) - p.friction_mps2 * (1.0 + u) * p.motor_tau_s
            v_high = d_high_pct / 100.0 * v_noload_mps * (1.0 + g) - p.friction_mps2 * (1.0 - u) * p.motor_tau_s
            return ((v_low, p.motor_tau_s, p.accel_max_mps2 * (1.0 - u), p.beta_e_mps2),
                    (v_high, p.motor_tau_s, p.accel_max_mps2, p.beta_e_mps2))
        # not driven at one end at least: braked, coasting or driven somewhere in between, as hard as traction allows
        return (-p.beta_e_mps2,), (p.accel_max_mps2 if d_high_pct > 0 else 0.0,)


def _lag_mps(limit, v_mps: float, sign: float) -> float:
    """How far the speed can change over SPEED_LAG_S from `v_mps` the way `sign` says (-1: falling, under the slowest
    `limit` of _limits; +1: rising, under the fastest), at the rate it would start at."""
    if len(limit) == 1:
        rate = limit[0]
    else:
        v_ss, tau_s, up, down = limit
        rate = min(up, max(-down, (v_ss - v_mps) / tau_s))
    return max(0.0, sign * rate) * SPEED_LAG_S
