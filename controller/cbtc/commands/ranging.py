"""`cbtc ranging`: figures of the coded ranging receiver, the 31-chip data channel and the Hamming telegrams."""

from cbtc.commands import arg_types
from cbtc.commands.common import format_table, print_json
from cbtc.errors import ConfigError

EXAMPLES = (
    "cbtc ranging --json",
)


def register(sub):
    p = sub.add_parser("ranging", help="measure coded train-to-train ranging, the data channel's BER, telegram coding",
                       description="Ranging accuracy against chip length and SNR (two-way exchanges, two other "
                                   "trains' codes present), the SNR threshold of the receiver, the BER of the "
                                   "31-chip data channel beside theory and the CODIBDT coded radar, and telegram "
                                   "statistics "
                                   "under random bit errors.")
    p.add_argument("--seed", type=arg_types.seed, default=0, help="random seed (default: 0)")
    p.add_argument("--chip-rate", type=arg_types.number(above=0.0, example="1e9"), default=1e9, metavar="HZ",
                   help="chip rate (default: 1e9, a UWB-class radio: 0.15 m of range per chip)")
    p.add_argument("--trials", type=arg_types.whole(1), default=300, help="exchanges per table cell (default: 300)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args):
    from cbtc.experiments.ranging_tables import ranging_figures

    if args.trials < 20:
        raise ConfigError(f"--trials must be >= 20, got {args.trials}")
    if args.chip_rate <= 0:
        raise ConfigError(f"--chip-rate must be > 0 Hz, got {args.chip_rate}")
    result = ranging_figures(args.seed, args.chip_rate, args.trials)
    if args.json:
        print_json(result)
        return 0
    print(f"two-way coded ranging, {args.chip_rate:.3g} chip/s: {result['chip_m']:.3f} m of range per chip; "
          f"SNR per chip (Ec/N0); two other trains' codes present; {args.trials} exchanges per cell")
    print(format_table(result["accuracy"], [("chips", "code"), ("snr_db", "SNR dB"), ("rmse_chips", "RMSE chips"),
                                            ("rmse_m", "RMSE m"), ("outliers", "outliers >1 chip")]))
    print(f"receiver threshold (C1023, delay within 1 chip in >= 99 % of trials, 2 other codes): "
          f"{result['threshold_snr_db']} dB")
    rej = result["code_rejection"]
    print(f"own-code echo 6 dB above the reply, 0 dB: outliers {rej['same_code']:.1%} replying with the same code, "
          f"{rej['orthogonal_codes']:.1%} with a different Gold code")
    print("\nBER of the 31-chip DSSS data channel (BPSK, AWGN, SNR per chip); theory Q(sqrt(2 * 31 * Ec/N0))")
    print(format_table([{**r, "simulated": None if r["simulated"] is None else f"{r['simulated']:.2e}",
                         "theory": f"{r['theory']:.2e}",
                         "codibdt": None if r["codibdt"] is None else f"{r['codibdt']:.0e}"} for r in result["ber"]],
                       [("snr_db", "SNR dB"), ("simulated", "simulated"), ("errors", "errors"), ("bits", "bits"),
                        ("theory", "theory"), ("codibdt", "CODIBDT")]))
    print("(- : too deep to simulate in seconds; theory only)")
    print("\nbalise telegrams (126 bits) under random bit errors, per 10k")
    print(format_table(result["telegrams"], [("ber", "bit error rate"), ("ok", "ok"), ("corrected", "corrected"),
                                             ("detected", "detected"), ("undetected", "undetected")]))
    print(f"({result['wall_s']:.1f} s)")
    return 0
