"""Mosquitto 2.x for the testbed: a configuration with passwords and per-train ACLs, and a private broker process.

`write_config` makes a folder with `mosquitto.conf` (one loopback listener, no anonymous clients, TCP_NODELAY, log
to stderr, no persistence), `passwd` (PBKDF2-SHA512 hashes in Mosquitto's `$7$` format, as `mosquitto_passwd` writes
them), `acl` and `credentials.json` (the clear-text passwords the clients need; keep it private).

ACL: user `zc` reads every train's report and status and writes every train's command and `cbtc/zc/#`; user
`train-<id>` writes only its own report and status and reads only its own command and the zones' status and info.
Mosquitto drops a publish that the ACL forbids without telling the sender, so a train that tries to command another
train is simply not heard, and no one but the zone controller, which never retains a command, can leave a message on
a command topic (Mosquitto 2.0 cannot refuse the retain flag per topic; boards drop retained messages). Packets
over MAX_PACKET_BYTES are refused.
Each client's id is its user name (`use_username_as_clientid`), so a client that reuses another's client id takes
over only a session of its own user: a train's credentials can never disconnect the controller or another train.

`MosquittoProcess` runs a broker on a loopback port (open, or with a generated config) and can kill and restart it on
the same port: the tests and `cbtc bench` use it.
"""

import base64
import hashlib
import json
import os
import secrets
import shutil
import socket
import subprocess
import time

from cbtc.errors import BusError, ConfigError
from cbtc.protocol import wire

ZC_USER = "zc"
# Largest MQTT packet the broker takes: a payload of the protocol's limit, its topic and headers. Longer ones are
# refused (the sender is disconnected) before they reach a board, whose link would drop them unread anyway.
MAX_PACKET_BYTES = wire.MAX_PAYLOAD + 128
PBKDF2_ITERATIONS = 101   # what mosquitto_passwd 2.0 uses
SALT_BYTES = 12


def train_user(train_id: str) -> str:
    """The broker user name of a train board."""
    return "train-" + train_id


def password_hash(password: str, salt: bytes = None) -> str:
    """Mosquitto 2.0 password-file hash `$7$101$<salt b64>$<PBKDF2-HMAC-SHA512 b64>` (64-byte digest)."""
    salt = secrets.token_bytes(SALT_BYTES) if salt is None else salt
    digest = hashlib.pbkdf2_hmac("sha512", password.encode("utf-8"), salt, PBKDF2_ITERATIONS, 64)
    return "$7$%d$%s$%s" % (PBKDF2_ITERATIONS, base64.b64encode(salt).decode(), base64.b64encode(digest).decode())


def acl_text(train_ids) -> str:
    """The Mosquitto ACL file for the zone controller and the given trains."""
    lines = ["# lego-cbtc broker ACL: the zone controller commands trains; a train speaks only for itself.",
             "user " + ZC_USER,
             "topic read cbtc/train/+/report",
             "topic read cbtc/train/+/status",
             "topic write cbtc/train/+/cmd",
             "topic write cbtc/zc/#",
             ""]
    for train_id in train_ids:
        lines += ["user " + train_user(train_id),
                  "topic write " + wire.topic_report(train_id),
                  "topic write " + wire.topic_status(train_id),
                  "topic read " + wire.topic_command(train_id),
                  "topic read cbtc/zc/+/status",
                  "topic read cbtc/zc/+/info",
                  ""]
    return "\n".join(lines)


def config_text(port: int, folder: str, host: str = "127.0.0.1", secured: bool = True, run_as: str = None) -> str:
    """mosquitto.conf: one listener on `host:port`; `secured` = passwords and ACL from `folder`, else anonymous.

    Started as root, Mosquitto switches to user `mosquitto` before it reads the password and ACL files, so they must
    be reachable by that user; `run_as` names another user (`root` keeps a private test broker where it is)."""
    lines = ["# lego-cbtc broker (Mosquitto 2.x)"] + (["user " + run_as] if run_as else []) + [
             "per_listener_settings false",
             "listener %d %s" % (port, host),
             "set_tcp_nodelay true",
             "max_packet_size %d" % MAX_PACKET_BYTES,
             "persistence false",
             "log_dest stderr",
             "log_type error",
             "log_type warning",
             "log_type notice"]
    if secured:
        lines += ["allow_anonymous false",
                  "use_username_as_clientid true",   # a client id is its user: no one can take over another's session
                  "password_file " + os.path.join(os.path.abspath(folder), "passwd"),
                  "acl_file " + os.path.join(os.path.abspath(folder), "acl")]
    else:
        lines += ["allow_anonymous true"]
    return "\n".join(lines) + "\n"


def new_password() -> str:
    """A random password of 144 bits in hex digits: it never starts with '-', so `--password X` takes it on any
    command line (a urlsafe token may, and argparse then reads it as an option)."""
    return secrets.token_hex(18)


