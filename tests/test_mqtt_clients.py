"""The real-broker clients: URL and QoS rules, and against a real Mosquitto, for each way of connecting (paho on its
own thread, paho on a NetLoop, the lean client on a NetLoop): refusal with no broker, retained status and last will,
reconnect with resubscribe; routing and TCP_NODELAY on paho's thread, and paho on one NetLoop. The lean client's
own tests are in test_lean_bus.py."""

import os
import socket
import subprocess
import sys
import threading
import time

import pytest

from cbtc.bus.client import BusClient, parse_broker_url, topic_qos
from cbtc.bus.lean_bus import LeanBus
from cbtc.bus.net_loop import NetLoop
from cbtc.bus.paho_bus import PahoBus
from cbtc.errors import BusError, ConfigError


def wait_for(predicate, timeout_s, what, net=None):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        if net is not None:
            net.poll(0.01)
        else:
            time.sleep(0.01)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


class Clients:
    """Buses of one kind: "paho thread", "paho net loop" or "lean"; the net-loop kinds share one NetLoop."""

    KINDS = ("paho thread", "paho net loop", "lean")

    def __init__(self, kind):
        self.kind = kind
        self.net = None if kind == "paho thread" else NetLoop()

    def bus(self, url, client_id, **options):
        """A bus not yet started."""
        kind = LeanBus if self.kind == "lean" else PahoBus
        return kind(url, client_id, net=self.net, **options)

    def start(self, url, client_id, **options):
        return self.bus(url, client_id, **options).start()

    def wait_for(self, predicate, timeout_s, what):
        wait_for(predicate, timeout_s, what, net=self.net)

    def pause(self, seconds):
        """Let `seconds` pass, the loop (if any) handling traffic meanwhile."""
        if self.net is None:
            time.sleep(seconds)
            return
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.net.poll(0.01)

    def start_and_die_code(self, url, client_id, status_topic):
        """Python that starts a bus of this kind in a new process and ends it abruptly (no DISCONNECT)."""
        kind = "LeanBus" if self.kind == "lean" else "PahoBus"
        net = "" if self.net is None else ", net=NetLoop()"
        return (f"import os, time; from cbtc.bus.lean_bus import LeanBus; from cbtc.bus.paho_bus import PahoBus; "
                f"from cbtc.bus.net_loop import NetLoop; "
                f"{kind}('{url}', '{client_id}', status_topic='{status_topic}'{net}).start(); "
                "time.sleep(0.3); os._exit(0)")


def test_parse_broker_url():
    assert parse_broker_url("mqtt://127.0.0.1:1884") == ("127.0.0.1", 1884, None, None)
    assert parse_broker_url("broker.local") == ("broker.local", 1883, None, None)
    assert parse_broker_url("mqtt://zc:s%40cret@h:2000") == ("h", 2000, "zc", "s@cret")
    for bad in ("http://h:1", "mqtt://:1883", "mqtt://h:99999"):
        with pytest.raises(ConfigError, match="broker URL"):
            parse_broker_url(bad)


def test_qos_per_topic():
    assert topic_qos("cbtc/train/A/status") == 1
    assert topic_qos("cbtc/zc/zc1/status") == 1
    assert topic_qos("cbtc/train/A/report") == 0
    assert topic_qos("cbtc/train/A/cmd") == 0
    assert topic_qos("cbtc/train/+/report") == 0


@pytest.mark.parametrize("kind", Clients.KINDS)
def test_no_broker_is_a_bus_error_naming_the_address(kind):
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]   # bound, not listening: connections are refused
        bus = Clients(kind).bus(f"mqtt://127.0.0.1:{port}", "lonely")
        with pytest.raises(BusError, match=f"127.0.0.1:{port}"):
            bus.start(timeout_s=0.5)


@pytest.mark.mosquitto
def test_publish_subscribe_through_mosquitto_on_pahos_thread(mosquitto):
    sub = PahoBus(mosquitto.url, "sub").start()
    pub = PahoBus(mosquitto.url, "pub").start()
    try:
        assert isinstance(sub, BusClient) and sub.connected
        got = []
        sub.subscribe("cbtc/train/+/report", lambda t, p: got.append((t, p, threading.get_ident())))
        time.sleep(0.2)  # SUBACK
        pub.publish("cbtc/train/A/report", b"one")
        pub.publish("cbtc/train/B/cmd", b"not for this filter")
        pub.publish("cbtc/train/B/report", b"two")
        wait_for(lambda: len(got) == 2, 3.0, "two reports")
        assert [(t, p) for t, p, _ in got] == [("cbtc/train/A/report", b"one"), ("cbtc/train/B/report", b"two")]
        assert threading.get_ident() not in {ident for _, _, ident in got}   # called back on paho's thread
        sock = sub._client.socket()
        assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
        sub.unsubscribe("cbtc/train/+/report")
        time.sleep(0.2)
        pub.publish("cbtc/train/C/report", b"three")
        time.sleep(0.3)
        assert len(got) == 2
    finally:
        sub.disconnect()
        pub.disconnect()


