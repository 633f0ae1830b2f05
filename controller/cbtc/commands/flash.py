"""`cbtc flash`: deploy the firmware and a generated train_config.py to a board, verify, reset, see it boot."""

import os

from cbtc.commands import arg_types
from cbtc.live.keys import ENV_PASSWORD, ENV_USERNAME, credentials, train_keys

EXAMPLES = (
    "cbtc flash --port /dev/ttyUSB0 --train A --keys live/keys.json --credentials live/credentials.json "
    "--broker mqtt://192.168.1.10:1883 --wifi-ssid lego-cbtc",
)


def register(subparsers):
    p = subparsers.add_parser("flash", help="copy the firmware to a train board with mpremote and verify it boots",
                              description=__doc__)
    p.add_argument("--port", required=True, help="serial port of the board, e.g. /dev/ttyUSB0")
    p.add_argument("--train", required=True, help="train id (1-16 of A-Z a-z 0-9 _ -)")
    p.add_argument("--broker", type=arg_types.broker_url, default="mqtt://192.168.1.10:1883",
                   help="broker the board connects to: mqtt://HOST[:PORT]")
    p.add_argument("--wifi-ssid", default=None, help="Wi-Fi network (omit to leave the board's Wi-Fi as it is)")
    p.add_argument("--wifi-password", default=os.environ.get("CBTC_WIFI_PASSWORD", ""),
                   help="Wi-Fi password (default: $CBTC_WIFI_PASSWORD)")
    p.add_argument("--key", default=os.environ.get("CBTC_TRAIN_KEY"),
                   help="the train's 16-byte key as 32 hex digits (default: $CBTC_TRAIN_KEY); the zone controller "
                        "must hold the same key")
    p.add_argument("--keys", type=arg_types.input_file, default=None, metavar="FILE",
                   help="keys file from `cbtc keys new`: the train's key is taken from it (instead of --key)")
    p.add_argument("--credentials", type=arg_types.input_file, default=None, metavar="FILE",
                   help="the broker's credentials.json (cbtc broker config): the board logs in as train-<id> with its "
                        "password (default: --username/--password, else anonymous, for an open broker)")
    p.add_argument("--username", default=None, help=f"broker user name of the board (default: ${ENV_USERNAME})")
    p.add_argument("--password", default=None, help=f"broker password of the board (default: ${ENV_PASSWORD})")
    p.add_argument("--timeout", type=arg_types.seconds, default=120.0, help="seconds allowed for copying (default 120)")
    p.set_defaults(func=run)


def run(args):
    from cbtc.board.flash import flash
    from cbtc.errors import ConfigError

    if args.keys is not None:   # the file the zone controller reads: the board gets the very same key
        key = train_keys([args.train], args.keys)[args.train]
        args.key = key.hex() if isinstance(key, bytes) else key
    if not args.key:
        raise ConfigError("--key is required (or --keys FILE, or set CBTC_TRAIN_KEY): 32 hex digits, the train's "
                          "key")
    login = None
    username, password = credentials(f"train-{args.train}", args.username, args.password)
    if username:
        login = {"mqtt_user": username, "mqtt_password": password or ""}
    if args.credentials is not None:
        from cbtc.bus.broker_config import load_credentials

        user = f"train-{args.train}"
        passwords = load_credentials(args.credentials)
        if user not in passwords:
            raise ConfigError(f"--credentials {args.credentials} has no user {user}: run `cbtc broker config "
                              f"--train-ids ...,{args.train} --out DIR --keep-passwords` and restart the broker")
        login = {"mqtt_user": user, "mqtt_password": passwords[user]}
    result = flash(args.port, args.train, args.key, args.broker, args.wifi_ssid, args.wifi_password, extra=login,
                   timeout_s=args.timeout)
    print(f"flashed {result['files']} files to {result['port']}; "
          f"train {args.train} booted firmware {result['version']}")
    return 0
