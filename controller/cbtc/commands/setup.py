"""`cbtc setup`: everything a live run over Mosquitto needs, in one folder, for one fleet.

Writes the broker's files (mosquitto.conf, passwd, acl, credentials.json: `cbtc broker config`), a keys file (`cbtc
keys new`) and live.json, which names the broker, the layout or scenario, the trains, the keys and the credentials.
Then the run is three commands, each in its own terminal, that cannot disagree on any of them:

    mosquitto -c DIR/mosquitto.conf
    cbtc zone --setup DIR
    cbtc trains --setup DIR
"""

import json
import os

from cbtc.commands import arg_types
from cbtc.errors import ConfigError

EXAMPLES = (
    "cbtc setup --layout itb_square --train-ids A,B --out live",
    "cbtc setup --scenario lego_oval_mixed --port 1884 --out oval-live",
)
SETUP_FILE = "live.json"


def register(sub):
    p = sub.add_parser("setup", help="write one folder for a live run: broker config, keys, credentials, live.json",
                       description=__doc__)
    p.add_argument("--layout", type=arg_types.layout, default=None,
                   help="layout file or packaged name, e.g. itb_square (or give --scenario)")
    p.add_argument("--train-ids", type=arg_types.train_ids, default=None, metavar="A,B",
                   help="the trains' ids on --layout (default A,B)")
    p.add_argument("--scenario", type=arg_types.scenario, default=None, metavar="NAME|FILE",
                   help="a scenario file or packaged name: its layout and trains")
    p.add_argument("--out", required=True, metavar="DIR", type=arg_types.output_folder,
                   help="folder to write into (created)")
    p.add_argument("--port", type=arg_types.whole(1, 65535), default=1883, help="broker port (default 1883)")
    p.add_argument("--host", default="127.0.0.1",
                   help="broker listener address (default 127.0.0.1; 0.0.0.0 for boards on the Wi-Fi)")
    p.add_argument("--run-as", default=None, metavar="USER",
                   help="user Mosquitto runs as when started as root (default: its own, `mosquitto`)")
    p.add_argument("--force", action="store_true", help="write over an existing setup (new keys and passwords)")
    p.set_defaults(func=run)


def run(args):
    from cbtc.bus.broker_config import write_config
    from cbtc.live.keys import write_new_keys

    if args.scenario is not None and (args.layout is not None or args.train_ids is not None):
        raise ConfigError("--scenario sets the layout and the trains: leave --layout and --train-ids out, or give "
                          "them without --scenario")
    if args.scenario is None and args.layout is None:
        raise ConfigError("give the fleet: --layout NAME (with --train-ids, default A,B) or --scenario NAME|FILE")
    setup_path = os.path.join(args.out, SETUP_FILE)
    if os.path.exists(setup_path) and not args.force:
        raise ConfigError(f"{setup_path} exists: its keys and passwords may be in use; give --force to make new ones "
                          f"or another --out")
    if args.scenario is not None:
        ids = [spec.train_id for spec in args.scenario.trains]
        fleet = {"scenario": _named(args.scenario.source)}
    else:
        from cbtc.layout_files import load_layout

        load_layout(args.layout, "a live run")   # checked before anything is written: the zone would refuse it
        ids = args.train_ids or ["A", "B"]
        fleet = {"layout": _named(args.layout), "train_ids": ids}
    paths = write_config(args.out, ids, port=args.port, host=args.host, run_as=args.run_as)
    keys_path = os.path.join(args.out, "keys.json")
    write_new_keys(keys_path, ids)
    host = "127.0.0.1" if args.host in ("0.0.0.0", "::") else args.host
    setup = {"broker": f"mqtt://{host}:{args.port}", **fleet, "keys": "keys.json", "credentials": "credentials.json"}
    with open(setup_path, "w") as fh:
        json.dump(setup, fh, indent=2)
        fh.write("\n")
    print(f"wrote {', '.join(sorted([*paths.values(), keys_path, setup_path]))}")
    print(f"run it in three terminals:\n  mosquitto -c {paths['mosquitto.conf']}\n  cbtc zone --setup {args.out}\n"
          f"  cbtc trains --setup {args.out}")
    return 0


def _named(path_or_name: str) -> str:
    """A file as its whole path (live.json is read from other folders), a packaged name as it is."""
    return os.path.abspath(path_or_name) if os.path.exists(path_or_name) else path_or_name
