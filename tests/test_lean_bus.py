"""The lean MQTT client: its packets against the 3.1.1 layout, the parser fed in any chunks, and against a real
Mosquitto, beside paho: routing both ways, a handler's answer written in the poll that read the message, refusal
of wrong credentials. Refusal with no broker, retained status and last will (QoS 1 acknowledged), and reconnect run
for it and for paho in test_mqtt_clients.py."""

import socket
import threading
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cbtc.bus import mqtt_packets as mp
from cbtc.bus.client import BusClient
from cbtc.bus.lean_bus import LeanBus
from cbtc.bus.net_loop import NetLoop
from cbtc.bus.paho_bus import PahoBus
from cbtc.errors import BusError


def poll_until(net, predicate, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return
        net.poll(0.01)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


def test_packets_have_the_3_1_1_layout():
    assert mp.publish("a/b", b"xy") == b"\x30\x07\x00\x03a/bxy"
    assert mp.publish("a", b"", qos=1, retain=True, packet_id=258) == b"\x33\x05\x00\x01a\x01\x02"
    assert mp.publish("t", b"x" * 200)[:3] == b"\x30\xcb\x01"    # 203 bytes: two length bytes, low 7 bits first
    assert mp.puback(7) == b"\x40\x02\x00\x07"
    assert mp.subscribe(1, [("a/+", 0), ("s", 1)]) == b"\x82\x0c\x00\x01\x00\x03a/+\x00\x00\x01s\x01"
    assert mp.unsubscribe(2, ["a/+"]) == b"\xa2\x07\x00\x02\x00\x03a/+"
    assert mp.pingreq() == b"\xc0\x00" and mp.disconnect() == b"\xe0\x00"
    connect = mp.connect("zc", 5, will=("s", b"off", 1, True), username="u", password="p")
    assert connect == (b"\x10\x1c\x00\x04MQTT\x04\xee\x00\x05" + b"\x00\x02zc" + b"\x00\x01s\x00\x03off"
                       + b"\x00\x01u\x00\x01p")
    assert mp.connect("x", 60)[8:10] == b"\x04\x02"   # clean session alone
    assert mp.parse_publish(0x33, b"\x00\x01a\x01\x02xyz") == ("a", b"xyz", 1, 258, True)
    with pytest.raises(mp.ProtocolError):
        mp.parse_publish(0x34, b"\x00\x01a\x00\x01")     # QoS 2: never subscribed to
    with pytest.raises(mp.ProtocolError):
        mp.split(bytearray(b"\x30\xff\xff\xff\xff\x01"))   # a length of five bytes


@settings(max_examples=200, deadline=None)
@given(messages=st.lists(st.tuples(st.sampled_from(["cbtc/train/A/report", "a", "x/y/z"]), st.binary(max_size=300),
                                   st.integers(0, 1)), min_size=1, max_size=8),
       cuts=st.lists(st.integers(1, 64), max_size=40))
def test_the_parser_gives_back_every_packet_whatever_chunks_the_bytes_come_in(messages, cuts):
    stream = b"".join(mp.publish(t, p, q, False, 9 if q else 0) for t, p, q in messages)
    buffer, got, pos = bytearray(), [], 0
    for n in cuts + [len(stream)]:
        buffer += stream[pos:pos + n]
        pos += n
        got += [mp.parse_publish(first, body)[:3] for first, body in mp.split(buffer)]
    assert got == [(t, p, q) for t, p, q in messages] and not buffer


def _packet(kind, flags, body):
    return bytes((kind | flags,)) + mp._remaining(len(body)) + body


_HOSTILE = st.one_of(
    st.binary(max_size=80),                                                     # line noise
    st.builds(_packet, st.sampled_from([mp.CONNACK, mp.PUBLISH, mp.PUBACK, mp.SUBACK, mp.UNSUBACK, mp.PINGRESP,
                                        0x00, 0x50, 0x60, 0x70, 0xF0]),
              st.integers(0, 15), st.binary(max_size=60)),                      # any type, flags and body
    st.builds(lambda topic_len, rest, qos: _packet(mp.PUBLISH, qos << 1, topic_len.to_bytes(2, "big") + rest),
              st.integers(0, 0xFFFF), st.binary(max_size=40), st.integers(0, 3)),   # a topic length that lies
    st.just(b"\x30\xff\xff\xff\x7f"),                                            # the largest length stated
)


@settings(max_examples=300, deadline=None)
@given(chunks=st.lists(_HOSTILE, min_size=1, max_size=12))
def test_hostile_broker_bytes_end_at_most_the_connection_and_never_raise_past_the_client(chunks):
    """Whatever a broker (or whatever answers on its port) sends: the client takes the packets it can, hands only
    whole, well-formed PUBLISHes to its subscriber, and on bytes that are no MQTT closes the connection to open it
    again; no exception leaves `net_read`."""
    bus = LeanBus("mqtt://127.0.0.1:1", "fuzzed", net=NetLoop())
    near, far = socket.socketpair()
    near.setblocking(False)
    bus._sock, bus._connected, bus.connects = near, True, 1   # connected once already: a loss is retried
    got = []
    bus.subscribe("#", lambda topic, payload: got.append((topic, payload)))
    try:
        for chunk in chunks:
            far.sendall(chunk)
            bus.net_read()
            if bus._sock is None:   # a protocol error: the connection is closed, to be opened again
                assert bus._retry_due_s is not None and not bus._connected
                break
        assert all(isinstance(t, str) and isinstance(p, bytes) for t, p in got)
    finally:
        far.close()
        if bus._sock is not None:
            bus._sock.close()


def test_a_publish_whose_topic_length_runs_past_its_packet_is_refused():
    with pytest.raises(mp.ProtocolError, match="topic longer than its packet"):
        mp.parse_publish(0x30, b"\x00\x09abc")


@pytest.mark.mosquitto
def test_lean_and_paho_clients_talk_both_ways_and_the_answer_leaves_in_the_poll_that_read_the_message(mosquitto):
    threads_before = threading.active_count()
    net = NetLoop()
    zc = LeanBus(mosquitto.url, "zc", net=net).start()
    train = PahoBus(mosquitto.url, "train-A", status_topic="cbtc/train/A/status", net=net).start()
    assert isinstance(zc, BusClient) and zc.connected and threading.active_count() == threads_before
    try:
        assert zc.net_socket().getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
        seen, answers = [], []

        def on_report(topic, payload):
            seen.append((topic, threading.get_ident()))
            if payload == b"bad":
                raise ValueError("a handler's bug")
            zc.publish("cbtc/train/A/cmd", b"answer to " + payload)

        zc.subscribe("cbtc/train/+/report", on_report)
        train.subscribe("cbtc/train/A/cmd", lambda t, p: answers.append(p))
        for _ in range(20):   # the SUBACKs
            net.poll(0.01)
        for payload in (b"one", b"bad", b"two" * 100):
            train.publish("cbtc/train/A/report", payload)
        train.publish("cbtc/train/A/cmd_not_a_report", b"not for the filter")
        poll_until(net, lambda: len(answers) == 2, 3.0, "two answers")
        assert answers == [b"answer to one", b"answer to " + b"two" * 100]
        assert {ident for _, ident in seen} == {threading.get_ident()} and len(seen) == 3
        assert net.errors == 1 and "ValueError" in net.last_error
        train.publish("cbtc/train/A/report", b"three")
        poll_until(net, lambda: len(seen) == 4, 3.0, "the fourth report")
        assert not zc.net_wants_write()   # its answer left in the poll that read the report
        zc.unsubscribe("cbtc/train/+/report")
        for _ in range(20):
            net.poll(0.01)
        train.publish("cbtc/train/A/report", b"four")
        for _ in range(30):
            net.poll(0.01)
        assert len(seen) == 4
    finally:
        train.disconnect()
        zc.disconnect()
    assert threading.active_count() == threads_before


@pytest.mark.mosquitto
def test_wrong_credentials_are_refused_with_the_brokers_reason(secured_mosquitto):
    broker, creds = secured_mosquitto(["A"])
    user = next(iter(creds))
    bus = LeanBus(broker.url, "intruder", username=user, password="wrong", net=NetLoop())
    with pytest.raises(BusError, match="refused the connection .*(bad user name or password|not authorised)"):
        bus.start(timeout_s=5.0)
    ok = LeanBus(broker.url, "zc-ok", username=user, password=creds[user], net=NetLoop()).start()
    assert ok.connected
    ok.disconnect()


@pytest.mark.mosquitto
def test_a_client_that_only_publishes_pings_the_broker_and_stays_connected(mosquitto):
    """A board whose commands never come (a wrong key) still publishes every 50 ms: it hears nothing from the broker
    unless it asks, so it pings when nothing was read for the keepalive period rather than call the broker lost."""
    net = NetLoop()
    train = LeanBus(mosquitto.url, "train-A", net=net, keepalive_s=1).start()
    try:
        deadline = time.monotonic() + 2.2   # a loss is called after 1.5 keepalive periods with nothing read
        while time.monotonic() < deadline:
            train.publish("cbtc/train/A/report", b"r")
            net.poll(0.05)
        assert train.connected and train.losses == 0
    finally:
        train.disconnect()
