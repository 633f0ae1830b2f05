"""Track path geometry: a chain of straights and circular arcs, parameterised by arc length `s_m` (metres).

Pure functions of `s_m`: `pose(s)` gives (x_m, y_m, heading_rad) for a float or a numpy array of any shape, without a
Python loop over the points; `project(x, y)` gives the arc length of the nearest point of the path, exactly (closed form
per segment), for floats or arrays. A closed path wraps `s` modulo its length; an open one clips it to [0, length].
"""

from bisect import bisect_right
from math import atan2, copysign, cos, pi, sin

import numpy as np
from numpy import ndarray

MAX_ARC_RAD = pi   # longer runs of one curvature are split, so every arc is at most a half circle


def circular_offset_m(a_m, b_m, length_m=None):
    """a - b (m) along a path: on a loop of `length_m` the shorter way round the seam (None: an open line)."""
    d = a_m - b_m
    if length_m:
        d = (d + 0.5 * length_m) % length_m - 0.5 * length_m
    return d


def forward_m(s_from_m, s_to_m, length_m=None):
    """Distance (m) going forward from `s_from_m` to `s_to_m`: in [0, length) on a loop of `length_m`, to - from on
    an open line (None)."""
    if length_m:
        return (s_to_m - s_from_m) % length_m
    return s_to_m - s_from_m


def _runs(segments):
    """Merge consecutive segments of equal curvature into runs [curvature_per_m, length_m] (0 per m on a straight)."""
    runs = []
    for seg in segments:
        if seg[0] == "straight":
            k, length = 0.0, float(seg[1])
        else:
            radius, angle = float(seg[1]), float(seg[2])
            k, length = copysign(1.0 / radius, angle), radius * abs(angle)
        if runs and runs[-1][0] == k and abs(k) * (runs[-1][1] + length) <= MAX_ARC_RAD + 1e-12:
            runs[-1][1] += length
        else:
            runs.append([k, length])
    return runs


def _pose_in(seg, d):
    """(x_m, y_m, heading_rad) at distance `d` (m) into a run `seg` = (curvature, x0, y0, heading0, centre x, y)."""
    k, x0, y0, h0, cx, cy = seg
    if k == 0.0:
        return x0 + d * cos(h0), y0 + d * sin(h0), h0
    h = h0 + k * d
    return cx + sin(h) / k, cy - cos(h) / k, h