@pytest.mark.mosquitto
@pytest.mark.parametrize("kind", Clients.KINDS)
def test_status_online_retained_offline_on_clean_exit_and_as_last_will(mosquitto, kind):
    clients = Clients(kind)
    watcher = clients.start(mosquitto.url, "watcher")
    seen = []
    watcher.subscribe("cbtc/train/+/status", lambda t, p: seen.append((t, p)))
    try:
        bus = clients.start(mosquitto.url, "train-A", status_topic="cbtc/train/A/status")
        clients.wait_for(lambda: ("cbtc/train/A/status", b"online") in seen, 3.0, "online")
        bus.disconnect()
        if isinstance(bus, LeanBus):
            assert not bus._unacked   # the offline status was acknowledged (QoS 1) before DISCONNECT
        clients.wait_for(lambda: seen[-1] == ("cbtc/train/A/status", b"offline"), 3.0, "offline on a clean exit")
        # an abrupt end (the process dies, no DISCONNECT): the broker publishes the last will
        code = clients.start_and_die_code(mosquitto.url, "train-B", "cbtc/train/B/status")
        subprocess.run([sys.executable, "-c", code], check=True, timeout=20)
        clients.wait_for(lambda: seen[-1] == ("cbtc/train/B/status", b"offline"), 3.0, "the will of B")
        assert ("cbtc/train/B/status", b"online") in seen
        # retained: a late subscriber learns both at once
        late = clients.start(mosquitto.url, "late")
        retained = []
        late.subscribe("cbtc/train/+/status", lambda t, p: retained.append((t, p)))
        clients.wait_for(lambda: len(retained) == 2, 3.0, "two retained statuses")
        assert sorted(retained) == [("cbtc/train/A/status", b"offline"), ("cbtc/train/B/status", b"offline")]
        late.disconnect()
    finally:
        watcher.disconnect()


@pytest.mark.mosquitto
@pytest.mark.parametrize("kind", Clients.KINDS)
def test_reconnects_and_resubscribes_after_a_broker_restart(mosquitto, kind):
    clients = Clients(kind)
    sub = clients.start(mosquitto.url, "sub", reconnect_max_s=0.5)
    connects = []
    sub.on_connect = connects.append
    got = []
    sub.subscribe("cbtc/train/A/cmd", lambda t, p: got.append(p))
    try:
        mosquitto.kill()
        clients.wait_for(lambda: not sub.connected, 5.0, "the loss to be noticed")
        sub.publish("cbtc/train/A/cmd", b"into the void")   # dropped, counted, no exception
        assert sub.dropped == 1
        mosquitto.start()
        clients.wait_for(lambda: sub.connected, 10.0, "reconnect")
        assert connects == [sub] and sub.losses == 1 and sub.connects == 2
        pub = clients.start(mosquitto.url, "pub")
        deadline = time.monotonic() + 5.0
        while not got and time.monotonic() < deadline:   # until the resubscription has reached the broker
            pub.publish("cbtc/train/A/cmd", b"after restart")
            clients.pause(0.1)
        pub.disconnect()
        assert got and got[0] == b"after restart"
    finally:
        sub.disconnect()


@pytest.mark.mosquitto
def test_one_net_loop_reads_handles_and_answers_in_its_own_thread(mosquitto):
    """No network thread: the loop's poll reads each socket, runs the callbacks here, and writes what a callback
    published as soon as it returns; a failing callback is counted and the next message still handled."""
    threads_before = threading.active_count()
    net = NetLoop()
    zc = PahoBus(mosquitto.url, "zc", net=net).start()
    train = PahoBus(mosquitto.url, "train-A", status_topic="cbtc/train/A/status", net=net).start()
    assert threading.active_count() == threads_before
    try:
        for bus in (zc, train):
            assert bus._client.socket().getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
        seen, answers = [], []

        def on_report(topic, payload):
            seen.append(threading.get_ident())
            if payload == b"bad":
                raise ValueError("a handler's bug")
            zc.publish("cbtc/train/A/cmd", b"answer to " + payload)    # inside the callback: queued, then written

        zc.subscribe("cbtc/train/+/report", on_report)
        train.subscribe("cbtc/train/A/cmd", lambda t, p: answers.append(p))
        for _ in range(20):   # the SUBACKs
            net.poll(0.01)
        for payload in (b"one", b"bad", b"two"):
            train.publish("cbtc/train/A/report", payload)
        wait_for(lambda: len(answers) == 2, 3.0, "two answers", net=net)
        assert answers == [b"answer to one", b"answer to two"]
        assert set(seen) == {threading.get_ident()} and len(seen) == 3
        assert net.errors == 1 and "ValueError" in net.last_error
        train.publish("cbtc/train/A/report", b"three")
        deadline = time.monotonic() + 3.0
        while len(seen) < 4 and time.monotonic() < deadline:
            net.poll(0.05)
        assert len(seen) == 4 and not zc._client.want_write()   # the answer left in the poll that read the report
    finally:
        train.disconnect()
        zc.disconnect()
    assert threading.active_count() == threads_before


