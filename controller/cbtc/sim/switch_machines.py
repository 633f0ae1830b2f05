"""Simulated switch machines: a switch takes time to move, and may stall, lose its detection or report the wrong
leg (the faults `switch_stall`, `switch_detection_lost`, `switch_wrong_leg`).

A machine has two faces: the leg its blades truly lie in (`physical`, None while moving: a train entering then runs
through or derails) and the leg its detector reports (`detected`, None while moving or without detection). The
interlocking commands it; the authority reads only what it detects; the truth checks read what it physically is.
"""

from dataclasses import dataclass
from math import inf

from cbtc.railway.track_graph import LEGS
from cbtc.sim.faults import SWITCH_FAULTS  # noqa: F401  (the faults a machine has)

MOVE_S = 1.0          # a servo throwing a LEGO switch: about a second end to end


@dataclass
class SwitchMachine:
    id: str
    leg: str = "straight"        # where the blades lie once a move is done
    move_s: float = MOVE_S
    target: str = None           # the leg it is moving to
    done_at_s: float = None
    fault: str = ""              # one of SWITCH_FAULTS, active from fault_at_s until fault_until_s
    fault_at_s: float = 0.0
    fault_until_s: float = inf

    def _faulty(self, name, now_s):
        return self.fault == name and self.fault_at_s <= now_s < self.fault_until_s

    def command(self, leg, now_s):
        """Move to `leg` (a move under way to another leg is redirected); nothing when already there and still."""
        if leg not in LEGS:
            raise ValueError(f"switch {self.id}: no leg {leg!r}")
        if self.target is None and leg == self.leg:
            return
        self.target, self.done_at_s = leg, now_s + self.move_s

    def step(self, now_s):
        """Complete a move whose time is up, unless the machine stalls."""
        if self.target is not None and now_s >= self.done_at_s and not self._faulty("switch_stall", now_s):
            self.leg, self.target = self.target, None

    def physical(self, now_s):
        """The leg the blades truly lie in; None while moving (a stalled move never ends)."""
        return None if self.target is not None else self.leg

    def detected(self, now_s):
        """The leg the detector reports: None while moving or with detection lost; the other leg when it lies."""
        if self.target is not None or self._faulty("switch_detection_lost", now_s):
            return None
        if self._faulty("switch_wrong_leg", now_s):
            return next(leg for leg in LEGS if leg != self.leg)
        return self.leg
