"""`cbtc bench latency`: report -> command round trips through a real MQTT broker, and the controller's compute time
(experiments/latency.py says what each figure measures)."""

import argparse

from cbtc.commands import arg_types
from cbtc.commands.common import module_doc, print_json
from cbtc.errors import ConfigError

EXAMPLES = (
    "cbtc bench latency --trains 4 --duration 2 --warmup 0.5 --json",
)


def register(sub):
    p = sub.add_parser("bench", help="measure the live system (MQTT latency, controller compute time)",
                       description=module_doc("cbtc.experiments.latency"),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    bench_sub = p.add_subparsers(dest="bench_command", metavar="WHAT")
    bench_sub.required = True
    lat = bench_sub.add_parser("latency", help="report -> command round trip through the broker",
                               description=module_doc("cbtc.experiments.latency"),
                               formatter_class=argparse.RawDescriptionHelpFormatter)
    lat.add_argument("--broker", default="embedded", metavar="URL",
                     help="mqtt://HOST:PORT of an open broker, or 'embedded' (default): a private Mosquitto")
    lat.add_argument("--trains", type=arg_types.whole(1), default=20, help="number of virtual trains (default 20)")
    lat.add_argument("--duration", type=arg_types.seconds, default=10.0,
                     help="seconds measured after the warm-up (default 10)")
    lat.add_argument("--warmup", type=arg_types.number(minimum=0.0, example="2"), default=2.0,
                     help="seconds left out at the start (default 2)")
    lat.add_argument("--train-procs", type=arg_types.whole(1), default=4,
                     help="processes the trains are shared out to (default 4): in one process, 20 trains queue "
                          "behind each other for the GIL as 20 boards never would")
    lat.add_argument("--layout", type=arg_types.layout, default=None,
                     help="layout (default: a LEGO oval long enough for the trains)")
    lat.add_argument("--seed", type=arg_types.seed, default=0)
    lat.add_argument("--json", action="store_true", help="print the figures as JSON")
    lat.set_defaults(func=run_latency)


def run_latency(args):
    if args.trains < 1 or args.train_procs < 1 or args.duration <= 0 or args.warmup < 0:
        raise ConfigError("bench latency: --trains and --train-procs must be >= 1, --duration > 0, --warmup >= 0")
    from cbtc.experiments import latency
    result = latency.run_latency(args)
    if args.json:
        print_json(result)
    else:
        _print(result)
    return 0


def _print(f):
    print(f"{f['trains']} trains on {f['layout']} through {f['broker']}, reports at {f['report_hz']} Hz a train, "
          f"controller cycle {f['controller_cycle_hz']} Hz, {f['duration_s']} s measured")
    rows = [("transport_rtt_ms", "transport round trip (uplink + downlink)"),
            ("uplink_ms", "  report published -> controller handles it"),
            ("downlink_ms", "  command published -> train handles it"),
            ("answer_wait_ms", "controller: report received -> its command published"),
            ("report_to_cmd_ms", "report published -> its command received"),
            ("event_answer_ms", "report -> triggered command to the train behind"),
            ("cycle_compute_ms", "controller cycle compute"),
            ("on_report_compute_ms", "controller on_report compute")]
    for key, label in rows:
        s = f[key]
        p50 = "       -" if s["p50"] is None else f"{s['p50']:8.3f}"
        p99 = "       -" if s["p99"] is None else f"{s['p99']:8.3f}"
        print(f"  {label:52s} p50 {p50} ms  p99 {p99} ms  (n={s['n']})")
    print(f"  reports {f['reports_received']}/{f['reports_published']} received, {f['reports_answered']} "
          f"answered; trains moving: {f['moving_trains']}/{f['trains']}")
