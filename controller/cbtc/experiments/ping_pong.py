"""The reference for `cbtc bench latency`: a raw paho-mqtt ping-pong with as many clients, at the same rate, through
the same broker, in the same process layout.

N "train" clients, shared out to child processes as the bench's trains are, each publish a ping of a report's size
on `bench/ping/<i>` at the rate asked (phases spread over the period); one "controller" client in this process answers
every ping at once on `bench/pong/<i>` with the same payload. Plain paho usage: its network thread per client
(`loop_start`), callbacks on that thread, TCP_NODELAY set on each socket. What it measures is what the broker and
paho cost a round trip with no control work at all: the floor the controller's report -> command time sits on.
"""

import multiprocessing
import resource
import socket
import struct
import time

import paho.mqtt.client as mqtt

from cbtc.bus.client import parse_broker_url
from cbtc.errors import BusError

PING_FILTER = "bench/ping/+"
PAYLOAD_BYTES = 220      # about a sealed report's size
TAIL_S = 0.3


def _client(url: str, client_id: str) -> mqtt.Client:
    """A connected paho client with its network thread running and Nagle off."""
    host, port, user, password = parse_broker_url(url)
    client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=client_id, clean_session=True)
    if user is not None:
        client.username_pw_set(user, password)
    client.connect(host, port, keepalive=5)
    client.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    client.loop_start()
    return client


def _cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def ping_pong(url: str, n_clients: int, rate_hz: float, duration_s: float, warmup_s: float, procs: int) -> dict:
    """Round trips (ms, p50 / p99 / max) of pings sent in the measured window, pings lost, and the answering
    process's CPU (share of one core) over the window."""
    from cbtc.experiments.latency import stats_ms
    answered = [0]

    def on_ping(client, _userdata, message):
        client.publish("bench/pong/" + message.topic.rsplit("/", 1)[1], message.payload)
        answered[0] += 1

    server = _client(url, "bench-pong")
    server.on_message = on_ping
    server.subscribe(PING_FILTER, qos=0)
    ctx = multiprocessing.get_context("spawn")
    groups = [list(range(k, n_clients, procs)) for k in range(min(procs, n_clients))]
    pipes, children = [], []
    try:
        for group in groups:
            here, there = ctx.Pipe()
            child = ctx.Process(target=_pingers, args=(there, url, group, n_clients, rate_hz), daemon=True)
            child.start()
            pipes.append(here)
            children.append(child)
        for here in pipes:
            ready = here.recv() if here.poll(30.0) else "no answer within 30 s"
            if ready != "ready":
                raise BusError(f"bench: a ping process failed: {ready}")
        t0 = time.monotonic() + warmup_s + 0.2
        t1 = t0 + duration_s
        for here in pipes:
            here.send((t0 - warmup_s, t1))
        time.sleep(max(0.0, t0 - time.monotonic()))
        cpu0 = _cpu_s()
        time.sleep(max(0.0, t1 - time.monotonic()))
        cpu1 = _cpu_s()
        rtts, sent = [], 0
        for here in pipes:
            if not here.poll(10.0 + TAIL_S):
                raise BusError("bench: a ping process sent no results")
            found = here.recv()
            if isinstance(found, str):
                raise BusError(f"bench: a ping process failed: {found}")
            for t_sent, t_back in found:
                if t0 <= t_sent <= t1:
                    sent += 1
                    if t_back is not None:
                        rtts.append(t_back - t_sent)
    finally:
        server.loop_stop()
        server.disconnect()
        for child in children:
            child.join(5.0)
            if child.is_alive():
                child.kill()
    return {"round_trip_ms": stats_ms(rtts), "pings_sent": sent, "pings_lost": sent - len(rtts),
            "answering_cpu_core_share": round((cpu1 - cpu0) / duration_s, 3)}


def _pingers(conn, url, indices, n_clients, rate_hz):
    """A child process: the ping clients `indices`; sends back (sent, answered or None) monotonic times."""
    clients = []
    try:
        back = {}

        def on_pong(_client, _userdata, message):
            back[message.payload[:12]] = time.monotonic()

        for i in indices:
            client = _client(url, f"bench-ping-{i}")
            client.on_message = on_pong
            client.subscribe(f"bench/pong/{i}", qos=0)
            clients.append(client)
        time.sleep(0.2)    # the SUBACKs
        conn.send("ready")
        start_s, t1 = conn.recv()
        period_s = 1.0 / rate_hz
        # each client's sends at start + phase + k period, phases spread over the period as independent boards'
        due = [(start_s + period_s * i / n_clients, i, client) for i, client in zip(indices, clients)]
        sent = {}
        n = 0
        while True:
            due.sort(key=lambda d: d[0])
            t_s, i, client = due[0]
            if t_s > t1:
                break
            wait_s = t_s - time.monotonic()
            if wait_s > 0:
                time.sleep(wait_s)
            tag = struct.pack(">IQ", i, n)
            n += 1
            sent[tag] = time.monotonic()
            client.publish(f"bench/ping/{i}", tag + b"x" * (PAYLOAD_BYTES - len(tag)), qos=0)
            due[0] = (t_s + period_s, i, client)
        time.sleep(TAIL_S)
        conn.send([(t, back.get(tag)) for tag, t in sent.items()])
    except Exception as exc:  # report to the parent instead of dying silently
        conn.send(f"{type(exc).__name__}: {exc}")
    finally:
        for client in clients:
            client.loop_stop()
            client.disconnect()
