"""Calibration arithmetic for a real train: encoder scale, IPS frame alignment, RFID tag survey. Pure functions.

- Encoder: counts per metre from measured runs (least squares through the origin over several runs).
- IPS: the rigid transform (rotation + translation, no scale) that best maps IPS fixes onto known track points
  in the least-squares sense (2-D Kabsch), in the layout's convention track = origin + R(rotation) * ips.
- Tags: where each RFID tag lies along the track, from the odometer value the board stamped on each read.
"""

import math

import numpy as np

from cbtc.errors import ConfigError
from cbtc.railway.geometry import circular_offset_m


def counts_per_m(counts, distances_m):
    """Encoder counts per metre from runs of known length: argmin_k sum (counts_i - k d_i)^2 = sum(c d) / sum(d^2)."""
    c = np.asarray(counts, dtype=float)
    d = np.asarray(distances_m, dtype=float)
    if c.shape != d.shape or c.size == 0:
        raise ConfigError("counts_per_m: give one count per measured distance, at least one run")
    if np.any(d <= 0):
        raise ConfigError("counts_per_m: every measured distance must be > 0 m")
    return float(np.dot(c, d) / np.dot(d, d))


def align_ips(ips_xy_m, track_xy_m):
    """Least-squares rigid transform from IPS points to track points (2-D Kabsch, no scale, no reflection).

    Returns (rotation_deg, origin_x_m, origin_y_m, rms_m) with track = origin + R(rotation) * ips.
    """
    p = np.asarray(ips_xy_m, dtype=float)
    q = np.asarray(track_xy_m, dtype=float)
    if p.shape != q.shape or p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 2:
        raise ConfigError("align_ips: give at least two (x, y) IPS points and as many track points")
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    a, b = p - pc, q - qc
    # the optimal angle maximises sum(b . R a): atan2 of the cross and dot sums
    cross = float(np.sum(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    dot = float(np.sum(a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    theta = math.atan2(cross, dot)
    rot = np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])
    origin = qc - rot @ pc
    residual = q - (p @ rot.T + origin)
    rms_m = float(math.sqrt(np.mean(np.sum(residual ** 2, axis=1))))
    return math.degrees(theta), float(origin[0]), float(origin[1]), rms_m


def survey_tags(reports, start_s_m=0.0, start_odo_mm=None, loop_m=None, odo_per_m=1.0, read_ahead_m=0.0):
    """Each tag's position along the track from a run's reports: where the head was at the read, from the odometer
    (`odo_per_m`: odometer metres per true metre, from the encoder calibration; 1: it reads true), plus how far short
    of a tag the head is when the reader first reads it: `read_ahead_m` (the reader's range, ahead of the head) less
    half the way the train ran since the reader's previous poll (the read's `span_ms` at the speed of the report
    carrying the read: the field's edge lies in that run).

    `reports`: decoded report dicts in order (fields `odo_mm`, `tags`, and `v_mmps` for a read's lateness);
    start_odo_mm defaults to the first report's odometer, taken where the train's head stood at start_s_m. Several
    reads of one tag are averaged (on a loop, within one lap of the first read). Returns [(uid, s_m, reads)] sorted
    by s_m.
    """
    if not odo_per_m > 0.0:
        raise ConfigError(f"survey_tags: odometer metres per metre must be > 0, got {odo_per_m}")
    reads = {}
    for report in reports:
        if start_odo_mm is None:
            start_odo_mm = report["odo_mm"]
        for entry in report.get("tags", []):   # [uid, odo_mm, t_ms, span_ms] and a balise's telegram
            uid, odo_mm = entry[0], entry[1]
            late_mm = 0.5 * abs(report.get("v_mmps", 0)) * entry[3] / 1000.0
            s_m = start_s_m + (odo_mm - late_mm - start_odo_mm) / 1000.0 / odo_per_m + read_ahead_m
            if loop_m:
                s_m %= loop_m
                first = reads.get(uid, [s_m])[0]
                s_m = first + circular_offset_m(s_m, first, loop_m)
            reads.setdefault(uid, []).append(s_m)
    found = []
    for uid, values in reads.items():
        s_m = sum(values) / len(values)
        found.append((uid, s_m % loop_m if loop_m else s_m, len(values)))
    return sorted(found, key=lambda item: item[1])


def tags_yaml(survey):
    """YAML lines for a layout's `tags:` list."""
    return "".join("  - {uid: \"%s\", s_m: %.3f}   # %d read%s\n" % (uid, s_m, n, "" if n == 1 else "s")
                   for uid, s_m, n in survey)
