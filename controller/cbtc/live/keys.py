"""Keys and broker credentials of a live run: per-train HMAC keys from a keys file or derived as the simulator does,
and each client's broker user name and password."""

import binascii
import json
import os
import secrets

from cbtc.errors import ConfigError
from cbtc.protocol import wire
from cbtc.zone.config import train_key

ENV_USERNAME = "CBTC_MQTT_USERNAME"
ENV_PASSWORD = "CBTC_MQTT_PASSWORD"
KEY_BYTES = 16


def new_keys(train_ids) -> dict:
    """{train_id: 32 hex characters}: a fresh random 16-byte key per train."""
    return {wire.check_train_id(t): secrets.token_bytes(KEY_BYTES).hex() for t in train_ids}


def write_new_keys(path: str, train_ids) -> None:
    """Write new_keys(train_ids) to `path` as JSON, readable by its owner only (the keys sign every command)."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
    with os.fdopen(fd, "w") as fh:
        json.dump(new_keys(train_ids), fh, indent=2, sort_keys=True)
        fh.write("\n")


def load_keys(path: str) -> dict:
    """{train_id: key bytes} from a JSON keys file {train_id: hex key}."""
    try:
        with open(path) as fh:
            data = json.load(fh)
    except OSError as exc:
        raise ConfigError(f"keys file {path}: {exc.strerror}; "
                          f"make one with `cbtc keys new --train-ids A,B --out {path}`") from None
    except ValueError as exc:
        raise ConfigError(f"keys file {path} is not JSON ({exc}); make one with `cbtc keys new`") from None
    if not isinstance(data, dict) or not data:
        raise ConfigError(f"keys file {path} must be a JSON object {{train_id: hex key}} with at least one train")
    keys = {}
    for train_id, text in data.items():
        try:
            wire.check_train_id(train_id)
        except wire.WireError as exc:
            raise ConfigError(f"keys file {path}: {exc.reason}") from None
        try:
            key = binascii.unhexlify(text) if isinstance(text, str) else b""
        except (binascii.Error, ValueError):
            key = b""
        if len(key) != KEY_BYTES:
            raise ConfigError(f"keys file {path}: key of train {train_id!r} must be {2 * KEY_BYTES} hex characters "
                              f"({KEY_BYTES} bytes)")
        keys[train_id] = key
    return keys


def train_keys(train_ids, keys_path: str = None, sim_seed: int = 0) -> dict:
    """{train_id: key}: from the keys file, or derived from `sim_seed` as the simulator does (zone.config.train_key)."""
    if keys_path is None:
        return {t: train_key(sim_seed, t) for t in train_ids}
    keys = load_keys(keys_path)
    missing = [t for t in train_ids if t not in keys]
    if missing:
        raise ConfigError(f"keys file {keys_path} has no key for trains {missing}; it holds {sorted(keys)}")
    return {t: keys[t] for t in train_ids}


def credentials(user: str, username: str = None, password: str = None, credentials_path: str = None):
    """(username, password) for broker user `user`: a credentials file wins, then the options, then the
    environment (CBTC_MQTT_USERNAME / CBTC_MQTT_PASSWORD); (None, None) for an open broker."""
    if credentials_path:
        from cbtc.bus.broker_config import load_credentials
        table = load_credentials(credentials_path)
        if user not in table:
            raise ConfigError(f"credentials file {credentials_path} has no user {user!r}; it holds {sorted(table)}")
        return user, table[user]
    username = username if username is not None else os.environ.get(ENV_USERNAME)
    password = password if password is not None else os.environ.get(ENV_PASSWORD)
    return username, password