def write_config(folder: str, train_ids, port: int = 1883, host: str = "127.0.0.1", credentials: dict = None,
                 run_as: str = None) -> dict:
    """Write mosquitto.conf, passwd, acl and credentials.json into `folder` (created); returns the file paths.

    `credentials` {user: password} keeps given passwords; missing users get random ones. The files are readable by
    all (Mosquitto started as root reads them as user `mosquitto`, see `config_text`) except credentials.json."""
    train_ids = checked_train_ids(train_ids, "broker config")
    if not 0 < int(port) < 65536:
        raise ConfigError(f"broker config: port {port} is not in 1-65535")
    users = [ZC_USER] + [train_user(t) for t in train_ids]
    passwords = dict(credentials or {})
    for user in users:
        passwords.setdefault(user, new_password())
    os.makedirs(folder, exist_ok=True)
    paths = {name: os.path.join(folder, name) for name in ("mosquitto.conf", "passwd", "acl", "credentials.json")}
    _write(paths["passwd"], "".join("%s:%s\n" % (u, password_hash(passwords[u])) for u in users), 0o644)
    _write(paths["acl"], acl_text(train_ids), 0o644)
    _write(paths["mosquitto.conf"], config_text(port, folder, host, run_as=run_as), 0o644)
    _write(paths["credentials.json"], json.dumps({u: passwords[u] for u in users}, indent=2) + "\n", 0o600)
    return paths


def checked_train_ids(train_ids, context):
    """The ids as a list, each a valid train id, none twice; ConfigError prefixed by `context` otherwise."""
    ids = list(train_ids)
    if not ids:
        raise ConfigError(f"{context}: no trains given: pass --train-ids A,B")
    if len(set(ids)) != len(ids):
        raise ConfigError(f"{context}: duplicate train ids in {ids}")
    for train_id in ids:
        try:
            wire.check_train_id(train_id)
        except wire.WireError as exc:
            raise ConfigError(f"{context}: {exc.reason}") from None
    return ids


def _write(path, text, mode):
    with open(path, "w") as fh:
        fh.write(text)
    os.chmod(path, mode)


def load_credentials(path: str) -> dict:
    """{user: password} from a credentials.json written by `write_config`."""
    try:
        with open(path) as fh:
            data = json.load(fh)
    except OSError as exc:
        raise ConfigError(f"credentials file {path}: {exc.strerror}; make it with `cbtc broker config`") from None
    except ValueError as exc:
        raise ConfigError(f"credentials file {path} is not JSON ({exc}); make it with `cbtc broker config`") from None
    if not isinstance(data, dict) or not all(isinstance(k, str) and isinstance(v, str) for k, v in data.items()):
        raise ConfigError(f"credentials file {path} must be a JSON object {{user: password}}")
    return data


# --- a private broker --------------------------------------------------------------------------------------------

def mosquitto_exe() -> str:
    """Path of the mosquitto binary, or '' when it is not installed."""
    if os.path.exists("/usr/sbin/mosquitto"):
        return "/usr/sbin/mosquitto"
    return shutil.which("mosquitto") or ""


def free_port(host: str = "127.0.0.1") -> int:
    """A TCP port that is free on `host` now."""
    with socket.socket() as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


class MosquittoProcess:
    """A Mosquitto on `127.0.0.1:port` with the config file `conf_path`; `kill()` and `start()` again on the same port.

    `open_broker(folder)` makes one that admits anonymous clients (for tests and the embedded bench broker)."""

    def __init__(self, conf_path: str, port: int, log_path: str = None):
        self.conf_path = conf_path
        self.port = port
        self.log_path = log_path or conf_path + ".log"
        self.proc = None

    @classmethod
    def open_broker(cls, folder: str, port: int = None) -> "MosquittoProcess":
        port = port or free_port()
        os.makedirs(folder, exist_ok=True)
        conf = os.path.join(folder, "mosquitto.conf")
        _write(conf, config_text(port, folder, secured=False), 0o644)
        return cls(conf, port)

    @property
    def url(self) -> str:
        return "mqtt://127.0.0.1:%d" % self.port

    def start(self, timeout_s: float = 5.0) -> "MosquittoProcess":
        exe = mosquitto_exe()
        if not exe:
            raise BusError("mosquitto is not installed: apt-get install mosquitto (or use an existing broker URL)")
        with open(self.log_path, "ab") as log:
            self.proc = subprocess.Popen([exe, "-c", self.conf_path], stdout=log, stderr=log)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise BusError(f"mosquitto exited with code {self.proc.returncode} on {self.conf_path}; "
                               f"see {self.log_path}")
            try:
                socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
                return self
            except OSError:
                time.sleep(0.02)
        self.kill()
        raise BusError(f"mosquitto did not listen on 127.0.0.1:{self.port} within {timeout_s} s; see {self.log_path}")

    def kill(self) -> None:
        """Abrupt end (SIGKILL): no goodbye to the clients."""
        if self.proc is not None:
            self.proc.kill()
            self.proc.wait(5)
            self.proc = None

    def log(self) -> str:
        try:
            with open(self.log_path, errors="replace") as fh:
                return fh.read()
        except OSError:
            return ""
