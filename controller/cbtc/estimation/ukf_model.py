"""The track UKF's model, in filterpy's grain: the state's entries, the noise, module-level `fx(x, dt_s)` and `hx_*`
with explicit `Q` and `R`, the tag read's model and the gate (cbtc.estimation.track_ukf runs the filter on it;
filterpy's UnscentedKalmanFilter on the same functions is its reference).

State `x = [s_m, v_mps, d_m, k]`:

- `s_m`: head position along the track (m), wrapped onto a loop after every step;
- `v_mps`: speed along the track (m/s);
- `d_m`: the encoder odometer (m of encoder travel), so the encoder is a plain distance measurement;
- `k`: encoder scale error, the encoder counts `(1 + k)` times the distance travelled (dimensionless). Optional:
  without it the state is `[s_m, v_mps, d_m]` and the scale is taken as exact.

Motion (`fx`): constant speed under white acceleration noise; the odometer integrates `(1 + k) v` plus wheel slip.
Measurements: the odometer `d` (linear), an IPS fix `(x, y) = layout.xy(s)` (the nonlinearity on the curves, the
reason for the UKF), and an RFID balise read `[tag s, d]` at the read. A loop's seam is handled by the residual
function of the along-track coordinate.
"""

from dataclasses import dataclass
from functools import lru_cache
from math import hypot, log1p, sqrt
from statistics import NormalDist

import numpy as np

from cbtc.protocol import wire
from cbtc.railway.geometry import circular_offset_m

# scaled unscented transform: sigma points at +-2 sigma, all mean weights positive (lambda = 0)
UT_ALPHA = 1.0
UT_BETA = 2.0
UT_KAPPA = 0.0

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


def tag_read_model(noise: NoiseModel, late_m: float, in_field: bool = False):
    """(how far the head is short of a tag at its read (m), the variance of that (m^2)). Driven into the field, the
    reader read the tag at the first poll after the head came `rfid_range_m` short of it: the read lands anywhere in
    the `late_m` the head ran since the poll before (the board says how long ago that was), uniformly. A train that
    has not moved since it was first heard may have stood in the field from the start (a boot over a tag): the head
    is then anywhere within `rfid_range_m` either side of the tag."""
    if in_field:
        return 0.0, noise.tag_var_m2 + noise.rfid_range_m ** 2 / 3.0
    late_m = abs(late_m)
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
    return np.array([hypot(float(px) - radio_x_m, float(py) - radio_y_m)])


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


def initial_covariance(n, sigma_s_m, sigma_v_mps, sigma_d_m, sigma_k):
    """Diagonal P0 for a state of dimension `n` (3 without the scale error, 4 with it)."""
    return np.diag([sigma_s_m ** 2, sigma_v_mps ** 2, sigma_d_m ** 2, sigma_k ** 2][:n])


@lru_cache(maxsize=None)
def gate_sigmas(gate_prob: float):
    """(1-D, 2-D) Mahalanobis distances holding `gate_prob` of a normal innovation: the square roots of chi-square's
    quantiles, in closed form (one degree: a normal's two-sided quantile; two: -2 ln(1 - p))."""
    return NormalDist().inv_cdf(0.5 + 0.5 * gate_prob), sqrt(-2.0 * log1p(-gate_prob))
