"""The track-constrained unscented Kalman filter of one train: the state lives along the track (its model,
cbtc.estimation.ukf_model), outliers gated by a Mahalanobis gate on every IPS fix and tag read.

`TrackUkf` does the algebra of filterpy's UnscentedKalmanFilter on the model on Python floats (a state of 3 or 4 is
too small for numpy's per-call cost to pay); filterpy on the same model is the reference it is held equal to
(tests, `cbtc bench fusion`).
"""

from math import hypot, inf, sqrt

import numpy as np

from cbtc.estimation.ukf_model import (
    K_HIGH,
    K_LOW,
    UT_ALPHA,
    UT_BETA,
    UT_KAPPA,
    D,
    K,
    NoiseModel,
    S,
    V,
    gate_sigmas,
    tag_read_model,
)
from cbtc.railway.geometry import circular_offset_m


def cholesky_upper(P, scale=1.0):
    """The upper factor U (rows as lists) of `scale` * P, U^T U = scale P, in LAPACK dpotrf's order (the factor scipy
    gives, to rounding); its row j is sigma point j's offset from the mean. LinAlgError when P is not positive
    definite or not finite: such a covariance has no sigma points."""
    n = len(P)
    if n == 4:
        return _cholesky_upper4(P, scale)
    U = [[0.0] * n for _ in range(n)]
    for j in range(n):
        acc = scale * P[j][j]
        for k in range(j):
            acc -= U[k][j] * U[k][j]
        if not 0.0 < acc < inf:
            raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
        pivot = sqrt(acc)
        row = U[j]
        row[j] = pivot
        for i in range(j + 1, n):
            acc = scale * P[j][i]
            for k in range(j):
                acc -= U[k][j] * U[k][i]
            row[i] = acc / pivot
    return U


def _cholesky_upper4(P, scale):
    """cholesky_upper written out for a state of 4, the filter's usual one."""
    (p00, p01, p02, p03), (_, p11, p12, p13), (_, _, p22, p23), (_, _, _, p33) = P
    a = scale * p00
    if not 0.0 < a < inf:
        raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
    u00 = sqrt(a)
    u01, u02, u03 = scale * p01 / u00, scale * p02 / u00, scale * p03 / u00
    a = scale * p11 - u01 * u01
    if not 0.0 < a < inf:
        raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
    u11 = sqrt(a)
    u12, u13 = (scale * p12 - u01 * u02) / u11, (scale * p13 - u01 * u03) / u11
    a = scale * p22 - u02 * u02 - u12 * u12
    if not 0.0 < a < inf:
        raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
    u22 = sqrt(a)
    u23 = (scale * p23 - u02 * u03 - u12 * u13) / u22
    a = scale * p33 - u03 * u03 - u13 * u13 - u23 * u23
    if not 0.0 < a < inf:
        raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
    return [[u00, u01, u02, u03], [0.0, u11, u12, u13], [0.0, 0.0, u22, u23], [0.0, 0.0, 0.0, sqrt(a)]]


