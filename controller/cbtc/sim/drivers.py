"""Simulated drivers: the same duck types as firmware/drivers/, reading a virtual train's true state.

Each sensor model is where the testbed's honesty lives: the encoder drifts (wheel-diameter error, random slip) and
is quantised to whole counts; the IPS is noisy, late, drops fixes and sometimes jumps; the RFID reader misses tags
and misreads bits of their telegrams.
Randomness comes from the numpy Generator handed in, so a seed reproduces a run.
"""

from bisect import bisect_left, bisect_right
from math import cos, floor, pi, sin, sqrt

import numpy as np

from cbtc.railway import balise
from cbtc.railway.ips_frame import track_to_ips


class SimEncoder:
    """Edge counts of a slotted wheel: true distance scaled by the wheel error, plus slip, floored to counts; and the
    time of the newest edge, as the board's interrupt notes it (`age_us` after `count()`: us since that edge). Two
    channels (`profile.encoder_channels` 2, the board's pin plan) count travel backwards down (`signed`); one channel
    counts it up, as forward travel."""

    def __init__(self, profile, rng):
        self._profile = profile
        self._rng = rng
        self.signed = profile.encoder_channels == 2
        self.distance_m = 0.0  # what the wheel has rolled (with errors), not what the train travelled
        self.scale_fault = 1.0  # fault injection: counts run this many times too fast (1.0: healthy)
        self.way = 1            # the board's way of travel (it sets -1 running backwards: two channels count up)
        self.cab = 1            # which end of the train leads on its frame (-1: the wheel turns backwards)
        self._since_edge_s = 0.0
        self.age_us = 0

    def advance(self, ds_m: float, dt_s: float = 0.0, v0_mps: float = 0.0, a_mps2: float = 0.0) -> None:
        """The train travelled `ds_m` (m; negative: backwards) in truth over `dt_s` seconds, starting at `v0_mps`
        under constant `a_mps2` (what the physics step did): the newest edge's time comes from that motion."""
        self._since_edge_s += dt_s
        if ds_m == 0.0:
            return
        p = self._profile
        slip = self._rng.normal(0.0, p.encoder_slip_sigma) if p.encoder_slip_sigma > 0 else 0.0
        factor = (1.0 + p.encoder_scale_error + slip) * self.scale_fault
        # counts run down (two channels, backwards) as up on the mirrored distance: one edge timing for both
        way = -1.0 if self.signed and (ds_m < 0.0) != (self.cab * self.way < 0) else 1.0
        before = self.distance_m * way
        after = before + abs(ds_m) * factor
        self.distance_m = after * way
        newest = floor(after * p.counts_per_m)
        if dt_s <= 0.0 or newest <= floor(before * p.counts_per_m):
            return
        x_m = (newest / p.counts_per_m - before) / factor     # true travel into the step at the newest edge
        v0_mps = abs(v0_mps)
        if abs(a_mps2) < 1e-9:
            tau_s = x_m / v0_mps if v0_mps > 0 else dt_s
        else:
            tau_s = (sqrt(max(0.0, v0_mps * v0_mps + 2.0 * a_mps2 * x_m)) - v0_mps) / a_mps2
        self._since_edge_s = dt_s - min(max(tau_s, 0.0), dt_s)

    def count(self) -> int:
        self.age_us = min(int(round(self._since_edge_s * 1e6)), 1000000)
        return int(floor(self.distance_m * self._profile.counts_per_m))


class SimIps:
    """Marvelmind-like fixes in the IPS frame: sampled at a fixed rate, delivered after a latency, with noise,
    dropouts and outliers. `poll` returns the newest delivered fix as (t_ms, x_mm, y_mm, z_mm, flags)."""

    def __init__(self, profile, layout, rng, z_m: float = 0.05):
        self._profile = profile
        self._layout = layout
        self._rng = rng
        self._z_mm = int(z_m * 1000)
        self._pending = []      # (arrival_ms, x_mm, y_mm) in arrival order
        self._next_sample_ms = None
        self.last_fix_ms = None
        self.crc_errors = 0
        self.frames_ok = 0
        self.unplugged = False
        self.offset_m = 0.0     # fault injection: fixes placed this far ahead along the track (0.0: healthy)

    def use_layout(self, layout) -> None:
        """Sample on `layout` from now (a train that reverses: its beacon trails its head)."""
        self._layout = layout

    def sample(self, now_ms: int, s_m: float) -> None:
        """Called by the virtual train every loop with the true head position; samples when a fix is due."""
        p = self._profile
        period_ms = 1000.0 / p.ips_rate_hz
        if self._next_sample_ms is None:
            self._next_sample_ms = now_ms + self._rng.uniform(0, period_ms)
        while now_ms >= self._next_sample_ms:
            self._next_sample_ms += period_ms
            if self.unplugged or self._rng.random() < p.ips_dropout:
                continue
            x_m, y_m = (float(v) for v in self._layout.xy(self._layout.wrap(s_m + self.offset_m)))
            x_m += self._rng.normal(0.0, p.ips_sigma_m)
            y_m += self._rng.normal(0.0, p.ips_sigma_m)
            if self._rng.random() < p.ips_outlier:
                angle = self._rng.uniform(0, 2 * pi)
                jump_m = self._rng.uniform(0.3, 1.0)
                x_m += jump_m * cos(angle)
                y_m += jump_m * sin(angle)
            xi, yi = track_to_ips(x_m, y_m, self._layout.ips)
            arrival_ms = int(now_ms + p.ips_latency_s * 1000)
            self._pending.append((arrival_ms, int(round(xi * 1000)), int(round(yi * 1000))))

    def restart(self) -> None:
        """The board restarted and its clock begins again: the hedgehog goes on sampling, on the new clock."""
        self._pending = []
        self._next_sample_ms = None
        self.last_fix_ms = None

    def poll(self, now_ms: int):
        newest = None
        while self._pending and self._pending[0][0] <= now_ms:
            newest = self._pending.pop(0)
            self.frames_ok += 1
        if newest is None:
            return None
        self.last_fix_ms = now_ms
        return (now_ms, newest[1], newest[2], self._z_mm, 0)


