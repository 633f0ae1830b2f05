"""The UKF estimator's settings that are not sensor properties (those come from the TrainProfile), checked, and the
filter's noise made from both; docs/fusion.md's settings table lists them."""

from dataclasses import dataclass, fields

from cbtc.errors import ConfigError
from cbtc.estimation.ukf_model import K_HIGH, K_LOW, NoiseModel

WHEEL_LOWEST = 1.0 + K_LOW   # odometer m per true m: the least a wheel reads (and a command may state)
WHEEL_HIGHEST = 1.0 + K_HIGH  # ... and the most
SCALE_K_SIGMA = 3.0   # the scale's bounds within that band, in its sigmas


@dataclass(frozen=True)
class UkfParams:
    """Filter settings that are not sensor properties (those come from the TrainProfile); see docs/fusion.md."""

    # white-acceleration PSD: ~0.3 m/s^2 changes of acceleration per motor time constant
    accel_psd_m2ps3: float = 0.02
    scale_sigma: float = 0.03         # prior 1-sigma of the encoder scale error; 0 leaves it out of the state
    scale_walk_per_sqrt_m: float = 1e-3  # scale error drift per sqrt(metre) travelled (wear, dirt, load)
    slip_length_m: float = 0.02       # distance over which wheel slip is correlated (a wheel's roll per loop tick)
    tag_sigma_m: float = 0.002        # tag placement and reader-field spread (1-sigma)
    gate_prob: float = 0.999          # innovation gate: reject what falls outside this chi-square mass
    relocate_after: int = 8           # gated IPS fixes looked at together: where enough agree, the sensors disagree
    bias_fixes: int = 16              # newest IPS fixes whose innovations' median tells a bias of the wheel (from
    #                                   relocate_after of them on): a spin inside the speed envelope's band shows there
    locate_fixes: int = 3             # IPS fixes that must agree before the IPS alone places (or re-places) a train
    ips_bias_m: float = 0.3           # the lasting error an IPS placement may carry (multipath: a beacon's path
    #                                   reflected off a wall or a hand is tens of cm long; its noise is ips_sigma_m),
    #                                   covered until a balise confirms it
    tag_bias_m: float = 0.03          # how far a tag may lie from where the layout says (laid by hand; cbtc calibrate
    #                                   measures them to mm), covered until a second reference confirms a tag placement
    history_s: float = 2.0            # how late a measurement may arrive and still be applied at its time
    step_tol_mps: float = 0.04        # a report's speed may change this much beyond what traction or brakes allow
    step_scale_sigma: float = 0.15    # a speed step beyond that re-opens the scale to this 1-sigma (wheel slip/spin:
    #                                   3 sigma cover a wheel that reads 0.7-1.8 times the travel)
    drift_tol_mps: float = 0.02       # reported speeds may leave the motor's band (below) by this much, plus
    drift_tol_share: float = 0.03     # this share of the speed (the scale learnt, random slip)
    motor_tol: float = 0.10           # friction, traction and (until learnt) no-load speed are known within this share
    motor_learnt_tol: float = 0.04    # ... its no-load speed within this once learnt (cbtc.estimation.motor_gain)
    motor_learn_s: float = 10.0       # driving it is learnt over (s): the median of that many 1 s windows
    motor_needed_s: float = 3.0       # driving learnt before the learnt band is used (s)
    step_window_s: float = 1.0        # reported speeds are held to what the motor allows over this long (s)

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or value != value or value < 0:
                raise ConfigError(f"UKF estimator: {f.name} must be a number >= 0, got {value!r}")
        if not 0.5 < self.gate_prob < 1.0:
            raise ConfigError(f"UKF estimator: gate_prob is a probability in (0.5, 1), got {self.gate_prob}")
        if self.relocate_after < 1 or self.history_s <= 0 or not 1 <= self.locate_fixes <= self.relocate_after:
            raise ConfigError("UKF estimator: relocate_after must be >= 1, history_s > 0 and locate_fixes between 1 "
                              "and relocate_after")


def make_params(params: dict) -> UkfParams:
    known = {f.name for f in fields(UkfParams)}
    unknown = set(params) - known
    if unknown:
        raise ConfigError(f"UKF estimator: unknown settings {sorted(unknown)}; known: {sorted(known)}")
    return UkfParams(**params)


def noise_model(profile, params: UkfParams) -> NoiseModel:
    """The filter's noise from the train's sensor profile and the filter settings."""
    count_m = 1.0 / profile.counts_per_m
    return NoiseModel(
        accel_psd_m2ps3=params.accel_psd_m2ps3,
        slip_var_m2_per_m=profile.encoder_slip_sigma ** 2 * params.slip_length_m,
        scale_var_per_m=params.scale_walk_per_sqrt_m ** 2,
        odo_var_m2=(count_m ** 2 + 0.001 ** 2) / 12.0,   # one count, then integer millimetres on the wire
        ips_var_m2=profile.ips_sigma_m ** 2,
        tag_var_m2=params.tag_sigma_m ** 2,
        rfid_range_m=profile.rfid_range_m,
        gate_prob=params.gate_prob,
    )