class Path:
    """A path of segments, each ('straight', length_m) or ('arc', radius_m, angle_rad) (angle > 0 turns left).

    `segments` keeps them as given; internally consecutive segments of one curvature are merged into runs.
    """

    def __init__(self, segments, x0_m=0.0, y0_m=0.0, heading0_rad=0.0, closed=False):
        if not segments:
            raise ValueError("a path needs at least one segment")
        self.segments = tuple(segments)
        self.closed = bool(closed)
        self.start_pose = (float(x0_m), float(y0_m), float(heading0_rad))
        starts, lengths, ks, xs, ys, hs, cxs, cys = [], [], [], [], [], [], [], []
        x, y, h, s = self.start_pose[0], self.start_pose[1], self.start_pose[2], 0.0
        for k, length in _runs(self.segments):
            starts.append(s)
            lengths.append(length)
            ks.append(k)
            xs.append(x)
            ys.append(y)
            hs.append(h)
            if k == 0.0:
                cxs.append(0.0)
                cys.append(0.0)
                x += length * cos(h)
                y += length * sin(h)
            else:  # centre of the circle: one radius to the left of the heading (to the right when k < 0)
                cx, cy = x - sin(h) / k, y + cos(h) / k
                cxs.append(cx)
                cys.append(cy)
                h += k * length
                x, y = cx + sin(h) / k, cy - cos(h) / k
            s += length
        self.length_m = s
        self.end_pose = (x, y, h)
        self._starts = starts                     # Python lists for the scalar paths (bisect, projection)
        self._lens = lengths
        self._seg = tuple(zip(ks, xs, ys, hs, cxs, cys))
        # each run with the points at its two ends, as _pose_in gives them: the projection's fixed candidates
        self._seg_ends = tuple((seg, start, length, _pose_in(seg, 0.0), _pose_in(seg, length))
                               for seg, start, length in zip(self._seg, starts, lengths))
        self._start = np.asarray(starts)
        self._len = np.asarray(lengths)
        self._k = np.asarray(ks)
        self._arc = self._k != 0.0
        self._safe_k = np.where(self._arc, self._k, 1.0)
        self._x0, self._y0, self._h0 = np.asarray(xs), np.asarray(ys), np.asarray(hs)
        self._cx, self._cy = np.asarray(cxs), np.asarray(cys)

    @property
    def run_count(self):
        """Number of runs (maximal pieces of one curvature, arcs at most a half circle) the path is made of."""
        return len(self._starts)

    def wrap(self, s_m):
        """Closed: `s_m` modulo the length; open: clipped to [0, length]. Float in, float out; arrays elementwise."""
        if isinstance(s_m, ndarray):
            return np.mod(s_m, self.length_m) if self.closed else np.clip(s_m, 0.0, self.length_m)
        s = float(s_m)
        return s % self.length_m if self.closed else min(max(s, 0.0), self.length_m)

    # --- s -> pose ---------------------------------------------------------------------------------------------

    def _pose_scalar(self, s_m):
        s = self.wrap(float(s_m))
        i = max(bisect_right(self._starts, s) - 1, 0)
        return _pose_in(self._seg[i], s - self._starts[i])

    def _pose_on(self, i, d):
        """Pose at distance `d` (m) into run `i` (arrays of one shape)."""
        k, h0 = self._k[i], self._h0[i]
        h = np.where(self._arc[i], h0 + k * d, h0)
        sk = self._safe_k[i]
        x = np.where(self._arc[i], self._cx[i] + np.sin(h) / sk, self._x0[i] + d * np.cos(h0))
        y = np.where(self._arc[i], self._cy[i] - np.cos(h) / sk, self._y0[i] + d * np.sin(h0))
        return x, y, h

    def pose(self, s_m):
        """(x_m, y_m, heading_rad) at arc length `s_m`: floats for a scalar, arrays of the input's shape for an array.

        The heading is not wrapped: it accumulates from the start heading along the path (3*pi/2, not -pi/2).
        """
        if np.ndim(s_m) == 0:
            return self._pose_scalar(s_m)
        s = self.wrap(np.asarray(s_m, dtype=float))
        i = np.clip(np.searchsorted(self._start, s, side="right") - 1, 0, len(self._starts) - 1)
        return self._pose_on(i, s - self._start[i])

    def xy_m(self, s_m: float):
        """(x_m, y_m) at arc length `s_m` as two floats: the filter's measurement model asks for one point at a time."""
        x, y, _ = self._pose_scalar(s_m)
        return x, y

    def xy(self, s_m):
        """Positions in metres, shape `np.shape(s_m) + (2,)`."""
        if np.ndim(s_m) == 0:
            x, y, _ = self._pose_scalar(s_m)
            return np.array((x, y))
        x, y, _ = self.pose(s_m)
        return np.stack([x, y], axis=-1)

    # --- (x, y) -> s -------------------------------------------------------------------------------------------

    def _project_scalar(self, px, py):
        """`project` of one point over the whole path, on floats: the same candidates (each run's free minimiser
        clipped to the run, then every run's start, then every run's end) taken in the same order, so the same
        answer, ties included: the first of the nearest, as argmin takes it."""
        best_d2 = best_s = None
        starts, ends = [], []   # (distance^2, s) of each run's start and end: taken after every free candidate
        for seg, start, length, first, last in self._seg_ends:
            k, x0, y0, h0, cx, cy = seg
            if k == 0.0:
                d_free = (px - x0) * cos(h0) + (py - y0) * sin(h0)
            else:
                sign = 1.0 if k > 0.0 else -1.0
                theta0 = h0 - sign * (pi / 2)
                swept = ((atan2(py - cy, px - cx) - theta0) * sign) % (2.0 * pi)
                d_free = swept / abs(k)
            d = min(max(d_free, 0.0), length)
            qx, qy, _h = first if d == 0.0 else last if d == length else _pose_in(seg, d)
            d2 = (qx - px) ** 2 + (qy - py) ** 2
            if best_d2 is None or d2 < best_d2:
                best_d2, best_s = d2, start + d
            qx, qy, _h = first
            starts.append(((qx - px) ** 2 + (qy - py) ** 2, start + 0.0))
            qx, qy, _h = last
            ends.append(((qx - px) ** 2 + (qy - py) ** 2, start + length))
        for d2, s in starts + ends:
            if d2 < best_d2:
                best_d2, best_s = d2, s
        return self.wrap(best_s)

    def project(self, x_m, y_m, s_hint_m=None, window_m=0.5):
        """Arc length (m) of the point of the path nearest to (x_m, y_m).

        With `s_hint_m`, only the stretch within `window_m` of the hint (either way, round the seam on a loop) is
        searched, so the answer is the local solution near the hint even where another part of the track is nearer.
        Floats or broadcastable arrays; a float for scalar input.
        """
        local = s_hint_m is not None and not (self.closed and 2.0 * window_m >= self.length_m)
        if not local and isinstance(x_m, (float, int)) and isinstance(y_m, (float, int)):
            return self._project_scalar(float(x_m), float(y_m))
        scalar = np.ndim(x_m) == 0 and np.ndim(y_m) == 0 and np.ndim(s_hint_m) == 0
        x, y, hint = np.broadcast_arrays(np.asarray(x_m, dtype=float), np.asarray(y_m, dtype=float),
                                         np.asarray(s_hint_m if local else 0.0, dtype=float))
        shape = x.shape
        px, py = x.reshape(-1, 1), y.reshape(-1, 1)                      # (P, 1) against runs on axis 1
        lo, hi = self._start[None, :], (self._start + self._len)[None, :]
        if local:
            hint = self.wrap(hint.reshape(-1, 1))
            shifts = (-self.length_m, 0.0, self.length_m) if self.closed else (0.0,)
            lo = np.concatenate([np.maximum(lo, hint - window_m + sh) for sh in shifts], axis=1)
            hi = np.concatenate([np.minimum(hi, hint + window_m + sh) for sh in shifts], axis=1)
        n = len(self._starts)
        run = np.broadcast_to(np.tile(np.arange(n), lo.shape[1] // n)[None, :], np.broadcast_shapes(lo.shape, px.shape))
        start = self._start[run]
        d_lo, d_hi = lo - start, hi - start                               # the searchable stretch of each run
        usable = d_hi >= d_lo
        # free minimiser on each run: foot of the perpendicular on a straight, radial foot on an arc
        k = self._k[run]
        h0 = self._h0[run]
        along = (px - self._x0[run]) * np.cos(h0) + (py - self._y0[run]) * np.sin(h0)
        theta0 = h0 - np.sign(k) * (np.pi / 2)                             # direction centre -> run start
        theta = np.arctan2(py - self._cy[run], px - self._cx[run])
        swept = np.mod((theta - theta0) * np.sign(k), 2.0 * np.pi)
        d_free = np.where(self._arc[run], swept / np.abs(self._safe_k[run]), along)
        ends = np.stack([np.clip(d_free, d_lo, d_hi), d_lo, d_hi])       # on an arc the nearest may be an end
        qx, qy, _ = self._pose_on(run, ends)
        d2 = np.where(usable, (qx - px) ** 2 + (qy - py) ** 2, np.inf)
        count = px.shape[0]
        d2 = np.moveaxis(d2, 0, 1).reshape(count, -1)
        candidates = np.moveaxis(start + ends, 0, 1).reshape(count, -1)
        best = np.take_along_axis(candidates, np.argmin(d2, axis=1)[:, None], axis=1)[:, 0]
        s = self.wrap(best).reshape(shape)
        return float(s) if scalar else s
