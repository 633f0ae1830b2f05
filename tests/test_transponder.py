"""Correlation receiver, two-way ranging, reply data, BER, running mean and the simulator's sensor model."""

import numpy as np

from cbtc.ranging import transponder as tp


def test_noise_free_receiver_reads_sub_chip_delay_exactly():
    code = tp.bipolar(tp.gold_code(10, tp.MASTER_CODE))
    delays = np.array([0.0, 3.25, 100.5, 1022.9])
    est = tp.find_delay_chips(tp.delayed(code, delays), code)
    assert np.allclose(tp.wrap_error(est, delays, len(code)), 0.0, atol=1e-9)


def test_receiver_within_one_chip_at_the_reported_threshold_with_two_other_codes():
    threshold_db, _curve = tp.threshold_snr_db(10, np.random.default_rng(11), trials=300)
    assert threshold_db is not None and -20.0 <= threshold_db <= -8.0
    # a fresh seeded batch at that SNR, two other trains' Gold codes present
    err = tp.one_way_trials(10, threshold_db, 400, np.random.default_rng(12), n_others=2)
    assert np.mean(np.abs(err) <= 1.0) >= 0.98


def test_two_way_range_subtracts_turnaround_and_averages_both_receivers():
    rng = np.random.default_rng(3)
    chip_rate = 1e9
    ranges = tp.two_way_trials(1.234, 10, 10.0, 200, rng, chip_rate)
    # at +10 dB: unbiased within a centimetre; spread a small fraction of the 0.15 m chip
    assert abs(np.mean(ranges) - 1.234) < 0.01
    assert np.std(ranges) < 0.2 * tp.chip_length_m(chip_rate)


def test_orthogonal_reply_code_rejects_the_own_code_echo():
    rng = np.random.default_rng(4)
    chip_m = tp.chip_length_m(1e9)
    same = tp.two_way_trials(1.0, 10, 0.0, 100, rng, 1e9, echo_amp=2.0, same_code=True) - 1.0
    ortho = tp.two_way_trials(1.0, 10, 0.0, 100, rng, 1e9, echo_amp=2.0, same_code=False) - 1.0
    assert np.mean(np.abs(same) > chip_m) > 0.9       # the echo's false peak wins
    assert np.mean(np.abs(ortho) > chip_m) == 0.0


def test_reply_carries_id_and_status_through_noise():
    rng = np.random.default_rng(8)
    chips = tp.reply_chips(0x2A, 0x81)
    noisy = chips + rng.normal(0.0, tp.noise_sigma(-6.0), chips.shape)
    assert tp.read_reply(noisy) == (0x2A, 0x81)


def test_ber_matches_theory():
    errors, bits = tp.ber_dsss(-10.0, 60_000, np.random.default_rng(9))
    theory = tp.ber_theory(-10.0)                     # Q(sqrt(2 * 31 * 0.1)) = 6.4e-3
    assert abs(theory - 6.39e-3) < 0.05e-3
    assert abs(errors / bits - theory) < 4 * np.sqrt(theory / bits)


def test_running_mean_over_100_ms():
    mean = tp.RunningMean(0.1)
    for k, value in enumerate([1.0, 2.0, 3.0, 4.0]):
        mean.add(0.04 * k, value)                    # at 0, 40, 80, 120 ms
    assert mean.mean(0.12) == 3.0                      # (20, 120] ms: the last three
    assert mean.mean(1.0) is None


def test_sensor_model_matches_the_full_receiver():
    sensor = tp.RangingSensor(snr_db=-12.0, reflection_prob=0.05, seed=2)
    rng = np.random.default_rng(10)
    fast = np.array([sensor.measure(0.8, rng)[0] for _ in range(200)])
    full = np.array([sensor.measure(0.8, rng, full=True)[0] for _ in range(60)])
    assert abs(np.mean(fast) - 0.8) < 0.01 and abs(np.mean(full) - 0.8) < 0.01
    assert abs(np.std(fast) - np.std(full)) < 0.5 * np.std(full) + 0.002
    assert sensor.measure(None, rng) == (None, 0.0)
    assert sensor.measure(9.0, rng)[0] is None         # out of range: nothing answers
