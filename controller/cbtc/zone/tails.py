"""A train's tail as a beacon on its last car sees it: the check of its configured length, and its tail when lost.

Each fix of the tail beacon, projected on the track, is set against the head estimate at the fix's own time: one
sample of the train's length. The median of the newest samples, more than TOL_M beyond the configured length, says
the train is longer than configured (a wrong length, a car added, or a car dropped whose beacon stays with it,
standing). A tail whose fixes moved as far as the head did then reaches back to that length and the samples' spread;
any other (a dropped car standing, or a train too slow to tell) to the rear-most of its newest fixes and the spread.
A train only a few cm longer shows in the mean of the newest 40 samples (5 s): beyond 4 sigma of that mean it
reaches back that far and the 4 sigma. `extra_behind_m` is added to what the authority of the train behind takes
off. A beacon heard and then silent leaves its last fix occupied: the rear point stays there, however far the head
moves on, until the beacon is heard again. A train configured with a beacon (`TrainProfile.tail_beacon`) reaches
back over the whole track until its beacon has been heard three times; one configured without stands on its
configured length. TailWatch is pure (positions and times in, metres out); take_tail_fix feeds it a
train's fixes.
"""

from collections import deque

from cbtc.railway.ips_frame import ips_to_track
from cbtc.zone.refusals import UNKNOWN

TOL_M = 0.10        # a median length this far beyond the configured one is no IPS noise (one sample's sigma is
                    # 6 cm on the default layouts, the median's of five 3.3 cm): the train is longer
SAMPLES = 5         # newest length samples kept; their median is the measured length
SILENT_S = 1.0      # no tail fix for this long (the beacon samples at 8 Hz): the tail is lost, kept where last seen
SPREAD_M = 0.05     # what the measured length may still lie short of the true one (the fixes' noise and the head
                    # estimate's share); added when the train is found longer
LONG_SAMPLES = 40   # the length is steady: the mean of this many samples (5 s of fixes) measures it to a cm
SAMPLE_SIGMA_M = 0.03   # the least sigma a length sample is taken to have (the window's own spread, when wider)
OUTLIER_M = 0.15    # a sample this far from the long window's median is an outlier fix, left out of its mean


