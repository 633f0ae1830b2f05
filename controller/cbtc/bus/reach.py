"""What a live command says when it cannot reach its broker, said fast and by cause: an unknown host at once, a port
nothing listens on within a second, a refused login by what the broker answered, each with its fix."""

import socket
import time

from cbtc.errors import BusError

REFUSED_PATIENCE_S = 1.0   # a broker being started may refuse for a moment: tried again for this long
LOGIN_OPTIONS = "--username/--password (or CBTC_MQTT_USERNAME/PASSWORD)"


def reach(host: str, port: int, client_id: str, patience_s: float = REFUSED_PATIENCE_S) -> None:
    """Resolve `host` and look for a listener on `port`; raise BusError naming the cause when there is none. A host
    that does not answer at all (filtered, down) is left to the client's own wait."""
    try:
        socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        raise BusError(f"{client_id}: unknown host {host!r} ({exc.strerror if hasattr(exc, 'strerror') else exc}); "
                       f"fix the host in --broker, e.g. mqtt://127.0.0.1:1883") from None
    deadline_s = time.monotonic() + patience_s
    while True:
        try:
            socket.create_connection((host, port), timeout=2.0).close()
            return
        except ConnectionRefusedError:
            if time.monotonic() >= deadline_s:
                raise BusError(f"{client_id}: nothing listens at {host}:{port} (connection refused); start the "
                               f"broker (`cbtc broker config`, then mosquitto -c on its file) or fix the port in "
                               f"--broker") from None
            time.sleep(0.1)
        except OSError:
            return


def refused_login(client_id: str, host: str, port: int, refusal: str, login: str = LOGIN_OPTIONS) -> str:
    """The words for a CONNECT the broker refused with `refusal` (its reason), the login having come from `login`."""
    said = refusal.lower()
    if "password" in said:
        return f"{client_id}: the broker at {host}:{port} refused the login: bad user name or password; check {login}"
    if "authori" in said:
        return (f"{client_id}: the broker at {host}:{port} refused the login: not authorised (a user it does not "
                f"know, a wrong password, or one its ACL refuses); check {login}")
    return f"{client_id}: the broker at {host}:{port} refused the connection ({refusal}); check {login}"