class SimRfid:
    """An MFRC522 under the train's head: reads a tag while within `rfid_range_m` of it, once per passage, with misses.
    Every tag of the layout is a balise: after a read, `data` holds its telegram (cbtc.railway.balise) as 32 hex digits,
    each bit read wrong with probability `rfid_bit_error`."""

    def __init__(self, profile, layout, rng):
        self._profile = profile
        self._layout = layout
        self._rng = rng
        self._inside = {}   # uid -> True once this passage was decided (read or missed)
        self._images = {tag.uid: balise.image(i + 1, tag.s_m) for i, tag in enumerate(layout.tags)}
        self._tag_s_m = [tag.s_m for tag in layout.tags]   # sorted, as the layout keeps its tags
        self._tag_index = {tag.uid: i for i, tag in enumerate(layout.tags)}
        self.present = True
        self.wrong_tag = 0.0    # fault injection: share of reads that return another tag of the layout
        self.data = None
        self._s_m = 0.0

    def use_layout(self, layout) -> None:
        """Read the tags of `layout` from now (a train that reverses: its reader trails its head)."""
        self._layout = layout
        self._inside = {}
        self._images = {tag.uid: balise.image(i + 1, tag.s_m) for i, tag in enumerate(layout.tags)}
        self._tag_s_m = [tag.s_m for tag in layout.tags]
        self._tag_index = {tag.uid: i for i, tag in enumerate(layout.tags)}

    def sense(self, s_m: float) -> None:
        """The virtual train tells the reader where it is (true head position, m)."""
        self._s_m = s_m

    def move_tag(self, uid: str, distance_m: float) -> float:
        """Fault injection: the tag `uid` lies `distance_m` further along the track than the layout (and its telegram)
        says, as far as its neighbours and the track's origin leave room, less 1 cm (the tags stay in the layout's
        order); returns how far it moved."""
        i = self._tag_index[uid]
        positions = self._tag_s_m
        low_m = positions[i - 1] if i > 0 else 0.0
        high_m = positions[i + 1] if i + 1 < len(positions) else self._layout.length_m
        if distance_m < 0.0:
            distance_m = max(distance_m, min(0.0, low_m + 0.01 - positions[i]))
        else:
            distance_m = min(distance_m, max(0.0, high_m - 0.01 - positions[i]))
        positions[i] += distance_m
        return distance_m

    def poll(self, now_ms: int):
        self.data = None
        if not self.present:
            return None
        tags = self._layout.tags
        near = self._near()
        if not near and not self._inside:
            return None
        # in the layout's order: the tags in range, and those left since the last poll (forgotten below)
        seen = set(near)
        seen.update(self._tag_index[uid] for uid in self._inside)
        for i in sorted(seen):
            tag = tags[i]
            if i not in near:
                self._inside.pop(tag.uid, None)
                continue
            if tag.uid in self._inside:
                continue
            self._inside[tag.uid] = True
            if self._rng.random() >= self._profile.rfid_miss:
                if self.wrong_tag and len(self._layout.tags) > 1 and self._rng.random() < self.wrong_tag:
                    others = [t for t in self._layout.tags if t.uid != tag.uid]
                    tag = others[int(self._rng.integers(len(others)))]
                self.data = self._read(self._images[tag.uid])
                return tag.uid
        return None

    def _near(self):
        """Indices of the layout's tags (sorted by position) within reading range of the head, either way round a
        loop: the candidates found by bisection, then each tested exactly."""
        range_m = self._profile.rfid_range_m
        s_m = self._s_m
        positions = self._tag_s_m
        low_m, high_m = s_m - range_m, s_m + range_m
        length_m = self._layout.loop_length_m
        near = set()
        for shift_m in ((0.0, -length_m, length_m) if length_m else (0.0,)):
            first = bisect_left(positions, low_m + shift_m - 1e-9)
            end = bisect_right(positions, high_m + shift_m + 1e-9)
            if first < end:   # mostly none: a tag every metre or so, read within centimetres
                ahead_m = self._layout.ahead_m
                for i in range(first, end):
                    tag_s_m = positions[i]
                    if abs(ahead_m(tag_s_m, s_m)) <= range_m or abs(ahead_m(s_m, tag_s_m)) <= range_m:
                        near.add(i)
        return near

    def _read(self, image):
        flips = self._rng.random(len(image) * 8) < self._profile.rfid_bit_error
        if not flips.any():
            return image.hex()
        data = bytearray(image)
        for i in np.flatnonzero(flips):
            data[i >> 3] ^= 0x80 >> (i & 7)
        return bytes(data).hex()


class SimTrainLine:
    """The train line's loop through every coupling: it reads 0 while the train is whole, 1 once a car came off."""

    def __init__(self):
        self.open = False

    def value(self):
        return 1 if self.open else 0


class SimMotor:
    """Records the OnboardUnit's motor command for the physics model."""

    def __init__(self):
        self.mode = "brake"
        self.duty_pct = 0

    def drive(self, duty_pct):
        self.mode = "drive"
        self.duty_pct = max(-100, min(100, int(duty_pct)))

    def coast(self):
        self.mode = "coast"
        self.duty_pct = 0

    def brake(self):
        self.mode = "brake"
        self.duty_pct = 0
