"""Track path geometry: a chain of straights and circular arcs, parameterised by arc length `s_m`.

Pure and vectorised (numpy): `pose(s)` maps arc length to (x, y, heading) for a float or an array; `project(x, y)`
finds the arc length of the nearest point. A closed path wraps `s` modulo its length.
"""

import math

import numpy as np


class Path:
    """A path of segments, each ('straight', length_m) or ('arc', radius_m, angle_rad) (angle > 0 turns left)."""

    def __init__(self, segments, x0_m=0.0, y0_m=0.0, heading0_rad=0.0, closed=False, sample_step_m=0.005):
        if not segments:
            raise ValueError("a path needs at least one segment")
        self.closed = closed
        starts, lengths, kinds, radii, signs = [], [], [], [], []
        xs, ys, hs = [], [], []
        x, y, h, s = x0_m, y0_m, heading0_rad, 0.0
        for seg in segments:
            starts.append(s)
            xs.append(x)
            ys.append(y)
            hs.append(h)
            if seg[0] == "straight":
                length = float(seg[1])
                kinds.append(0)
                radii.append(math.inf)
                signs.append(0.0)
                x += length * math.cos(h)
                y += length * math.sin(h)
            else:
                radius, angle = float(seg[1]), float(seg[2])
                length = radius * abs(angle)
                k = math.copysign(1.0 / radius, angle)
                kinds.append(1)
                radii.append(radius)
                signs.append(k)
                h1 = h + angle
                x += (math.sin(h1) - math.sin(h)) / k
                y -= (math.cos(h1) - math.cos(h)) / k
                h = h1
            lengths.append(length)
            s += length
        self.length_m = s
        self.end_pose = (x, y, h)
        self.start_pose = (x0_m, y0_m, heading0_rad)
        self._start = np.asarray(starts)
        self._len = np.asarray(lengths)
        self._kind = np.asarray(kinds)
        self._k = np.asarray(signs)
        self._x0 = np.asarray(xs)
        self._y0 = np.asarray(ys)
        self._h0 = np.asarray(hs)
        n = max(2, int(math.ceil(self.length_m / sample_step_m)))
        self._sample_s = np.linspace(0.0, self.length_m, n, endpoint=not closed)
        self._sample_xy = np.stack(self.pose(self._sample_s)[:2], axis=-1)

    def wrap(self, s_m):
        if self.closed:
            return np.mod(s_m, self.length_m) if isinstance(s_m, np.ndarray) else float(s_m) % self.length_m
        return np.clip(s_m, 0.0, self.length_m) if isinstance(s_m, np.ndarray) else min(max(float(s_m), 0.0), self.length_m)

    def pose(self, s_m):
        """(x_m, y_m, heading_rad) at arc length `s_m` (float or array)."""
        scalar = np.ndim(s_m) == 0
        s = np.atleast_1d(np.asarray(self.wrap(np.asarray(s_m, dtype=float)), dtype=float))
        i = np.clip(np.searchsorted(self._start, s, side="right") - 1, 0, len(self._start) - 1)
        d = s - self._start[i]
        h0 = self._h0[i]
        k = self._k[i]
        arc = self._kind[i] == 1
        safe_k = np.where(arc, k, 1.0)
        h = np.where(arc, h0 + k * d, h0)
        x = np.where(arc, self._x0[i] + (np.sin(h) - np.sin(h0)) / safe_k, self._x0[i] + d * np.cos(h0))
        y = np.where(arc, self._y0[i] - (np.cos(h) - np.cos(h0)) / safe_k, self._y0[i] + d * np.sin(h0))
        if scalar:
            return float(x[0]), float(y[0]), float(h[0])
        return x, y, h

    def xy(self, s_m):
        """Positions, shape (..., 2)."""
        x, y, _ = self.pose(s_m)
        return np.stack([x, y], axis=-1)

    def project(self, x_m, y_m, s_hint_m=None, window_m=0.5):
        """Arc length of the point of the path nearest to (x, y); with a hint, the nearest within +/- window of it."""
        d2 = (self._sample_xy[:, 0] - x_m) ** 2 + (self._sample_xy[:, 1] - y_m) ** 2
        if s_hint_m is not None:
            delta = self._sample_s - float(s_hint_m)
            if self.closed:
                delta = (delta + self.length_m / 2) % self.length_m - self.length_m / 2
            d2 = np.where(np.abs(delta) <= window_m, d2, np.inf)
            if not np.isfinite(d2).any():
                return self.project(x_m, y_m)
        s = float(self._sample_s[int(np.argmin(d2))])
        for _ in range(3):  # refine along the tangent
            px, py, h = self.pose(s)
            s = float(self.wrap(s + (x_m - px) * math.cos(h) + (y_m - py) * math.sin(h)))
        return s
