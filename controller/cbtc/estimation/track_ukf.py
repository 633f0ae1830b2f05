"""The track-constrained unscented Kalman filter of one train: the state lives along the track.

State `x = [s_m, v_mps, d_m, k]`:

- `s_m`: head position along the track (m), wrapped onto a loop after every step;
- `v_mps`: speed along the track (m/s);
- `d_m`: the encoder odometer (m of encoder travel), so the encoder is a plain distance measurement;
- `k`: encoder scale error, the encoder counts `(1 + k)` times the distance travelled (dimensionless). Optional:
  without it the state is `[s_m, v_mps, d_m]` and the scale is taken as exact.

Motion (`fx`): constant speed under white acceleration noise; the odometer integrates `(1 + k) v` plus wheel slip.
Measurements: the odometer `d` (linear), an IPS fix `(x, y) = layout.xy(s)` (the nonlinearity on the curves, the
reason for the UKF), and an RFID balise read `[tag s, d]` at the read. A loop's seam is handled by the residual
function of the along-track coordinate; outliers by a Mahalanobis gate on every IPS fix and tag read.

Filterpy's grain: module-level `fx(x, dt_s)` and `hx_*`, the real `dt_s` at every predict, explicit `Q` and `R`.
"""

import math
from dataclasses import dataclass

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter, unscented_transform
from scipy.linalg.lapack import dpotrf
from scipy.stats import chi2

from cbtc.protocol import wire
from cbtc.railway.geometry import circular_offset_m

# scaled unscented transform: sigma points at +-2 sigma, all mean weights positive (lambda = 0)
_ALPHA = 1.0
_BETA = 2.0
_KAPPA = 0.0

S, V, D, K = 0, 1, 2, 3
# the scale error a wheel can have: it reads between half and twice the travel (the band a command may state)
K_LOW, K_HIGH = wire.ODO_MM_PER_M_MIN / 1000.0 - 1.0, wire.ODO_MM_PER_M_MAX / 1000.0 - 1.0


@dataclass(frozen=True)
class NoiseModel:
    """Process and measurement noise of one train's filter (SI units, variances in m^2 unless said)."""

    accel_psd_m2ps3: float        # power spectral density of the white acceleration (m^2/s^3)
    slip_var_m2_per_m: float      # odometer slip variance gained per metre travelled
    scale_var_per_m: float        # random walk of the scale error k per metre travelled (1/m)
    odo_var_m2: float             # odometer quantisation (one count, one mm)
    ips_var_m2: float             # IPS noise per axis
    tag_var_m2: float             # tag placement and reader-field spread, before the polling spread
    rfid_range_m: float           # the reader reads a tag this far before its head reaches it
    rfid_poll_s: float            # the reader is polled once per this period: reads land up to v * poll late
    gate_prob: float              # a measurement outside this probability mass of its innovation is rejected


def fx(x, dt_s):
    """State after `dt_s` seconds at constant speed; the odometer advances by (1 + k) v dt."""
    out = np.array(x, dtype=float)
    k = x[K] if len(x) > K else 0.0
    out[S] = x[S] + x[V] * dt_s
    out[D] = x[D] + (1.0 + k) * x[V] * dt_s
    return out


def process_noise(n, dt_s, v_mps, k, noise: NoiseModel):
    """Q (n x n) of one predict over `dt_s` seconds at speed `v_mps`: white acceleration drives s, v and d alike;
    slip enters the odometer only and the scale error random-walks, both in proportion to the distance travelled."""
    dt = abs(dt_s)
    q = noise.accel_psd_m2ps3
    c = 1.0 + k
    travel_m = abs(v_mps) * dt
    Q = np.zeros((n, n))
    Q[S, S] = q * dt ** 3 / 3.0
    Q[S, V] = Q[V, S] = q * dt ** 2 / 2.0
    Q[V, V] = q * dt
    Q[S, D] = Q[D, S] = c * q * dt ** 3 / 3.0
    Q[V, D] = Q[D, V] = c * q * dt ** 2 / 2.0
    Q[D, D] = c * c * q * dt ** 3 / 3.0 + noise.slip_var_m2_per_m * travel_m
    if n > K:
        Q[K, K] = noise.scale_var_per_m * travel_m
    return Q


def tag_read_model(noise: NoiseModel, v_mps: float, in_field: bool = False):
    """(how far the head is short of a tag at its read (m), the variance of that (m^2)). Driven into the field, the
    reader, polled once per `rfid_poll_s`, reads between `rfid_range_m` before the tag and `v * rfid_poll_s` later,
    uniformly. A train that has not moved since it was first heard may have stood in the field from the start (a
    boot over a tag): the head is then anywhere within `rfid_range_m` either side of the tag."""
    if in_field:
        return 0.0, noise.tag_var_m2 + noise.rfid_range_m ** 2 / 3.0
    late_m = abs(v_mps) * noise.rfid_poll_s
    return noise.rfid_range_m - 0.5 * late_m, noise.tag_var_m2 + late_m ** 2 / 12.0


