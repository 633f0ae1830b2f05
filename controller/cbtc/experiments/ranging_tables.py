"""Figures of the coded ranging receiver, the 31-chip data channel and the Hamming telegrams."""

import time

import numpy as np

from cbtc.protocol import telegram
from cbtc.ranging import transponder as tp

CODE_BITS = (5, 7, 10)                 # chip lengths 31, 127, 1023
SNRS_DB = (-20.0, -10.0, 0.0, 10.0)
BER_SNRS_DB = tuple(float(s) for s in range(-10, 5, 2))
CODIBDT_POINT = (-2.0, 1e-5)          # the CODIBDT coded radar: BER 1e-5 at -2 dB SNR


def accuracy_table(rng, chip_rate_hz, trials):
    """Rows: code length, SNR, RMSE of the range (chips of range resolution and m) among inliers, outlier share."""
    chip_m = tp.chip_length_m(chip_rate_hz)
    rows = []
    for n_bits in CODE_BITS:
        for snr in SNRS_DB:
            gap_m = rng.uniform(0.3, 2.0)   # within C31's unambiguous range at 1 Gchip/s
            err_m = tp.two_way_trials(gap_m, n_bits, snr, trials, rng, chip_rate_hz) - gap_m
            inlier = np.abs(err_m) <= chip_m
            rmse_m = float(np.sqrt(np.mean(err_m[inlier] ** 2))) if inlier.any() else None
            rows.append({"chips": 2 ** n_bits - 1, "snr_db": snr,
                         "rmse_chips": None if rmse_m is None else round(rmse_m / chip_m, 4),
                         "rmse_m": None if rmse_m is None else round(rmse_m, 4),
                         "outliers": round(1.0 - float(np.mean(inlier)), 4)})
    return rows


def code_rejection(rng, chip_rate_hz, trials):
    """Outlier share with the leader's own-code radar echo (6 dB above the reply) present: reply with the same code
    against reply with a different Gold code, at 0 dB."""
    chip_m = tp.chip_length_m(chip_rate_hz)
    out = {}
    for name, same in (("same_code", True), ("orthogonal_codes", False)):
        gaps = rng.uniform(0.3, 2.0, trials)
        bad = 0
        for gap in gaps:
            err = tp.two_way_trials(float(gap), 10, 0.0, 1, rng, chip_rate_hz, echo_amp=2.0, same_code=same) - gap
            bad += int(abs(err[0]) > chip_m)
        out[name] = round(bad / trials, 4)
    return out


def ber_table(rng):
    rows = []
    for snr in BER_SNRS_DB:
        theory = tp.ber_theory(snr)
        n_bits = int(min(1_000_000, max(20_000, 30.0 / max(theory, 1e-12))))
        if theory * 1_000_000 >= 10:
            errors, bits = tp.ber_dsss(snr, n_bits, rng)
            simulated = errors / bits
        else:
            errors, bits, simulated = None, None, None   # too deep to resolve in a few seconds: theory only
        rows.append({"snr_db": snr, "simulated": simulated, "errors": errors, "bits": bits, "theory": theory,
                     "codibdt": CODIBDT_POINT[1] if snr == CODIBDT_POINT[0] else None})
    return rows


def telegram_stats(rng, n=10_000, bers=(1e-3, 1e-2, 3e-2)):
    """Per bit-error rate: decoded correctly (ok + corrected), detected, undetected (wrong data) per n telegrams."""
    payload = telegram.balise_payload(0x04A7, 1234567, 5)
    frame = np.frombuffer(bytes(telegram.encode(payload)), dtype=np.uint8)
    rows = []
    for ber in bers:
        flips = (rng.random((n, len(frame))) < ber).astype(np.uint8)
        counts = {"ok": 0, "corrected": 0, "detected": 0, "undetected": 0}
        for row in frame[None, :] ^ flips:
            data, status = telegram.decode(bytearray(row.tobytes()))
            if status != telegram.DETECTED and data != payload:
                counts["undetected"] += 1
            else:
                counts[status] += 1
        rows.append({"ber": ber, "telegrams": n, **counts})
    return rows


def ranging_figures(seed: int, chip_rate_hz: float, trials: int) -> dict:
    """Every table of `cbtc ranging`, from one random generator seeded with `seed`."""
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    threshold, shares = tp.threshold_snr_db(10, rng, trials=max(200, trials))
    result = {
        "seed": seed, "chip_rate_hz": chip_rate_hz, "chip_m": tp.chip_length_m(chip_rate_hz),
        "accuracy": accuracy_table(rng, chip_rate_hz, trials),
        "threshold_snr_db": threshold, "threshold_curve": shares,
        "code_rejection": code_rejection(rng, chip_rate_hz, 200),
        "ber": ber_table(rng),
        "telegrams": telegram_stats(rng),
    }
    result["wall_s"] = round(time.perf_counter() - started, 2)
    return result
