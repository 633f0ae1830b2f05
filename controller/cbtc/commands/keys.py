"""`cbtc keys new`: a JSON keys file {train_id: hex key}, one random 16-byte key per train.

`cbtc zone` and `cbtc trains` (and each real board's train_config.py) read the same file: a command is accepted only
with the key of the train it is addressed to. Keep the file private.
"""

import os

from cbtc.commands import arg_types
from cbtc.errors import ConfigError
from cbtc.live.keys import write_new_keys

EXAMPLES = (
    "cbtc keys new --train-ids A,B --out keys.json",
)


def register(sub):
    p = sub.add_parser("keys", help="make per-train authentication keys", description=__doc__)
    keys_sub = p.add_subparsers(dest="keys_command", metavar="ACTION")
    keys_sub.required = True
    new = keys_sub.add_parser("new", help="write a new keys file", description=__doc__)
    new.add_argument("--train-ids", type=arg_types.train_ids, required=True, metavar="A,B",
                     help="train ids, e.g. A,B")
    arg_types.renamed(new, "--trains", "--train-ids A,B")
    new.add_argument("--out", required=True, metavar="FILE", type=arg_types.output_file,
                     help="keys file to write (e.g. keys.json)")
    new.add_argument("--force", action="store_true", help="overwrite an existing file")
    new.set_defaults(func=run_new)


def run_new(args):
    ids = args.train_ids
    if os.path.exists(args.out) and not args.force:
        raise ConfigError(f"{args.out} exists: its keys may be on boards already; use --force to replace them")
    write_new_keys(args.out, ids)
    print(f"wrote keys of {len(ids)} trains to {args.out} (owner-only); pass it as --keys to cbtc zone and cbtc trains")
    return 0