def hx_odometer(x):
    """The encoder odometer (m)."""
    return np.array([x[D]])


def hx_tag(x, rfid_offset_m):
    """What a tag read says: [tag position, odometer]. The head is `rfid_offset_m` short of the tag at the read."""
    return np.array([x[S] + rfid_offset_m, x[D]])


def hx_ips(x, layout):
    """The layout-frame (x, y) in metres of the head at `x[S]`."""
    px, py = layout.xy(x[S])
    return np.array([float(px), float(py)])


def hx_range(x, layout, radio_x_m, radio_y_m):
    """The distance (m) from the head at `x[S]` to a wayside radio at (radio_x_m, radio_y_m)."""
    px, py = layout.xy(x[S])
    return np.array([math.hypot(float(px) - radio_x_m, float(py) - radio_y_m)])


def along_track_residual(layout):
    """`a - b` for vectors whose first entry is an along-track position: on a loop it is the short way round the
    seam."""
    if not layout.closed:
        return np.subtract
    length_m = layout.length_m

    def residual(a, b):
        y = np.subtract(a, b)
        y[0] = circular_offset_m(y[0], 0.0, length_m)
        return y

    return residual


class _SigmaPoints(MerweScaledSigmaPoints):
    """Merwe's scaled sigma points built in one numpy step from LAPACK's Cholesky factor (the routine behind scipy's
    `cholesky`, called without its wrapper): the points filterpy's loop gives (x, then x + and x - each row of the
    factor), at a fraction of the cost for a state of 3 or 4."""

    def factor(self, P):
        """The upper Cholesky factor of (lambda + n) P: its row j is sigma point j's offset from the mean."""
        lambda_ = self.alpha ** 2 * (self.n + self.kappa) - self.n
        U, info = dpotrf((lambda_ + self.n) * np.asarray(P, dtype=float), lower=0, clean=1)
        if info or not math.isfinite(U.sum()):
            raise np.linalg.LinAlgError("covariance not positive definite: no sigma points")
        return U

    def sigma_points(self, x, P):
        U = self.factor(P)
        x = np.asarray(x, dtype=float)
        return np.concatenate((x[np.newaxis], x + U, x - U))


def _transform(sigmas, Wm, Wc, noise_cov):
    """filterpy's unscented_transform for plain differences: the weighted mean and covariance of the sigma points,
    plus the noise."""
    x = np.dot(Wm, sigmas)
    y = sigmas - x
    return x, (y.T * Wc) @ y + noise_cov


class _Ukf(UnscentedKalmanFilter):
    """filterpy's filter with its algebra done on whole arrays: the predict of `fx` in closed form, the cross variance
    as one product, no sigma points drawn in `predict` (TrackUkf draws them when an update needs them, after it has
    settled the state). The same steps as filterpy's (a test holds them equal to 1e-12)."""

    def predict(self, dt=None, UT=None, fx=None, **fx_args):
        """filterpy's unscented predict of `fx`, summed in closed form. `fx` is linear, with Jacobian J, but for the
        odometer's k * v dt; at the point x +- u_j (u_j: row j of the factor) that term is k v +- (k b_j + v a_j) +
        a_j b_j with a_j, b_j the k and v entries of u_j. The weighted sums over the points give the mean
        fx(x) + dt c (c = 2 W sum a_j b_j, the k-v covariance) and the covariance J P J^T + Q plus, on the odometer,
        dt^2 (W_c0 c^2 + 2 W sum (a_j b_j - c)^2): the terms the points' spread adds to the linearisation."""
        dt_s = self._dt if dt is None else dt
        x = np.array(self.x, dtype=float)
        P = self.P
        n = len(x)
        U = self.points_fn.factor(P)   # raises for a covariance with no sigma points, as drawing them would
        J = np.eye(n)
        J[S, V] = dt_s
        if n > K:
            k, v = x[K], x[V]
            J[D, V] = (1.0 + k) * dt_s
            J[D, K] = v * dt_s
            ab = U[:, K] * U[:, V]
            c = 2.0 * float(self.Wm[1]) * float(ab.sum())
            dev = ab - c
            spread = float(self.Wc[0]) * c * c + 2.0 * float(self.Wc[1]) * float(np.dot(dev, dev))
        else:
            k, v, c, spread = 0.0, x[V], 0.0, 0.0
            J[D, V] = dt_s
        x[S] += v * dt_s
        x[D] += ((1.0 + k) * v + c) * dt_s
        P = J @ P @ J.T + self.Q
        P[D, D] += dt_s * dt_s * spread
        self.x, self.P = x, P
        self.sigmas_f = None   # drawn from (x, P) when an update needs them

    def update(self, z, R=None, UT=None, hx=None, **hx_args):
        hx = self.hx if hx is None else hx
        R = self.R if R is None else R
        rows = _ALL_ROWS.get(hx)
        if rows is not None:
            sigmas_h = rows(self.sigmas_f, **hx_args)
        else:
            sigmas_h = np.atleast_2d([hx(s, **hx_args) for s in self.sigmas_f])
        self.sigmas_h = sigmas_h
        if self.residual_z is np.subtract:
            zp, self.S = _transform(sigmas_h, self.Wm, self.Wc, R)
            dz = sigmas_h - zp
        else:
            zp, self.S = unscented_transform(sigmas_h, self.Wm, self.Wc, R, self.z_mean, self.residual_z)
            dz = np.array([self.residual_z(h, zp) for h in sigmas_h])
        self.SI = self.inv(self.S)
        dx = self.sigmas_f - self.x   # the state residual is a plain difference: s is wrapped after each step
        Pxz = (self.Wc[:, np.newaxis] * dx).T @ dz
        self.K = Pxz @ self.SI
        self.y = self.residual_z(z, zp)
        self.x = self.x + self.K @ self.y
        self.P = self.P - self.K @ (self.S @ self.K.T)
        self.z = np.array(z, dtype=float)
        self._log_likelihood = self._likelihood = self._mahalanobis = None