@pytest.mark.mosquitto
@pytest.mark.parametrize("kind", Clients.KINDS)
def test_keepalive_keeps_a_publishing_client_connected_and_finds_a_broker_that_went_silent(mosquitto, kind):
    """A client that only publishes stays connected (it pings when nothing was read for the keepalive period); a
    broker that stops answering (stopped, its socket still open) is called lost within about 1.5 keepalive periods,
    and once it answers again the client is back."""
    import signal

    clients = Clients(kind)
    bus = clients.start(mosquitto.url, "train-A", keepalive_s=1, reconnect_max_s=0.5)
    try:
        for _ in range(32):   # 1.6 s of reports, 50 ms apart: past the 1.5 keepalive periods a silent link is lost in
            bus.publish("cbtc/train/A/report", b"r")
            clients.pause(0.05)
        assert bus.connected and bus.losses == 0
        os.kill(mosquitto.proc.pid, signal.SIGSTOP)
        try:
            started = time.monotonic()
            clients.wait_for(lambda: not bus.connected, 6.0, "the silent broker to be called lost")
            assert time.monotonic() - started < 4.0 and bus.losses == 1
        finally:
            os.kill(mosquitto.proc.pid, signal.SIGCONT)
        clients.wait_for(lambda: bus.connected, 10.0, "the way back")
    finally:
        bus.disconnect()


@pytest.mark.mosquitto
@pytest.mark.parametrize("kind", Clients.KINDS)
def test_status_goes_at_qos_1_and_reaches_a_qos_1_subscriber_as_qos_1(mosquitto, kind):
    import paho.mqtt.client as paho

    got = []
    raw = paho.Client(paho.CallbackAPIVersion.VERSION2, client_id="raw-watcher")
    raw.on_message = lambda _c, _u, msg: got.append((msg.topic, msg.payload, msg.qos, msg.retain))
    raw.connect("127.0.0.1", mosquitto.port)
    raw.subscribe("cbtc/train/+/status", qos=1)
    raw.loop_start()
    clients = Clients(kind)
    bus = None
    try:
        time.sleep(0.2)
        bus = clients.start(mosquitto.url, "train-A", status_topic="cbtc/train/A/status")
        clients.wait_for(lambda: got, 3.0, "the status")
        assert got[0] == ("cbtc/train/A/status", b"online", 1, False)
        assert topic_qos("cbtc/train/A/status") == 1 and topic_qos("cbtc/train/A/report") == 0
    finally:
        if bus is not None:
            bus.disconnect()
        raw.loop_stop()
        raw.disconnect()


@pytest.mark.mosquitto
@pytest.mark.parametrize("kind", Clients.KINDS)
def test_reconnect_attempts_back_off_to_their_ceiling(mosquitto, kind):
    """While the broker is away the client tries again at growing intervals, from reconnect_min_s up to
    reconnect_max_s: a listener on the broker's port that accepts and closes counts the attempts."""
    clients = Clients(kind)
    bus = clients.start(mosquitto.url, "sub", reconnect_min_s=0.1, reconnect_max_s=0.8)
    attempts = []
    try:
        mosquitto.kill()
        clients.wait_for(lambda: not bus.connected, 5.0, "the loss to be noticed")
        listener = socket.socket()
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        listener.bind(("127.0.0.1", mosquitto.port))
        listener.listen(16)
        listener.settimeout(0.01)
        deadline = time.monotonic() + 3.0   # attempts 0.1, 0.2, 0.4, 0.8, 0.8 s apart
        while time.monotonic() < deadline:
            try:
                conn, _ = listener.accept()
                attempts.append(time.monotonic())
                conn.close()
            except (socket.timeout, BlockingIOError):
                pass
            clients.pause(0.01)
        listener.close()
        gaps = [b - a for a, b in zip(attempts, attempts[1:])]
        assert 3 <= len(attempts) <= 20, attempts
        assert max(gaps) <= 0.8 * 1.5 + 0.3 and gaps[-1] > 1.5 * gaps[0], gaps   # growing, capped
    finally:
        bus.disconnect()
