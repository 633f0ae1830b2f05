"""Two-way time of arrival: the clock offset cancels; wayside ranges into the UKF."""

import math

import numpy as np

from cbtc.layout_files import load_layout
from cbtc.ranging import toa


def test_clock_offset_cancels_for_random_offsets():
    rng = np.random.default_rng(5)
    for _ in range(200):
        range_m = rng.uniform(0.05, 50.0)
        offset_s = rng.uniform(-100.0, 100.0)          # the radios' clocks disagree by up to 100 s
        stamps = toa.exchange_timestamps(range_m, rng.uniform(0, 10), offset_s, 1e-4, rng)
        assert abs(toa.two_way_range_m(*stamps) - range_m) < 1e-4


def test_stamp_jitter_gives_the_predicted_range_noise():
    rng = np.random.default_rng(6)
    sigma_t = 1e-10
    errs = [toa.two_way_range_m(*toa.exchange_timestamps(3.0, 0.0, 0.3, 1e-4, rng, sigma_t)) - 3.0
            for _ in range(4000)]
    # four stamps with jitter sigma_t, halved: c * sigma_t = 2.998 cm
    assert abs(np.std(errs) - toa.range_sigma_m(sigma_t)) < 0.003
    assert abs(toa.range_sigma_m(sigma_t) - 0.02998) < 1e-4


def test_measurement_model_on_a_layout():
    layout = load_layout("itb_square")
    radios = toa.survey_radios(layout, 1.0, lateral_m=0.15)
    ranging = toa.WaysideRanging(layout, radios)
    # a radio surveyed at s = 0, 0.15 m beside the track: h(0) is the lateral offset
    assert math.isclose(ranging.h(0.0, radios[0]), 0.15, abs_tol=1e-9)
    radio, measured = ranging.measure(0.0, np.random.default_rng(1))
    assert radio == radios[0] and abs(measured - 0.15) < 5 * ranging.sigma_m


def test_ukf_range_update_pulls_the_estimate_toward_truth():
    from cbtc.estimation.track_ukf import TrackUkf
    from cbtc.estimation.ukf_model import NoiseModel
    layout = load_layout("straight_test")
    noise = NoiseModel(0.02, 1e-6, 1e-6, 1e-6, 0.05 ** 2, 1e-6, 0.015, 0.999)
    f = TrackUkf(layout, noise, [1.0, 0.0, 0.0], np.diag([0.1 ** 2, 0.01, 1e-6]), 0.0)
    x, y = (float(v) for v in layout.xy(1.05))   # truth s = 1.05; radio 0.5 m further along, 0.1 m beside
    xr, yr, heading = (float(v) for v in layout.pose(1.55))
    radio = (xr - 0.1 * math.sin(heading), yr + 0.1 * math.cos(heading))
    true_range = math.hypot(x - radio[0], y - radio[1])
    f.predict_to(0.0)
    assert f.update_range(radio[0], radio[1], true_range, 0.01)
    assert abs(f.x[0] - 1.05) < 0.01 and f.P[0, 0] < 0.02 ** 2
