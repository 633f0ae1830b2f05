"""`cbtc broker config`: a Mosquitto 2.x configuration with passwords and per-train ACLs.

Writes mosquitto.conf, passwd, acl and credentials.json into a folder: start the broker with
`mosquitto -c DIR/mosquitto.conf`, give `--credentials DIR/credentials.json` to `cbtc zone` and `cbtc trains`.
The zone controller logs in as `zc`, each train as `train-<id>` and may publish only its own report and status and
read only its own commands.
"""

import os

from cbtc.commands import arg_types
from cbtc.errors import ConfigError

EXAMPLES = (
    "cbtc broker config --train-ids A,B --out broker",
)


def register(sub):
    p = sub.add_parser("broker", help="write a Mosquitto configuration with per-train ACLs", description=__doc__)
    broker_sub = p.add_subparsers(dest="broker_command", metavar="ACTION")
    broker_sub.required = True
    cfg = broker_sub.add_parser("config", help="write mosquitto.conf, passwd, acl, credentials.json",
                                description=__doc__)
    cfg.add_argument("--train-ids", type=arg_types.train_ids, required=True, metavar="A,B",
                     help="train ids, e.g. A,B")
    arg_types.renamed(cfg, "--trains", "--train-ids A,B")
    cfg.add_argument("--out", required=True, metavar="DIR", type=arg_types.output_folder,
                     help="folder to write the files into")
    cfg.add_argument("--port", type=arg_types.whole(1, 65535), default=1883, help="listener port (default 1883)")
    cfg.add_argument("--host", default="127.0.0.1", help="listener address (default 127.0.0.1; 0.0.0.0 for boards "
                                                         "on the Wi-Fi)")
    cfg.add_argument("--run-as", default=None, metavar="USER",
                     help="user Mosquitto runs as when started as root (default: its own, `mosquitto`)")
    again = cfg.add_mutually_exclusive_group()
    again.add_argument("--keep-passwords", action="store_true",
                       help="reuse the passwords of an existing DIR/credentials.json (boards keep working)")
    again.add_argument("--force", action="store_true",
                       help="make new passwords over an existing DIR/credentials.json (every board and client then "
                            "needs the new ones)")
    cfg.set_defaults(func=run_config)


def run_config(args):
    from cbtc.bus.broker_config import load_credentials, write_config

    ids = args.train_ids
    old = os.path.join(args.out, "credentials.json")
    if os.path.exists(old) and not (args.keep_passwords or args.force):
        raise ConfigError(f"{old} exists and its passwords are on your boards and clients: add --keep-passwords to "
                          f"keep them (new trains get new ones), or --force to make new ones for all")
    keep = load_credentials(old) if args.keep_passwords and os.path.exists(old) else None
    paths = write_config(args.out, ids, port=args.port, host=args.host, credentials=keep, run_as=args.run_as)
    print(f"wrote {', '.join(sorted(paths.values()))}")
    print(f"start the broker: mosquitto -c {paths['mosquitto.conf']}")
    print(f"then: cbtc zone --broker mqtt://{args.host}:{args.port} --credentials {paths['credentials.json']} ...")
    return 0