class TailWatch:
    def __init__(self, length_m: float, loop_m: float = None):
        self.length_m = length_m     # the configured length
        self.loop_m = loop_m         # the loop's length (None: an open line)
        self._samples = deque(maxlen=SAMPLES)   # (tail_s, head_s) of the newest fixes
        self._long = deque(maxlen=LONG_SAMPLES)   # the newest length samples, for the steady length
        self.heard_s = None          # controller time of the newest fix
        self.longer = False          # the newest verdict: longer than configured (for the zone's log)
        self._steady_m = None        # _steady_extra_m of the samples as they stand (None: not worked out since a fix)

    def see(self, t_s: float, tail_s_m: float, head_s_m: float) -> None:
        """A fix put the tail at `tail_s_m` when the head estimate was at `head_s_m` (both at controller time
        `t_s`)."""
        self._long.append(self._behind_head_m(head_s_m, tail_s_m))
        self._samples.append((tail_s_m, head_s_m))
        self.heard_s = t_s
        self._steady_m = None

    @property
    def _lengths(self) -> list:
        """The length samples of the newest SAMPLES fixes."""
        return list(self._long)[-len(self._samples):]

    @property
    def confirmed(self) -> bool:
        """Enough fixes to check the length by: until then the train's tail is not vouched for."""
        return len(self._samples) >= 3

    def extra_behind_m(self, head_s_m: float, now_s: float) -> float:
        """How much further back than its configured length the train may reach, its head estimate at `head_s_m` at
        controller time `now_s` (0.0 with no beacon, or one that agrees)."""
        if self.heard_s is None or len(self._samples) < 3:
            return 0.0
        if now_s - self.heard_s > SILENT_S:   # lost: its last fix stays occupied
            length_m = self._behind_head_m(head_s_m, self._samples[-1][0])
            self.longer = length_m + SPREAD_M > self.length_m + TOL_M
            return max(0.0, length_m + SPREAD_M - self.length_m)
        lengths = self._lengths
        median_m = sorted(lengths)[len(lengths) // 2]
        self.longer = median_m > self.length_m + TOL_M
        if not self.longer:
            return self._steady_extra_m()
        if self._moves_with_head():   # a train longer than configured: its length, measured
            return median_m + SPREAD_M - self.length_m
        # a tail that does not follow the head (a car come off) stands where its fixes put it: at the rear-most
        rear_m = max(self._behind_head_m(head_s_m, tail_s) for tail_s, _h in self._samples)
        return rear_m + SPREAD_M - self.length_m

    def _steady_extra_m(self) -> float:
        """A train a few cm longer than configured, which the median of five does not tell from noise: the mean of
        the long window's samples (outliers left out) beyond 4 sigma of that mean (the samples' own spread), and
        that 4 sigma. Worked out once a fix: every authority of the train behind asks for it."""
        if self._steady_m is None:
            self._steady_m = self._steady_of_window()
        return self._steady_m

    def _steady_of_window(self) -> float:
        window = sorted(self._long)
        if len(window) < 10:
            return 0.0
        median_m = window[len(window) // 2]
        kept = [x for x in window if abs(x - median_m) <= OUTLIER_M]
        n = len(kept)
        if n < 10:   # the samples scatter too widely to measure a steady length by (a tail on the move)
            return 0.0
        mean_m = sum(kept) / n
        sigma_m = max(SAMPLE_SIGMA_M, (sum((x - mean_m) ** 2 for x in kept) / (n - 1)) ** 0.5)
        tol_m = 4.0 * sigma_m / n ** 0.5
        excess_m = mean_m - self.length_m
        return excess_m + tol_m if excess_m > tol_m else 0.0

    def _behind_head_m(self, head_s_m, tail_s_m):
        behind_m = head_s_m - tail_s_m
        return behind_m % self.loop_m if self.loop_m else behind_m

    def _moves_with_head(self) -> bool:
        """The measured length stayed, and the head went 10 cm: the tail went as far as the head did. The medians of the
        oldest three and the newest three samples lie two of the four intervals apart, so a standing tail grows the
        length by half what the head went between them, one that follows not at all: the mark is a quarter. One
        outlier fix moves neither median."""
        samples, lengths = self._samples, self._lengths
        head_m = self._behind_head_m(samples[-1][1], samples[0][1])
        if head_m > (self.loop_m or 1e9) / 2 or head_m < 0.10 or len(lengths) < 5:
            return False
        grew_m = sorted(lengths[-3:])[1] - sorted(lengths[:3])[1]
        return abs(grew_m) < 0.25 * head_m


def tail_on_track(layout, x_m, y_m, expected_s_m, near_m=0.1):
    """The track coordinate of a tail fix at (x_m, y_m): the point nearest the tail the head puts it at
    (`expected_s_m`, within half a metre) when that lies within `near_m` of the fix, else the nearest on the whole
    track. A path that crosses itself (a figure eight) passes the fix twice; the nearest point is then the other
    pass as often as not, a tail metres away from the train's."""
    near_s = layout.project(x_m, y_m, expected_s_m, 0.5)
    nx_m, ny_m = layout.xy_m(near_s)
    if (nx_m - x_m) ** 2 + (ny_m - y_m) ** 2 <= near_m ** 2:
        return near_s
    return layout.project(x_m, y_m)


def see_tail_fix(state, layout, refusals, t_s, x_mm, y_mm):
    """Set a fix of `state`'s tail beacon (IPS frame mm, at controller time `t_s`) against its head estimate then;
    the first time it puts the tail further back than configured by more than IPS noise, say so."""
    train_id = state.train_id
    if not state.estimator.localized or state.clock.offset_s is None:
        return
    est = state.estimator.estimate(t_s)
    if est is None:
        return
    x_m, y_m = ips_to_track(x_mm / 1000.0, y_mm / 1000.0, layout.ips)
    if state.tail is None:
        state.tail = TailWatch(state.setup.profile.length_m, layout.loop_length_m)
    tail = state.tail
    was_longer = tail.longer
    tail.see(t_s, tail_on_track(layout, x_m, y_m, est.s_m - state.setup.profile.length_m), est.s_m)
    # said once the excess is past what IPS noise makes (TOL_M); a few cm more (the steady mean) is kept back from
    # in silence: it is within what a lasting IPS bias can show, and no length to correct
    if tail.extra_behind_m(est.s_m, t_s) and tail.longer and not was_longer:
        refusals.note(train_id, "tail further back", f"its tail beacon puts its tail further back than its "
                      f"configured length ({state.setup.profile.length_m:.2f} m)", t_s,
                      "the train behind keeps back from there; check the train's length in the configuration, and "
                      "whether a car has come off")


def take_tail_fix(trains, layout, refusals, train_id, t_s, x_mm, y_mm):
    """A fix of the beacon on the last car of train `train_id` (`trains`: the zone's), IPS frame mm, taken at
    controller time `t_s` (an IPS modem reports every beacon's fixes). Whatever it holds, it never stops the zone: a
    train whose check fails has no tail vouched for until its beacon is heard afresh."""
    state = trains.get(train_id)
    if state is None:
        refusals.note(UNKNOWN, "tail fix", f"a tail beacon fix for train {train_id!r}, not in this zone", t_s)
        return
    try:
        see_tail_fix(state, state.frame, refusals, t_s, x_mm, y_mm)
    except Exception as exc:
        state.tail = None
        refusals.note(train_id, "tail fix", f"checking its tail failed: {exc!r}", t_s)
