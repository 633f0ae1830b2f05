"""What a board's reports say of its train's wheel, before the filter takes them: counts made while rolling or in a
burst taken out of the odometer the filter sees (and the position widened by them instead), and speeds that step or
drift beyond what the motor can give the train (the wheel began to slip, spin or slide: its scale is open again).

It learns the motor from the speeds it reports (cbtc.estimation.motor_gain) and holds them to what the motor allows
(cbtc.estimation.speed_envelope); what the filter knows of the wheel (its scale and the bounds of it) is read from the
filter's newest state.
"""

from math import isfinite, sqrt

from cbtc.estimation.balise_reads import wheel_band
from cbtc.estimation.motor_gain import MotorGain
from cbtc.estimation.speed_envelope import SPEED_LAG_S, SpeedEnvelope
from cbtc.estimation.ukf_model import D, K
from cbtc.estimation.ukf_params import SCALE_K_SIGMA, WHEEL_HIGHEST, WHEEL_LOWEST

ADHESION_MPS2 = 3.0   # no train stops faster than this (wheel adhesion; the board's _ADHESION_MMPS2)
MOVING_MPS = 0.05   # speeds from here up are steady enough for a step between two reports to tell of the wheel


class WheelWatch:
    def __init__(self, profile, params):
        self.profile = profile
        self.params = params
        self.odo_m = None           # the newest report's odometer, as the board counts it
        self.first_odo_m = None     # the first report's: tag reads at it may come from a train standing on the tag
        self.t_s = None             # the newest report's board time (s)
        self.top_mps = 1.5 * profile.v_noload_mps   # no train runs half again faster than its motor drives it
        self.rolled_m = 0.0         # the steps it counted while rolling, left out of the odometer the filter sees
        self.roll_run_m = 0.0       # ... of the current roll, report after report
        self.v_mps = None           # the newest report's speed
        self.duty_pct = 0           # ... and the duty it was driven at (0 unless in mode run)
        self.before = None          # (t_s, v_mps, duty_pct) of the report before it, while no step lies between
        self.envelope = SpeedEnvelope(profile, params.motor_tol, params.step_window_s)
        self.motor = MotorGain(profile, params.motor_tol, params.motor_learnt_tol, params.motor_learn_s,
                               params.motor_needed_s)
        self.speed_drifts = 0       # times reported speeds left the speed envelope (a wheel taken to spin or slide)

    def take(self, report, t_s, state, scale_sigma0):
        """(odometer m the filter sees, speed m/s, rolled m, the roll's run before m, speed step or None) of the
        decoded `report` at board time `t_s`; `state`: the filter's newest (None: unlocated), what it knows of the
        wheel, `scale_sigma0` its scale's 1-sigma while unlocated."""
        # a step the board counted while braked to a standstill (`roll`) has no sign: it is taken out of the odometer
        # the filter sees (no travel, nothing for the scale to learn) and widens the position by its length instead;
        # the part a train braking from speed surely made forward stays travel (_may_have_turned, _surely_forward_m)
        odo_m, v_mps = report["odo_mm"] / 1000.0, report["v_mmps"] / 1000.0
        if v_mps > self.top_mps or v_mps < -self.top_mps:   # faster than the motor drives: a burst or a jump
            v_mps = self.top_mps if v_mps > 0.0 else -self.top_mps
        rolled_m, run_m, burst = 0.0, self.roll_run_m, False
        if "roll" in report.get("flt", ()) and self.odo_m is not None and self._may_have_turned(t_s, v_mps, state):
            rolled_m = max(0.0, odo_m - self.odo_m - self._surely_forward_m(state, scale_sigma0))
        if rolled_m:
            self.rolled_m += rolled_m
            self.roll_run_m += rolled_m
            v_mps = 0.0
        else:
            self.roll_run_m = 0.0
            if self.odo_m is not None:
                # counts beyond what the motor can drive since the previous report (a count that caught up after
                # sticking, a burst) are not travel: taken out like a roll, and the position widened by them
                reach_m = self.top_mps * max(0.0, t_s - self.t_s) + 0.01
                excess_m = odo_m - self.odo_m - reach_m
                if excess_m > 0.0:
                    rolled_m, run_m, burst = excess_m, 0.0, True
                    self.rolled_m += excess_m
                    v_mps = min(v_mps, self.top_mps)
        # the duty the train was driven at throughout the interval: none when the board braked or drove at zero duty
        # at some pass since its last report (`undriven`), whatever it drives at now
        # (`hold`: the board drove it only to hold a roll back, not at the speed loop's duty)
        flt = report.get("flt", ())
        driven = report.get("mode") == "run" and "undriven" not in flt and "hold" not in flt
        duty_pct = report.get("duty", 0) if driven else 0
        step = self._speed_step(t_s, v_mps, duty_pct) if not rolled_m else None
        if rolled_m or step is not None:
            self.envelope.reset()
        else:
            step = self._drifted(t_s, v_mps, duty_pct if "mode" in report else None, state)
        if burst or step is not None:
            self.motor.reset()   # the speeds it learnt from may hold some of the wheel's spin or slide
        elif rolled_m:
            # counts while braked to a stand tell nothing of the motor, nor of the wheel before: the window ends there
            self.motor.observe(t_s, 0.0, 0, False)
        else:
            self.motor.observe(t_s, v_mps / (1.0 + (self.scale_error(state) or 0.0)), duty_pct,
                               self.scale_settled(state))
        self.before = None if rolled_m or step is not None or self.t_s is None else (
            self.t_s, self.v_mps, self.duty_pct)
        self.odo_m, self.t_s, self.v_mps = odo_m, t_s, v_mps
        self.duty_pct = duty_pct
        if self.first_odo_m is None:
            self.first_odo_m = odo_m
        return odo_m - self.rolled_m, v_mps, rolled_m, run_m, step

    def _least_speed_mps(self, v_mps: float, state) -> float:
        """The least true speed a board's measured `v_mps` allows: the wheel reading as long as it may, the mean
        lagging the train by SPEED_LAG_S at the adhesion limit."""
        return max(0.0, v_mps / self.scale_high(state) - ADHESION_MPS2 * SPEED_LAG_S) if v_mps else 0.0

    def _may_have_turned(self, t_s: float, v_mps: float, state) -> bool:
        """False when the train, going forward at the newest report (driven, or taken as going on), cannot have
        turned back by `t_s`, when the board measures `v_mps` (no sign): its speed cannot change by the two speeds'
        sum faster than the adhesion limit allows."""
        v0_mps = self._least_speed_mps(self.v_mps, state)
        return v0_mps <= 0.0 or v0_mps + self._least_speed_mps(v_mps, state) <= ADHESION_MPS2 * (t_s - self.t_s)

    def _surely_forward_m(self, state, scale_sigma0) -> float:
        """Odometer metres the train surely went on forward after the newest report, whatever it met since: from the
        least true speed that report's speed allows, braking at the adhesion limit. A count flagged `roll` within them
        was no roll: a train cannot turn back before it stops."""
        v_mps = self._least_speed_mps(self.v_mps, state)
        low = self.scale_low(state, SCALE_K_SIGMA, scale_sigma0)
        if not (v_mps > 0.0 and isfinite(low)):
            return 0.0
        return max(low, WHEEL_LOWEST) * v_mps * v_mps / (2.0 * ADHESION_MPS2)

    def _speed_step(self, t_s, v_mps, duty_pct):
        """(travel in doubt m, scale 1-sigma) when the speed measured since the previous report, or since the one
        before it, changed by more than traction or the brake can change a train's speed (plus `step_tol_mps`): the
        wheel began or stopped slipping or spinning, so the encoder's scale is unknown again. A step that begins
        between two reports shows half in each (and the speed loop makes up part of it), so the two intervals are
        judged together too. None when it did not, or either speed is low."""
        found = self._step_over(self.t_s, self.v_mps, self.duty_pct, t_s, v_mps, duty_pct)
        if found is None and self.before is not None:
            t0_s, v0_mps, d0_pct = self.before
            found = self._step_over(t0_s, v0_mps, min(d0_pct, self.duty_pct), t_s, v_mps, duty_pct)
        return found

    def _step_over(self, t0_s, v0_mps, d0_pct, t_s, v_mps, duty_pct):
        """The step from speed `v0_mps` at `t0_s` to `v_mps` at `t_s` (None: none): a train driven throughout (mode
        run, duty > 0 at both ends, no `undriven` pass between) slows no faster than its motor's drag at the lower
        duty and friction allow; otherwise as fast as the emergency brake."""
        if v0_mps is None or min(v0_mps, v_mps) < MOVING_MPS or t_s <= t0_s:
            return None
        dt_s = t_s - t0_s
        p = self.profile
        fall_mps2 = p.beta_e_mps2
        driven_pct = min(duty_pct, d0_pct)
        if driven_pct > 0:
            drag_mps2 = max(0.0, (v0_mps - driven_pct / 100.0 * p.v_noload_mps) / p.motor_tau_s)
            fall_mps2 = min(fall_mps2, drag_mps2 + p.friction_mps2)
        excess_mps = max(v_mps - v0_mps - p.accel_max_mps2 * dt_s, v0_mps - v_mps - fall_mps2 * dt_s)
        if excess_mps <= self.params.step_tol_mps:
            return None
        return excess_mps * dt_s, self.params.step_scale_sigma

    def _drifted(self, t_s, v_mps, duty_pct, state):
        """(travel in doubt m, scale 1-sigma) when the reported speeds, read with the scale learnt, left what the
        motor could give the train at its duties (None: not reported) over the last `step_window_s` by more than
        `drift_tol_mps` plus `drift_tol_share` of the speed (cbtc.estimation.speed_envelope): a wheel that began to
        spin or slide gradually. None while they did not."""
        scale = self.scale_error(state) or 0.0
        self.envelope.set_motor(self.motor.gain, self.motor.tol)
        found = self.envelope.observe(t_s, v_mps / (1.0 + scale), duty_pct)
        if found is None or found[0] <= self.params.drift_tol_mps + self.params.drift_tol_share * v_mps \
                or self.scale_open(state):
            return None
        self.speed_drifts += 1
        self.envelope.reset()
        excess_mps, over_s = found
        return excess_mps * over_s, self.params.step_scale_sigma

    def scale_error(self, state):
        """The encoder scale error `state` (the filter's newest, or None) has learnt (None while unlocated or when it
        is not estimated)."""
        if state is None or len(state.snap[1]) <= K:
            return None
        return float(state.snap[1][K])

    def scale_low(self, state, k_sigma: float, scale_sigma0: float) -> float:
        """A lower bound of the encoder's odometer metres per true metre in `state` (the filter's newest, or None), 1 +
        scale error - k_sigma sigma: the controller turns a distance along the track into odometer units with it, so a
        train whose encoder reads short still stops within its authority. A scale error learnt above k_sigma prior
        sigmas counts as that much (a wheel that spun for a while reads true again when it grips); 1 - k_sigma * the
        prior sigma while unlocated or not estimated; the lowest a wheel can read (the band a command may state) while
        the IPS or a balise puts the train ahead of it, or when the bound learnt falls below that band (a slip learnt as
        the scale, or a scale re-opened by a speed step: the train would stand for good, since only travel relearns it);
        not finite, it says so to the caller."""
        if state is not None and k_sigma > 0.0 and ((state.disagree is not None and state.disagree[1] > 0.0)
                                                    or (state.tag_offset is not None and state.tag_offset > 0.0)):
            return WHEEL_LOWEST   # the IPS or a balise puts the train ahead of its wheel: it may read short, by any
            #                        amount
        if state is None or len(state.snap[1]) <= K:
            return max(1.0 - k_sigma * scale_sigma0, WHEEL_LOWEST)
        _t, x, P = state.snap
        # a wheel reading long beyond its prior band is spinning, which stops when it will: not counted on
        k_m = min(float(x[K]), k_sigma * self.params.scale_sigma) if k_sigma > 0.0 else float(x[K])
        low = 1.0 + k_m - k_sigma * sqrt(max(P[K][K], 0.0))
        if k_sigma > 0.0 and isfinite(low):
            # no lower than the balises allow (wheel_band; until they vouch, or with the IPS dark, the prior band):
            # a scale the IPS taught the filter (a biased IPS teaches a wrong one) never stretches the odometer an
            # authority allows
            band = wheel_band(state.vouched, state.ips_d_m, float(x[D]), k_sigma * self.params.scale_sigma)
            low = min(low, band[0])
        return max(low, WHEEL_LOWEST) if isfinite(low) else low

    def scale_high(self, state) -> float:
        """An upper bound of the encoder's odometer metres per true metre (SCALE_K_SIGMA above the scale learnt;
        the most a wheel reads while unlocated, or when the IPS or a balise puts the train behind its wheel)."""
        if state is None or len(state.snap[1]) <= K or (state.disagree is not None and state.disagree[0] < 0.0) \
                or (state.tag_offset is not None and state.tag_offset < 0.0):
            return WHEEL_HIGHEST
        _t, x, P = state.snap
        high = 1.0 + float(x[K]) + SCALE_K_SIGMA * sqrt(max(P[K][K], 0.0))
        return min(high, WHEEL_HIGHEST) if isfinite(high) else WHEEL_HIGHEST

    def scale_settled(self, state) -> bool:
        """The wheel's scale is learnt to a quarter of the motor's learnt band, and nothing disagrees with the
        wheel: the speeds it reads tell of the motor."""
        if state is None or len(state.snap[1]) <= K or state.disagree is not None or state.tag_offset is not None \
                or state.doubt is not None:
            return False
        return float(state.snap[2][K][K]) <= (0.25 * self.params.motor_learnt_tol) ** 2

    def scale_open(self, state) -> bool:
        """The scale is still as open as a step left it (half its 1-sigma or more): a wheel already in doubt."""
        if state is None or len(state.snap[1]) <= K:
            return False
        return float(state.snap[2][K][K]) >= (0.5 * self.params.step_scale_sigma) ** 2
