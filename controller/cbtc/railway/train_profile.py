"""Train parameters: one profile per train, with LEGO-realistic defaults (SI units)."""

import math
from dataclasses import dataclass, fields, replace

from cbtc.errors import ConfigError

STOP_WINDOW_MM = 5   # the firmware's default stop window (firmware/obu.py DEFAULTS)


@dataclass(frozen=True)
class TrainProfile:
    """Physical and sensor parameters of one LEGO train.

    Defaults: a two-car LEGO Powered-Up train with a 9 V-class motor on a NodeMCU + DRV8833, measured on the
    order of what LEGO trains do (top speed 0.3-0.8 m/s, braking 0.5-1.5 m/s^2, 0.2-0.5 m long).
    """

    length_m: float = 0.30            # head to tail
    v_max_mps: float = 0.60           # line speed ceiling
    v_noload_mps: float = 0.75        # steady speed at 100 % duty with no friction
    motor_tau_s: float = 0.25         # first-order motor + inertia time constant
    accel_max_mps2: float = 0.60      # traction limit (wheel adhesion)
    beta_s_mps2: float = 0.80         # maximum service deceleration (eq. 23's beta_s)
    beta_e_mps2: float = 1.40         # emergency deceleration: motor short-circuit brake
    friction_mps2: float = 0.08       # rolling resistance at speed (deceleration when coasting)
    counts_per_m: int = 1000          # encoder counts per metre of travel
    encoder_channels: int = 2         # 2: signed counts (the board's pin plan); 1: every edge counts up
    tail_beacon: int = 0              # 1: an IPS beacon on the last car, its fixes read by the zone; 0: none fitted
    integrity_loop: int = 1           # 1: a train line through the couplings, open once a car comes off; 0: none
    encoder_scale_error: float = 0.02 # wheel-diameter error: encoder distance = true * (1 + error)
    encoder_slip_sigma: float = 0.01  # random slip, fraction of distance travelled (1-sigma)
    ips_sigma_m: float = 0.05         # IPS noise per axis (1-sigma); see docs/fusion.md for the choice
    ips_rate_hz: float = 8.0          # IPS fix rate
    ips_latency_s: float = 0.06       # fix age when it reaches the board
    ips_dropout: float = 0.05         # probability a fix is lost
    ips_outlier: float = 0.01         # probability a fix is an outlier (0.3-1.0 m off)
    rfid_miss: float = 0.05           # probability a tag passage is not read
    rfid_range_m: float = 0.015       # a tag is read while the reader is within this distance of it
    rfid_bit_error: float = 0.002     # probability each bit of a balise's telegram is read wrong
    reaction_s: float = 0.06          # onboard reaction time counted in the braking curve (3 loops of 20 ms)

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, (int, float)) or value != value:
                raise ConfigError(f"train profile: {f.name} must be a number, got {value!r}")
        positive = ("length_m", "v_max_mps", "v_noload_mps", "motor_tau_s", "accel_max_mps2", "beta_s_mps2",
                    "beta_e_mps2", "counts_per_m", "ips_rate_hz")
        for name in positive:
            if getattr(self, name) <= 0:
                raise ConfigError(f"train profile: {name} must be > 0, got {getattr(self, name)}")
        for name in ("ips_dropout", "ips_outlier", "rfid_miss", "rfid_bit_error"):
            if not 0.0 <= getattr(self, name) < 1.0:
                raise ConfigError(f"train profile: {name} is a probability in [0, 1), got {getattr(self, name)}")
        for name in ("tail_beacon", "integrity_loop"):
            if getattr(self, name) not in (0, 1):
                raise ConfigError(f"train profile: {name} is 1 (fitted) or 0, got {getattr(self, name)}")
        if self.encoder_channels not in (1, 2):
            raise ConfigError(f"train profile: encoder_channels is 1 or 2, got {self.encoder_channels}")
        if self.v_max_mps > self.v_noload_mps:
            raise ConfigError("train profile: v_max_mps must not exceed v_noload_mps (the motor cannot reach it)")
        if self.beta_e_mps2 <= self.beta_s_mps2:
            raise ConfigError("train profile: beta_e_mps2 (emergency) must exceed beta_s_mps2 (service): the board's "
                              "service curve must stay under its trip curve")

    def with_changes(self, **changes) -> "TrainProfile":
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ConfigError(f"train profile: unknown keys {sorted(unknown)}; known: {[f.name for f in fields(self)]}")
        return replace(self, **changes)

    def stop_window_mm(self) -> int:
        """Where the board's service curve ends short of the end of authority (mm): the firmware's default, or wider
        where the reaction time would bring the service curve onto the trip curve (firmware/obu.py checks the same:
        reaction^2 dec emergency / (2 (emergency - dec))). Worked out once per profile: a zone asks it per command."""
        window_mm = self.__dict__.get("_stop_window_mm")
        if window_mm is None:
            window_mm = self._work_out_stop_window_mm()
            object.__setattr__(self, "_stop_window_mm", window_mm)   # a cache, not a field: equality ignores it
        return window_mm

    def _work_out_stop_window_mm(self) -> int:
        r_s = int(round(self.reaction_s * 1000)) / 1000
        dec, emergency = int(round(self.beta_s_mps2 * 1000)), int(round(self.beta_e_mps2 * 1000))
        need_mm = r_s * r_s * dec * emergency / (2 * (emergency - dec)) if emergency > dec else math.inf
        return max(STOP_WINDOW_MM, math.ceil(need_mm))

    def obu_config(self) -> dict:
        """The OnboardUnit configuration (integer mm / ms) that matches this profile."""
        return {
            "stop_window_mm": self.stop_window_mm(),
            "counts_per_m": int(self.counts_per_m),
            "v_max_mmps": int(round(self.v_max_mps * 1000)),
            "v_noload_mmps": int(round(self.v_noload_mps * 1000)),
            "acc_mmps2": int(round(self.accel_max_mps2 * 1000)),
            "dec_mmps2": int(round(self.beta_s_mps2 * 1000)),
            "emergency_dec_mmps2": int(round(self.beta_e_mps2 * 1000)),
            "reaction_ms": int(round(self.reaction_s * 1000)),
            "motor_tau_ms": int(round(self.motor_tau_s * 1000)),
        }
