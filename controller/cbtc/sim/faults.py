"""Faults by name, injected into the simulated world (drivers, links, boards, broker), never into the controller.

A fault is written `NAME[:param=value,...]` (`cbtc sim --fault encoder_burst:train=A,at_s=20,counts=200`); `parse`
checks the name, the parameters and their values before anything runs and says what is allowed. FAULTS lists them
with their parameters and defaults; cbtc.sim.fault_effects says what each does and schedules it (`inject`).
"""

import math
from dataclasses import dataclass

from cbtc.errors import ConfigError


@dataclass(frozen=True)
class Fault:
    name: str
    params: dict

    def __str__(self):
        return self.name + (":" + ",".join(f"{k}={v}" for k, v in sorted(self.params.items())) if self.params else "")


# name -> (what it does, {parameter: default}); a default's type is the parameter's type; "train" names a train id
# (empty: the run's first train)
FAULTS = {
    "stop_dead": ("the train stops at once where it is and stays (derailed, blocked)",
                  {"train": "", "at_s": 20.0}),
    "reboot": ("the train's board restarts: a new boot id, its odometer and clock from zero",
               {"train": "", "at_s": 20.0}),
    "link_loss": ("the train's link loses this share of messages for a while (up: its reports, down: commands), each "
                  "on its own or, with burst_s > 0, in whole outages of burst_s",
                  {"train": "", "at_s": 20.0, "duration_s": 5.0, "loss": 1.0, "direction": "both", "burst_s": 0.0}),
    "link_reorder": ("the train's link holds back this share of messages by delay_s for a while, so later ones "
                     "overtake them", {"train": "", "at_s": 20.0, "duration_s": 5.0, "share": 0.3, "delay_s": 0.1,
                                       "direction": "both"}),
    "link_duplicate": ("the train's link delivers this share of messages twice for a while",
                       {"train": "", "at_s": 20.0, "duration_s": 5.0, "share": 0.3, "direction": "both"}),
    "rfid_wrong_tag": ("this share of the train's RFID reads return another tag of the layout (a misplaced or "
                       "swapped tag) for a while", {"train": "", "at_s": 20.0, "duration_s": 5.0, "share": 0.5}),
    "rollback": ("the train, standing undriven after at_s, rolls back at this speed until it has rolled this far "
                 "(brakes not holding on a slope; a drive forward holds it); a one-channel encoder counts the roll "
                 "as forward travel",
                 {"train": "", "at_s": 20.0, "distance_m": 0.2, "v_mps": 0.05}),
    "reverse_run": ("from at_s the train's motor drives it backwards (its wires swapped) until it has run this far "
                    "backwards, then forward again; a one-channel encoder counts the run as forward travel",
                    {"train": "", "at_s": 20.0, "distance_m": 0.3}),
    "length_wrong": ("the train is truly this long, where its configuration (and so the zone) says otherwise, from "
                     "the start (as far as the room behind its tail leaves, less 0.15 m)",
                     {"train": "", "length_m": 0.5}),
    "car_dropped": ("the train's last car, this long (at most the train's length less 0.1 m), comes off at at_s and "
                    "stays standing where it is; the beacon on the last car (where fitted) stays with the car, and the "
                    "train line (where fitted) opens", {"train": "", "at_s": 20.0, "length_m": 0.1}),
    "encoder_burst": ("the train's encoder counts this many spurious counts at once",
                      {"train": "", "at_s": 20.0, "counts": 200}),
    "odometer_jump": ("the train's odometer jumps once by this far (negative: back), a glitch of its count: a board "
                      "whose one-channel count goes back trips", {"train": "", "at_s": 20.0, "distance_m": 0.5}),
    "encoder_stuck": ("the train's encoder count stands still for a while, whatever the wheel does",
                      {"train": "", "at_s": 20.0, "duration_s": 5.0}),
    "ips_offset": ("the train's IPS fixes are placed this far ahead along the track for a while (multipath)",
                   {"train": "", "at_s": 20.0, "duration_s": 5.0, "offset_m": 0.5}),
    "ips_blackout": ("the train's IPS gives no fix for a while", {"train": "", "at_s": 20.0, "duration_s": 5.0}),
    "rfid_absent": ("the train's RFID reader is gone for a while", {"train": "", "at_s": 20.0, "duration_s": 5.0}),
    "encoder_scale": ("the train's encoder counts this many times the true travel for a while (slip below 1, wheel "
                      "spin above)", {"train": "", "at_s": 20.0, "duration_s": 5.0, "factor": 1.1}),
    "link_delay": ("the train's link delays every message by this much, plus jitter, for a while",
                   {"train": "", "at_s": 20.0, "duration_s": 5.0, "latency_s": 0.2, "jitter_s": 0.05,
                    "direction": "both"}),
    "broker_outage": ("the broker is down for a while; then every client reconnects",
                      {"at_s": 20.0, "duration_s": 3.0}),
    "controller_restart": ("the zone controller crashes, and a new one (a new session) starts after a while",
                           {"at_s": 20.0, "duration_s": 3.0}),
    "ips_outliers": ("this share of the train's IPS fixes are outliers (0.3-1.0 m off) for a while",
                     {"train": "", "at_s": 20.0, "duration_s": 5.0, "share": 0.5}),
    "rfid_misses": ("the train's RFID reader misses this share of tag passages for a while",
                    {"train": "", "at_s": 20.0, "duration_s": 5.0, "share": 0.5}),
    "ips_bias": ("the train's IPS fixes carry a lasting error this far along the track for a while, and its reader "
                 "misses this share of the tags meanwhile (multipath over a stretch of worn or sparse balises)",
                 {"train": "", "at_s": 20.0, "duration_s": 10.0, "offset_m": 0.2, "share": 0.8}),
    "encoder_drift": ("the train's wheel reads this many times the true travel for a while (worn, dirty), its IPS "
                      "off meanwhile: the balises alone can tell", {"train": "", "at_s": 20.0, "duration_s": 30.0,
                                                                    "factor": 1.05}),
    "boot_moved": ("the train's board restarts and, before it reports again, the train is carried this far along the "
                   "track (negative: back; as far as the trains either side leave room), as a user who lifts it and "
                   "puts it down elsewhere", {"train": "", "at_s": 20.0, "distance_m": 0.3}),
    "unknown_board": ("a board the zone was not configured for (its own id and key) is put on the track, standing, "
                      "this far ahead of the train's head (in the largest free stretch ahead if it does not fit), "
                      "and reports from then on", {"train": "", "at_s": 20.0, "distance_m": 1.0}),
    "duplicate_board": ("a spare board flashed with the train's id and key is put on the track, standing, this far "
                        "ahead of the train's head (as unknown_board), and reports from then on",
                        {"train": "", "at_s": 20.0, "distance_m": 1.0}),
    "unseen_train": ("while the zone controller is down (it crashes at at_s, a new one starts duration_s later), a "
                     "train with no working board is put on the track, standing, this far ahead of the train's head "
                     "(as unknown_board): nothing of it reaches the new zone",
                     {"train": "", "at_s": 20.0, "duration_s": 3.0, "distance_m": 1.0}),
    "switch_stall": ("on a track network, the switch's moves from at_s stall for duration_s (the blades between the "
                     "legs, no leg detected), then complete; switch: its id (empty: the layout's first)",
                     {"switch": "", "at_s": 20.0, "duration_s": 10.0}),
    "switch_detection_lost": ("on a track network, the switch's detector reports no leg from at_s for duration_s "
                              "(a cable off, a microswitch stuck open)",
                              {"switch": "", "at_s": 20.0, "duration_s": 10.0}),
    "switch_wrong_leg": ("on a track network, the switch's detector reports the other leg from at_s for duration_s "
                         "(its two detectors swapped or misadjusted)",
                         {"switch": "", "at_s": 20.0, "duration_s": 10.0}),
    "tag_moved": ("the first tag ahead of the train at at_s lies this far from where the layout (and its telegram) "
                  "says (negative: back; knocked or laid by hand; as far as its neighbours and the track's origin "
                  "leave room, less 1 cm), for the rest of the run",
                  {"train": "", "at_s": 20.0, "distance_m": 0.05}),
}
SWITCH_FAULTS = ("switch_stall", "switch_detection_lost", "switch_wrong_leg")   # on track networks only
PATH_ONLY = ("length_wrong", "car_dropped", "boot_moved", "tag_moved", "unknown_board", "duplicate_board",
             "unseen_train")   # they place a train, a car or a tag by distances along one path: not on networks yet
