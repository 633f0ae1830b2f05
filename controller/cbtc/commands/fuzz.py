"""`cbtc fuzz`: throw bad payloads at a live zone controller and live virtual trains over a real Mosquitto and check
that nothing got through (experiments/fuzz.py says what is thrown and what each figure means).

Without --broker it starts a private Mosquitto on a free loopback port. Exit status 0 when the controller governs
every train afterwards and no payload got through; 1 otherwise.
"""

import argparse
import logging

from cbtc.commands import arg_types
from cbtc.commands.common import add_mqtt_client_arg, module_doc, print_json
from cbtc.commands.progress_bar import bar, shown

MAX_PAYLOADS = 1_000_000


EXAMPLES = (
    "cbtc fuzz --payloads 2000 --broker mqtt://HOST:PORT",
)


def register(sub):
    p = sub.add_parser("fuzz", help="throw bad payloads at a live zone and trains over Mosquitto; check nothing got "
                                    "through", description=__doc__ + "\n" + module_doc("cbtc.experiments.fuzz"),
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--broker", type=arg_types.broker_url, default=None, metavar="URL",
                   help="mqtt://HOST:PORT of an open broker (default: a private Mosquitto on a free loopback port)")
    p.add_argument("--payloads", type=arg_types.whole(1, MAX_PAYLOADS), default=10000,
                   help="bad payloads to throw (default 10000)")
    p.add_argument("--seed", type=arg_types.seed, default=0, help="seed of the payloads and the trains (default 0)")
    add_mqtt_client_arg(p)
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.set_defaults(func=run)


def run(args):
    # refusals are counted in the figures; the zone's own lines (a few per kind) would tear the progress bar
    logging.getLogger("cbtc.zone").setLevel(logging.ERROR)
    from cbtc.experiments import fuzz

    with bar("fuzz", 1.0, shown(args)) as update:
        result = fuzz.run_fuzz(args.payloads, args.seed, args.broker,
                               lambda done_s, total_s, sent: update(done_s / total_s if total_s else 1.0,
                                                                    f"{sent} payloads sent"),
                               client=args.mqtt_client)
    if args.json:
        print_json(result)
    else:
        _print(result)
    passed = (result["controller_alive"] and not result["uncaught_exceptions"] and not result["accepted_invalid"]
              and not result["moved_without_authority"])
    return 0 if passed else 1


def _print(r):
    classes = ", ".join(f"{n} {k}" for k, n in r["by_class"].items())
    print(f"{r['payloads']} bad payloads ({classes}) over {r['attack_s']} s, seed {r['seed']}")
    print(f"  uncaught exceptions       {r['uncaught_exceptions']}")
    print(f"  accepted invalid          {r['accepted_invalid']}" +
          "".join(f"\n    {example}" for example in r["accepted_invalid_examples"]))
    print(f"  moved without authority   {r['moved_without_authority']} trains drove past their end of authority "
          f"(mm: {r['drove_past_eoa_mm']}; braked or sliding past it: {r['moved_past_eoa_mm']})")
    print(f"  collisions                {r['collisions']}")
    print(f"  controller alive          {'yes' if r['controller_alive'] else 'NO'} ({r['trains_located']} trains "
          f"located, {r['trains_moving_after']} moving again, picture finite: {r['picture_finite']})")
    print(f"  refused: {r['reports_refused']} reports by the controller, {r['commands_refused_onboard']} commands "
          f"on board")