def _hx_ips_rows(sigmas, layout):
    return layout.xy(sigmas[:, S])


def _hx_tag_rows(sigmas, rfid_offset_m):
    return np.stack((sigmas[:, S] + rfid_offset_m, sigmas[:, D]), axis=-1)


# hx -> the same measurement of every sigma point (rows of a 2-D array) in one step
_ALL_ROWS = {hx_ips: _hx_ips_rows, hx_tag: _hx_tag_rows}


def initial_covariance(n, sigma_s_m, sigma_v_mps, sigma_d_m, sigma_k):
    """Diagonal P0 for a state of dimension `n` (3 without the scale error, 4 with it)."""
    return np.diag([sigma_s_m ** 2, sigma_v_mps ** 2, sigma_d_m ** 2, sigma_k ** 2][:n])


class TrackUkf:
    """One train's filter over a layout: `predict_to(t_s)`, then an `update_*` per measurement.

    Wraps filterpy's UnscentedKalmanFilter with MerweScaledSigmaPoints. Time `t_s` is whatever clock the caller
    uses (seconds); nothing here reads a clock. `snapshot()` / `restore()` let the caller re-run measurements that
    arrived out of order.
    """

    def __init__(self, layout, noise: NoiseModel, x0, P0, t_s: float):
        self.layout = layout
        self.noise = noise
        n = len(x0)
        points = _SigmaPoints(n, alpha=_ALPHA, beta=_BETA, kappa=_KAPPA)
        self.ukf = _Ukf(dim_x=n, dim_z=1, dt=0.0, hx=hx_odometer, fx=fx, points=points)
        self.ukf.x = np.array(x0, dtype=float)
        self.ukf.P = np.array(P0, dtype=float)
        self.t_s = float(t_s)
        self._points_stale = True   # sigmas_f no longer drawn from (x, P): drawn afresh before the next update
        self._along = along_track_residual(layout)
        self._gate1 = math.sqrt(chi2.ppf(noise.gate_prob, 1))
        self._gate2 = math.sqrt(chi2.ppf(noise.gate_prob, 2))

    @property
    def x(self):
        return self.ukf.x

    @property
    def P(self):
        return self.ukf.P

    @property
    def n(self):
        return len(self.ukf.x)

    def snapshot(self):
        return (self.t_s, self.ukf.x.copy(), self.ukf.P.copy())

    def restore(self, snap):
        self.t_s, x, P = snap
        self.ukf.x = x.copy()
        self.ukf.P = P.copy()
        self._points_stale = True

    def predict_to(self, t_s: float) -> None:
        """Advance to time `t_s` (s) with the real dt; a later call with the same time is a no-op in mean and P."""
        dt_s = t_s - self.t_s
        x = self.ukf.x
        k = x[K] if self.n > K else 0.0
        self.ukf.Q = process_noise(self.n, dt_s, x[V], k, self.noise)
        self.ukf.predict(dt=dt_s)
        self.t_s = float(t_s)
        self._settle()

    def update_odometer(self, d_m: float) -> bool:
        """Fold in the encoder odometer (m) at the current time. Never gated: the encoder is the backbone. The
        odometer is a state, so the unscented update is exactly the Kalman update, done here in closed form."""
        ukf = self.ukf
        P = ukf.P
        S_m2 = P[D, D] + self.noise.odo_var_m2
        gain = P[:, D] / S_m2
        ukf.x = ukf.x + gain * (d_m - ukf.x[D])
        ukf.P = P - np.outer(gain, gain) * S_m2
        self._settle()
        return True

    def update_ips(self, x_m: float, y_m: float) -> bool:
        """Fold in an IPS fix in the layout frame (m) unless it fails the gate; True when used."""
        self.ukf.residual_z = np.subtract
        R = np.eye(2) * self.noise.ips_var_m2
        return self._gated_update(np.array([x_m, y_m]), R, self._gate2, hx_ips, layout=self.layout)

    def update_tag(self, tag_s_m: float, d_m: float, in_field: bool = False) -> bool:
        """Fold in a balise read: the tag at `tag_s_m` was read when the odometer showed `d_m`; True when used.
        `in_field`: the train may have stood in the reader's field when the read came (tag_read_model)."""
        n = self.noise
        offset_m, var_m2 = tag_read_model(n, float(self.ukf.x[V]), in_field)
        R = np.diag([var_m2, n.odo_var_m2])
        self.ukf.residual_z = self._along
        return self._gated_update(np.array([tag_s_m, d_m]), R, self._gate2, hx_tag, rfid_offset_m=offset_m)

    def update_range(self, radio_x_m: float, radio_y_m: float, range_m: float, sigma_m: float) -> bool:
        """Fold in a two-way TOA range (m, 1-sigma `sigma_m`) to a wayside radio at a surveyed position; True when
        used."""
        self.ukf.residual_z = np.subtract
        return self._gated_update(np.array([range_m]), np.array([[sigma_m ** 2]]), self._gate1, hx_range,
                                  layout=self.layout, radio_x_m=radio_x_m, radio_y_m=radio_y_m)

    def relocate(self, s_m: float, sigma_s_m: float) -> None:
        """Start the position over at `s_m` (m) with 1-sigma `sigma_s_m`, keeping speed, odometer and scale."""
        P = self.ukf.P
        P[S, :] = 0.0
        P[:, S] = 0.0
        P[S, S] = sigma_s_m ** 2
        self.ukf.x[S] = s_m
        self._settle()

    def widen_position(self, sigma_m: float) -> None:
        """Add `sigma_m` (m) of independent uncertainty to the position: a motion of known length and unknown sign."""
        self.ukf.P[S, S] += sigma_m ** 2
        self._settle()

    def hold_still(self, sigma_v_mps: float, d_m: float) -> None:
        """The train's counted motion has no sign (braked, or rolling) and is not travel: its speed is taken as 0
        (1-sigma `sigma_v_mps`) and its odometer as standing at `d_m`, both uncorrelated, so that neither is explained
        by the scale."""
        P = self.ukf.P
        for i, var in ((V, sigma_v_mps ** 2), (D, self.noise.odo_var_m2)):
            P[i, :] = 0.0
            P[:, i] = 0.0
            P[i, i] = var
        self.ukf.x[V] = 0.0
        self.ukf.x[D] = d_m
        self._settle()

    def reopen_scale(self, sigma: float) -> None:
        """Let the encoder scale be unknown again to at least 1-sigma `sigma` (its learnt value kept as the mean): the
        position then widens with the distance travelled until other sensors pin the scale. No-op without a scale."""
        if self.n > K:
            self.ukf.P[K, K] = max(float(self.ukf.P[K, K]), sigma * sigma)
            self._settle()

    def _gated_update(self, z, R, gate, hx, **hx_args) -> bool:
        self._draw_points()
        x_before, P_before = self.ukf.x.copy(), self.ukf.P.copy()
        self.ukf.update(z, R=R, hx=hx, **hx_args)
        if self.ukf.mahalanobis > gate:
            self.ukf.x, self.ukf.P = x_before, P_before
            return False   # (x, P) as before: the points drawn from them still hold
        self._settle()
        return True

    def _settle(self):
        """Keep P symmetric, s on the layout and the scale error within what a wheel can have (an odometer that
        stands while the speed does not, as in a roll, would otherwise take the scale to -1); the sigma points are
        drawn from them when an update needs them."""
        ukf = self.ukf
        ukf.P = 0.5 * (ukf.P + ukf.P.T)
        if self.n > K:
            ukf.x[K] = min(max(ukf.x[K], K_LOW), K_HIGH)
        if self.layout.closed:
            ukf.x[S] = self.layout.wrap(ukf.x[S])
        self._points_stale = True

    def _draw_points(self):
        if self._points_stale:
            self.ukf.sigmas_f = self.ukf.points_fn.sigma_points(self.ukf.x, self.ukf.P)
            self._points_stale = False
