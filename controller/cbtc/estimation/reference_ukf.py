"""filterpy's UnscentedKalmanFilter driven step for step as TrackUkf drives its own algebra: the reference that
`TrackUkf` is held equal to (tests) and timed against (`cbtc bench fusion`). Not used by the zone."""

import numpy as np
from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

from cbtc.estimation.ukf_model import (
    K_HIGH,
    K_LOW,
    UT_ALPHA,
    UT_BETA,
    UT_KAPPA,
    K,
    NoiseModel,
    S,
    V,
    along_track_residual,
    fx,
    gate_sigmas,
    hx_ips,
    hx_odometer,
    hx_range,
    hx_tag,
    process_noise,
    tag_read_model,
)


class ReferenceUkf:
    """The same filter as TrackUkf (same constructor and steps), every step done by filterpy: sigma points drawn with
    MerweScaledSigmaPoints, predict and update by UnscentedKalmanFilter, the gate on its Mahalanobis distance."""

    def __init__(self, layout, noise: NoiseModel, x0, P0, t_s: float):
        n = len(x0)
        self.layout = layout
        self.noise = noise
        self.ukf = UnscentedKalmanFilter(dim_x=n, dim_z=1, dt=0.0, hx=hx_odometer, fx=fx,
                                         points=MerweScaledSigmaPoints(n, UT_ALPHA, UT_BETA, UT_KAPPA))
        self.ukf.x = np.array(x0, dtype=float)
        self.ukf.P = np.array(P0, dtype=float)
        self.t_s = float(t_s)
        self._along = along_track_residual(layout)
        self._gate1, self._gate2 = gate_sigmas(noise.gate_prob)

    @property
    def x(self):
        return self.ukf.x

    @property
    def P(self):
        return self.ukf.P

    def predict_to(self, t_s: float) -> None:
        dt_s = t_s - self.t_s
        x = self.ukf.x
        n = len(x)
        self.ukf.Q = process_noise(n, dt_s, x[V], x[K] if n > K else 0.0, self.noise)
        self.ukf.predict(dt=dt_s)
        self.t_s = float(t_s)
        self._settle()

    def update_odometer(self, d_m: float) -> bool:
        return self._update(np.array([d_m]), np.array([[self.noise.odo_var_m2]]), None, hx_odometer, np.subtract)

    def update_ips(self, x_m: float, y_m: float) -> bool:
        return self._update(np.array([x_m, y_m]), np.eye(2) * self.noise.ips_var_m2, self._gate2, hx_ips,
                            np.subtract, layout=self.layout)

    def update_tag(self, tag_s_m: float, d_m: float, in_field: bool = False, span_s: float = 0.0) -> bool:
        offset_m, var_m2 = tag_read_model(self.noise, float(self.ukf.x[V]) * span_s, in_field)
        return self._update(np.array([tag_s_m, d_m]), np.diag([var_m2, self.noise.odo_var_m2]), self._gate2, hx_tag,
                            self._along, rfid_offset_m=offset_m)

    def update_range(self, radio_x_m: float, radio_y_m: float, range_m: float, sigma_m: float) -> bool:
        return self._update(np.array([range_m]), np.array([[sigma_m ** 2]]), self._gate1, hx_range, np.subtract,
                            layout=self.layout, radio_x_m=radio_x_m, radio_y_m=radio_y_m)

    def _update(self, z, R, gate, hx, residual, **hx_args) -> bool:
        ukf = self.ukf
        before = ukf.x.copy(), ukf.P.copy()
        ukf.sigmas_f = ukf.points_fn.sigma_points(ukf.x, ukf.P)
        ukf.residual_z = residual
        ukf.update(z, R=R, hx=hx, **hx_args)
        if gate is not None and ukf.mahalanobis > gate:
            ukf.x, ukf.P = before
            return False
        self._settle()
        return True

    def _settle(self):
        ukf = self.ukf
        ukf.P = 0.5 * (ukf.P + ukf.P.T)
        if len(ukf.x) > K:
            ukf.x[K] = min(max(ukf.x[K], K_LOW), K_HIGH)
        if self.layout.closed:
            ukf.x[S] = self.layout.wrap(ukf.x[S])