class TrackUkf:
    """One train's filter over a layout: `predict_to(t_s)`, then an `update_*` per measurement.

    Filterpy's UnscentedKalmanFilter with Merwe's scaled sigma points (alpha 1, beta 2, kappa 0), its sums done in
    closed form on floats: the predict of the near-linear `fx`, and the updates of measurements of the position alone
    (IPS, range), where only the two sigma points off the position's axis measure anything else than the mean does.
    Equal to the reference to rounding (a test holds it to 1e-9). Time `t_s` is whatever clock the caller uses (s);
    nothing here reads a clock. `snapshot()` / `restore()` let the caller re-run measurements that arrived out of
    order. `mean` and `cov` are the state and covariance as lists; `x` and `P` the same as numpy arrays.
    """

    def __init__(self, layout, noise: NoiseModel, x0, P0, t_s: float):
        self.layout = layout
        self.noise = noise
        self.mean = [float(v) for v in x0]
        P0 = [[float(v) for v in row] for row in P0]
        self.cov = [[0.5 * (a + b) for a, b in zip(row, col)] for row, col in zip(P0, zip(*P0))]
        self.t_s = float(t_s)
        n = len(self.mean)
        lambda_ = UT_ALPHA ** 2 * (n + UT_KAPPA) - n
        self._spread = n + lambda_              # the points sit at x +- the rows of the factor of spread * P
        self._wm0 = lambda_ / (n + lambda_)     # the mean's weights: the centre, then each other point
        self._wc0 = self._wm0 + 1.0 - UT_ALPHA ** 2 + UT_BETA   # ... and the covariance's for the centre
        self._w = 0.5 / (n + lambda_)
        self._loop_m = layout.loop_length_m
        self._closed = layout.closed
        self._gate1, self._gate2 = gate_sigmas(noise.gate_prob)

    @property
    def x(self):
        return np.array(self.mean)

    @property
    def P(self):
        return np.array(self.cov)

    @property
    def n(self):
        return len(self.mean)

    def snapshot(self):
        return (self.t_s, tuple(self.mean), tuple(map(tuple, self.cov)))

    def restore(self, snap):
        self.t_s, x, P = snap
        self.mean = list(x)
        self.cov = [list(row) for row in P]

    def predict_to(self, t_s: float) -> None:
        """Advance to time `t_s` (s) with the real dt; a later call with the same time is a no-op in mean and P.

        filterpy's unscented predict of `fx`, summed in closed form. `fx` is linear, with Jacobian J, but for the
        odometer's k * v dt; at the point x +- u_j (u_j: row j of the factor) that term is k v +- (k b_j + v a_j) +
        a_j b_j with a_j, b_j the k and v entries of u_j. The weighted sums over the points give the mean fx(x) + dt c
        (c = 2 W sum a_j b_j, the k-v covariance) and the covariance J P J^T + Q plus, on the odometer, dt^2 (W_c0 c^2
        + 2 W sum (a_j b_j - c)^2): the terms the points' spread adds to the linearisation."""
        dt_s = t_s - self.t_s
        x, P = self.mean, self.cov
        n = len(x)
        U = cholesky_upper(P, self._spread)   # raises for a covariance with no sigma points, as drawing them would
        v = x[V]
        (pss, psv, psd, *sk), (_, pvv, pvd, *vk), (_, _, pdd, *dk) = P[:3]
        if n > K:
            k = x[K]
            psk, pvk, pdk, pkk = sk[0], vk[0], dk[0], P[K][K]
            ab0, ab1 = U[0][K] * U[0][V], U[1][K] * U[1][V]   # rows 2 and 3 have no v entry (upper triangular)
            c = 2.0 * self._w * (ab0 + ab1)
            spread = self._wc0 * c * c + 2.0 * self._w * ((ab0 - c) ** 2 + (ab1 - c) ** 2 + 2.0 * c * c)
        else:
            k, c, spread = 0.0, 0.0, 0.0
            psk = pvk = pdk = pkk = 0.0
        gain = 1.0 + k
        a, b = gain * dt_s, v * dt_s   # J[D, V] and J[D, K]; J[S, V] = dt
        # Q: white acceleration drives s, v and d alike; slip and the scale's walk grow with the distance travelled
        noise = self.noise
        q = noise.accel_psd_m2ps3
        adt = abs(dt_s)
        q3, q2, q1 = q * adt ** 3 / 3.0, q * adt ** 2 / 2.0, q * adt
        travel_m = abs(v) * adt
        # J P J^T + Q, entry by entry (J: s += v dt, d += (1 + k) v dt)
        dv = pvd + a * pvv + b * pvk            # (J P J^T)[V, D]
        ss = pss + 2.0 * dt_s * psv + dt_s * dt_s * pvv + q3
        sv = psv + dt_s * pvv + q2
        sd = psd + a * psv + b * psk + dt_s * dv + gain * q3
        vv = pvv + q1
        vd = dv + gain * q2
        dd = (pdd + a * a * pvv + b * b * pkk + 2.0 * (a * pvd + b * pdk + a * b * pvk)
              + gain * gain * q3 + noise.slip_var_m2_per_m * travel_m + dt_s * dt_s * spread)
        if n > K:
            sk_ = psk + dt_s * pvk
            dk_ = pdk + a * pvk + b * pkk
            kk = pkk + noise.scale_var_per_m * travel_m
            self.cov = [[ss, sv, sd, sk_], [sv, vv, vd, pvk], [sd, vd, dd, dk_], [sk_, pvk, dk_, kk]]
        else:
            self.cov = [[ss, sv, sd], [sv, vv, vd], [sd, vd, dd]]
        x[S] += v * dt_s
        x[D] += (gain * v + c) * dt_s
        self.t_s = float(t_s)
        self._settle()

    def update_odometer(self, d_m: float) -> bool:
        """Fold in the encoder odometer (m) at the current time. Never gated: the encoder is the backbone. The
        odometer is a state, so the unscented update is exactly the Kalman update, done here in closed form."""
        x, P = self.mean, self.cov
        s_m2 = P[D][D] + self.noise.odo_var_m2
        y = float(d_m) - x[D]
        if len(x) == 4:   # the usual state, written out: the same operations in the same order as below
            r0, r1, r2, r3 = P
            g0, g1, g2, g3 = r0[D] / s_m2, r1[D] / s_m2, r2[D] / s_m2, r3[D] / s_m2
            self.mean = [x[0] + g0 * y, x[1] + g1 * y, x[2] + g2 * y, x[3] + g3 * y]
            h0, h1, h2, h3 = g0 * s_m2, g1 * s_m2, g2 * s_m2, g3 * s_m2
            self.cov = [[r0[0] - h0 * g0, r0[1] - h0 * g1, r0[2] - h0 * g2, r0[3] - h0 * g3],
                        [r1[0] - h1 * g0, r1[1] - h1 * g1, r1[2] - h1 * g2, r1[3] - h1 * g3],
                        [r2[0] - h2 * g0, r2[1] - h2 * g1, r2[2] - h2 * g2, r2[3] - h2 * g3],
                        [r3[0] - h3 * g0, r3[1] - h3 * g1, r3[2] - h3 * g2, r3[3] - h3 * g3]]
        else:
            gains = [row[D] / s_m2 for row in P]
            self.mean = [xi + g * y for xi, g in zip(x, gains)]
            self.cov = [[p - gs * h for p, h in zip(row, gains)] for row, gs in zip(P, [g * s_m2 for g in gains])]
        self._settle()
        return True

    def update_ips(self, x_m: float, y_m: float) -> bool:
        """Fold in an IPS fix in the layout frame (m) unless it fails the gate; True when used."""
        var = self.noise.ips_var_m2
        return self._position_update(self.layout.xy_m, (float(x_m), float(y_m)), ((var, 0.0), (0.0, var)),
                                     self._gate2)

    def update_tag(self, tag_s_m: float, d_m: float, in_field: bool = False, span_s: float = 0.0) -> bool:
        """Fold in a balise read: the tag at `tag_s_m` was read when the odometer showed `d_m`, `span_s` seconds after
        the reader's previous poll (the head ran the filter's speed times that in between); True when used.
        `in_field`: the train may have stood in the reader's field when the read came (tag_read_model). The read is
        linear in the state ([s + offset, d]), so the unscented sums are exactly those of the Kalman update, taken
        along the track (the short way round a loop's seam)."""
        x, P = self.mean, self.cov
        cholesky_upper(P, self._spread)   # a covariance with no sigma points raises, as drawing them would
        offset_m, var_m2 = tag_read_model(self.noise, x[V] * span_s, in_field)
        s_m2 = ((P[S][S] + var_m2, P[S][D]), (P[D][S], P[D][D] + self.noise.odo_var_m2))
        cross = [(row[S], row[D]) for row in P]
        y = (circular_offset_m(tag_s_m - (x[S] + offset_m), 0.0, self._loop_m), d_m - x[D])
        return self._kalman(cross, s_m2, y, self._gate2)

    def update_range(self, radio_x_m: float, radio_y_m: float, range_m: float, sigma_m: float) -> bool:
        """Fold in a two-way TOA range (m, 1-sigma `sigma_m`) to a wayside radio at a surveyed position; True when
        used."""
        xy_m = self.layout.xy_m

        def distance(s_m):
            px, py = xy_m(s_m)
            return (hypot(px - radio_x_m, py - radio_y_m),)

        return self._position_update(distance, (range_m,), ((sigma_m ** 2,),), self._gate1)

    def relocate(self, s_m: float, sigma_s_m: float) -> None:
        """Start the position over at `s_m` (m) with 1-sigma `sigma_s_m`, keeping speed, odometer and scale."""
        P = self.cov
        for row in P:
            row[S] = 0.0
        P[S] = [0.0] * len(P)
        P[S][S] = sigma_s_m ** 2
        self.mean[S] = s_m
        self._settle()

    def widen_position(self, sigma_m: float) -> None:
        """Add `sigma_m` (m) of independent uncertainty to the position: a motion of known length and unknown sign."""
        self.cov[S][S] += sigma_m ** 2
        self._settle()

    def hold_still(self, sigma_v_mps: float, d_m: float) -> None:
        """The train's counted motion has no sign (braked, or rolling) and is not travel: its speed is taken as 0
        (1-sigma `sigma_v_mps`) and its odometer as standing at `d_m`, both uncorrelated, so that neither is explained
        by the scale."""
        P = self.cov
        for i, var in ((V, sigma_v_mps ** 2), (D, self.noise.odo_var_m2)):
            for row in P:
                row[i] = 0.0
            P[i] = [0.0] * len(P)
            P[i][i] = var
        self.mean[V] = 0.0
        self.mean[D] = d_m
        self._settle()

    def reopen_scale(self, sigma: float) -> None:
        """Let the encoder scale be unknown again to at least 1-sigma `sigma` (its learnt value kept as the mean): the
        position then widens with the distance travelled until other sensors pin the scale. No-op without a scale."""
        if self.n > K:
            self.cov[K][K] = max(self.cov[K][K], sigma * sigma)
            self._settle()

    def _position_update(self, h, z, R, gate) -> bool:
        """filterpy's unscented update for a measurement `h(s)` of the position alone (a tuple of floats). The factor
        is upper triangular, so every sigma point but x +- u_0 has the mean's position and measures h(s): the sums
        over the points take three values of h."""
        x = self.mean
        u0 = cholesky_upper(self.cov, self._spread)[0]
        s_m = x[S]
        w, wc0, wm0 = self._w, self._wc0, self._wm0
        same = 2 * len(x) - 2   # the points off the position's axis
        h0, hp, hm = h(s_m), h(s_m + u0[S]), h(s_m - u0[S])
        if len(z) == 1:
            (a0,), (b0,), (c0,) = h0, hp, hm
            zp = wm0 * a0 + w * (b0 + c0 + same * a0)
            e0, ep, em = a0 - zp, b0 - zp, c0 - zp
            s_m2 = ((wc0 * e0 * e0 + w * (ep * ep + em * em + same * e0 * e0) + R[0][0],),)
            dh = w * (b0 - c0)
            return self._kalman([(u * dh,) for u in u0], s_m2, (z[0] - zp,), gate)
        (a0, a1), (b0, b1), (c0, c1) = h0, hp, hm
        zp0 = wm0 * a0 + w * (b0 + c0 + same * a0)
        zp1 = wm0 * a1 + w * (b1 + c1 + same * a1)
        e0, ep0, em0 = a0 - zp0, b0 - zp0, c0 - zp0
        e1, ep1, em1 = a1 - zp1, b1 - zp1, c1 - zp1
        s00 = wc0 * e0 * e0 + w * (ep0 * ep0 + em0 * em0 + same * e0 * e0) + R[0][0]
        s01 = wc0 * e0 * e1 + w * (ep0 * ep1 + em0 * em1 + same * e0 * e1) + R[0][1]
        s11 = wc0 * e1 * e1 + w * (ep1 * ep1 + em1 * em1 + same * e1 * e1) + R[1][1]
        dh0, dh1 = w * (b0 - c0), w * (b1 - c1)
        return self._kalman([(u * dh0, u * dh1) for u in u0], ((s00, s01), (s01, s11)), (z[0] - zp0, z[1] - zp1),
                            gate)

    def _kalman(self, cross, s_m2, y, gate) -> bool:
        """The update from the state-measurement cross covariance, the innovation covariance and the innovation
        (one or two entries), unless the innovation's Mahalanobis distance exceeds `gate` (or is not a number):
        then nothing changes. True when used."""
        x, P = self.mean, self.cov
        if len(y) == 1:
            (s_m2,), = s_m2
            (y0,) = y
            if not y0 * y0 / s_m2 <= gate * gate:
                return False
            gains = [c0 / s_m2 for (c0,) in cross]
            self.mean = [xi + g * y0 for xi, g in zip(x, gains)]
            self.cov = [[p - gs * h for p, h in zip(row, gains)] for row, gs in zip(P, [g * s_m2 for g in gains])]
            self._settle()
            return True
        (a, b), (c, d) = s_m2
        det = a * d - b * c
        i00, i01, i10, i11 = d / det, -b / det, -c / det, a / det
        y0, y1 = y
        if not y0 * (i00 * y0 + i01 * y1) + y1 * (i10 * y0 + i11 * y1) <= gate * gate:
            return False
        gains = [(c0 * i00 + c1 * i10, c0 * i01 + c1 * i11) for c0, c1 in cross]
        self.mean = [xi + g0 * y0 + g1 * y1 for xi, (g0, g1) in zip(x, gains)]
        n = len(x)
        P = [list(row) for row in P]
        for i in range(n):
            g0, g1 = gains[i]
            s0, s1 = g0 * a + g1 * c, g0 * b + g1 * d   # row i of (gain S)
            row = P[i]
            for j in range(i, n):
                h0, h1 = gains[j]
                row[j] = P[j][i] = row[j] - (s0 * h0 + s1 * h1)
        self.cov = P
        self._settle()
        return True

    def _settle(self):
        """Keep s on the layout and the scale error within what a wheel can have (an odometer that stands while the
        speed does not, as in a roll, would otherwise take the scale to -1). P stays symmetric: every step builds it
        so."""
        x = self.mean
        if len(x) > K:
            x[K] = min(max(x[K], K_LOW), K_HIGH)
        if self._closed:
            x[S] = x[S] % self._loop_m
