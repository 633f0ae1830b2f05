"""`cbtc ranging`: figures of the coded ranging receiver, the 31-chip data channel and the Hamming telegrams."""

import time

import numpy as np

from cbtc.commands.common import format_table, print_json
from cbtc.errors import ConfigError
from cbtc.firmware_modules import telegram
from cbtc.ranging import transponder as tp

CODE_BITS = (5, 7, 10)                 # chip lengths 31, 127, 1023
SNRS_DB = (-20.0, -10.0, 0.0, 10.0)
BER_SNRS_DB = tuple(float(s) for s in range(-10, 5, 2))
SEED_001_POINT = (-2.0, 1e-5)          # seed 001: BER 1e-5 at -2 dB SNR


def register(sub):
    p = sub.add_parser("ranging", help="coded train-to-train ranging, BER of the data channel, telegram coding",
                       description="Ranging accuracy against chip length and SNR (two-way exchanges, two other "
                                   "trains' codes present), the SNR threshold of the receiver, the BER of the "
                                   "31-chip data channel beside theory and seed 001, and telegram statistics "
                                   "under random bit errors.")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: 0)")
    p.add_argument("--chip-rate", type=float, default=1e9, metavar="HZ",
                   help="chip rate (default: 1e9, a UWB-class radio: 0.15 m of range per chip)")
    p.add_argument("--trials", type=int, default=300, help="exchanges per table cell (default: 300)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


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
                     "seed_001": SEED_001_POINT[1] if snr == SEED_001_POINT[0] else None})
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


def run(args):
    if args.trials < 20:
        raise ConfigError(f"--trials must be >= 20, got {args.trials}")
    if args.chip_rate <= 0:
        raise ConfigError(f"--chip-rate must be > 0 Hz, got {args.chip_rate}")
    started = time.perf_counter()
    rng = np.random.default_rng(args.seed)
    threshold, shares = tp.threshold_snr_db(10, rng, trials=max(200, args.trials))
    result = {
        "seed": args.seed, "chip_rate_hz": args.chip_rate, "chip_m": tp.chip_length_m(args.chip_rate),
        "accuracy": accuracy_table(rng, args.chip_rate, args.trials),
        "threshold_snr_db": threshold, "threshold_curve": shares,
        "code_rejection": code_rejection(rng, args.chip_rate, 200),
        "ber": ber_table(rng),
        "telegrams": telegram_stats(rng),
    }
    result["wall_s"] = round(time.perf_counter() - started, 2)
    if args.json:
        print_json(result)
        return 0
    print(f"two-way coded ranging, {args.chip_rate:.3g} chip/s: {result['chip_m']:.3f} m of range per chip; "
          f"SNR per chip (Ec/N0); two other trains' codes present; {args.trials} exchanges per cell")
    print(format_table(result["accuracy"], [("chips", "code"), ("snr_db", "SNR dB"), ("rmse_chips", "RMSE chips"),
                                            ("rmse_m", "RMSE m"), ("outliers", "outliers >1 chip")]))
    print(f"receiver threshold (C1023, delay within 1 chip in >= 99 % of trials, 2 other codes): {threshold} dB")
    rej = result["code_rejection"]
    print(f"own-code echo 6 dB above the reply, 0 dB: outliers {rej['same_code']:.1%} replying with the same code, "
          f"{rej['orthogonal_codes']:.1%} with a different Gold code")
    print("\nBER of the 31-chip DSSS data channel (BPSK, AWGN, SNR per chip); theory Q(sqrt(2 * 31 * Ec/N0))")
    print(format_table([{**r, "simulated": None if r["simulated"] is None else f"{r['simulated']:.2e}",
                         "theory": f"{r['theory']:.2e}",
                         "seed_001": None if r["seed_001"] is None else f"{r['seed_001']:.0e}"} for r in result["ber"]],
                       [("snr_db", "SNR dB"), ("simulated", "simulated"), ("errors", "errors"), ("bits", "bits"),
                        ("theory", "theory"), ("seed_001", "seed 001")]))
    print("(- : too deep to simulate in seconds; theory only)")
    print("\nbalise telegrams (126 bits) under random bit errors, per 10k")
    print(format_table(result["telegrams"], [("ber", "bit error rate"), ("ok", "ok"), ("corrected", "corrected"),
                                             ("detected", "detected"), ("undetected", "undetected")]))
    print(f"({result['wall_s']:.1f} s)")
    return 0