_DIRECTIONS = ("up", "down", "both")
_SIGNED = {("odometer_jump", "distance_m"), ("boot_moved", "distance_m"), ("unknown_board", "distance_m"),
           ("duplicate_board", "distance_m"), ("unseen_train", "distance_m"),
           ("tag_moved", "distance_m")}   # parameters that may be negative
_WORDS = {int: "a whole number", float: "a number", str: "text"}


def parse(text: str) -> Fault:
    """The Fault of `NAME[:param=value,...]`; ConfigError naming what is wrong and what is allowed."""
    name, _, rest = text.partition(":")
    if name not in FAULTS:
        raise ConfigError(f"fault {name!r} is unknown; known: {', '.join(sorted(FAULTS))}")
    defaults = FAULTS[name][1]
    params = dict(defaults)
    for item in filter(None, rest.split(",")):
        key, eq, value = item.partition("=")
        if key not in defaults or not eq:
            raise ConfigError(f"fault {name}: {item!r} is not PARAM=VALUE with PARAM one of "
                              f"{', '.join(sorted(defaults))}")
        kind = type(defaults[key])
        try:
            params[key] = kind(value)
        except ValueError:
            raise ConfigError(f"fault {name}: {key}={value!r} must be {_WORDS[kind]}") from None
        if kind is float and not math.isfinite(params[key]):
            raise ConfigError(f"fault {name}: {key}={value!r} must be a finite number")
    for key in ("at_s", "duration_s", "counts", "factor", "latency_s", "jitter_s", "burst_s", "delay_s",
                "distance_m", "length_m"):
        if key in params and params[key] < 0 and (name, key) not in _SIGNED:
            raise ConfigError(f"fault {name}: {key} must be >= 0, got {params[key]}")
    if "loss" in params and not 0.0 <= params["loss"] <= 1.0:
        raise ConfigError(f"fault {name}: loss is a share of messages in [0, 1], got {params['loss']}")
    if "share" in params and not 0.0 <= params["share"] < 1.0:
        raise ConfigError(f"fault {name}: share is a probability in [0, 1) (rfid_absent, ips_blackout: all), got "
                          f"{params['share']}")
    if name == "length_wrong" and not 0.05 <= params["length_m"] <= 5.0:
        raise ConfigError(f"fault {name}: length_m is a train's length in [0.05, 5] m, got {params['length_m']}")
    if "v_mps" in params and not 0.0 < params["v_mps"] <= 1.0:
        raise ConfigError(f"fault {name}: v_mps is a rolling speed in (0, 1] m/s, got {params['v_mps']}")
    if params.get("direction", "both") not in _DIRECTIONS:
        raise ConfigError(f"fault {name}: direction must be one of {', '.join(_DIRECTIONS)}")
    return Fault(name, params)
