"""The mock broker: MQTT matching, latency on the virtual clock, ordering, loss, retained, wills, outages."""

import pytest

from cbtc.bus.client import BusClient, topic_matches, validate_filter, validate_topic
from cbtc.bus.mock_broker import LinkProfile, MockBroker
from cbtc.errors import BusError
from cbtc.scheduler import VirtualScheduler


@pytest.mark.parametrize("filt, topic, expected", [
    ("a/b/c", "a/b/c", True), ("a/+/c", "a/x/c", True), ("a/+/c", "a/x/y/c", False), ("a/#", "a", True),
    ("a/#", "a/b/c", True), ("#", "a/b", True), ("#", "$SYS/x", False), ("+/x", "$SYS/x", False),
    ("$SYS/#", "$SYS/x", True), ("a/+", "a", False), ("cbtc/train/+/report", "cbtc/train/A/report", True),
    ("a/b/#", "a/b", True), ("+", "a/b", False), ("+/+", "a/b", True), ("a/b", "a/b/c", False), ("/+", "/x", True),
    ("+/+", "/x", True), ("#", "$SYS", False), ("a/+/c", "a//c", True), ("A/b", "a/b", False),
])
def test_topic_matching(filt, topic, expected):
    assert topic_matches(filt, topic) is expected


@pytest.mark.parametrize("bad, rule", [("a/#/b", "last"), ("a/b#", "whole level"), ("a/+b", "whole level"),
                                       ("", "non-empty"), ("a/\x00", "NUL")])
def test_invalid_filters_are_named(bad, rule):
    with pytest.raises(ValueError) as err:
        validate_filter(bad)
    assert repr(bad) in str(err.value) and rule in str(err.value)


@pytest.mark.parametrize("bad, rule", [("a/+/b", "wildcards"), ("a/#", "wildcards"), ("", "non-empty"),
                                       ("x" * 65536, "65535 bytes"), ("\u00e9" * 32768, "65535 bytes")])
def test_invalid_publish_topics(bad, rule):
    with pytest.raises(ValueError, match=rule):
        validate_topic(bad)


def test_limits_are_inclusive():
    assert validate_topic("x" * 65535) and validate_filter("+/#")


def make(seed=0):
    sched = VirtualScheduler()
    return sched, MockBroker(sched, seed=seed)


def test_clients_implement_the_bus_interface():
    sched, broker = make()
    assert isinstance(broker.connect("c"), BusClient)


def test_latency_is_up_plus_down_on_the_virtual_clock():
    sched, broker = make()
    pub = broker.connect("pub", up=LinkProfile(latency_s=0.005))
    sub = broker.connect("sub", down=LinkProfile(latency_s=0.007))
    got = []
    sub.subscribe("t/#", lambda topic, payload: got.append((sched.now_s(), topic, payload)))
    pub.publish("t/1", b"x")
    sched.run_until(1.0)
    assert got == [(pytest.approx(0.012), "t/1", b"x")]


def test_order_is_kept_with_jitter_and_each_message_arrives_once():
    sched, broker = make(seed=3)
    jitter = LinkProfile(latency_s=0.001, jitter_s=0.05)
    pub = broker.connect("pub", up=jitter)
    sub = broker.connect("sub", down=jitter)
    got = []
    sub.subscribe("t/#", lambda topic, payload: got.append(int(payload)))
    sub.subscribe("t/+", lambda topic, payload: None)
    for i in range(200):
        sched.call_at(i * 0.001, pub.publish, "t/x", str(i).encode())
    sched.run_until(5.0)
    assert got == list(range(200))


def test_a_reordering_link_lets_later_messages_overtake_and_a_duplicating_one_delivers_twice():
    for link, check in ((LinkProfile(latency_s=0.001, reorder=0.3, reorder_s=0.02),
                         lambda got: sorted(got) == list(range(200)) and got != sorted(got)),
                        (LinkProfile(latency_s=0.001, duplicate=0.3),
                         lambda got: set(got) == set(range(200)) and 30 < len(got) - 200 < 90 and got == sorted(got))):
        sched, broker = make(seed=3)
        pub = broker.connect("pub", up=link)
        sub = broker.connect("sub")
        got = []
        sub.subscribe("t/#", lambda topic, payload, got=got: got.append(int(payload)))
        for i in range(200):
            sched.call_at(i * 0.005, pub.publish, "t/x", str(i).encode())
        sched.run_until(5.0)
        assert check(got), got
    with pytest.raises(ValueError, match="duplicate in"):
        LinkProfile(duplicate=1.5)


def test_same_seed_same_delivery_times():
    def run(seed):
        sched, broker = make(seed=seed)
        pub = broker.connect("pub", up=LinkProfile(latency_s=0.001, jitter_s=0.01))
        sub = broker.connect("sub", down=LinkProfile(latency_s=0.001, jitter_s=0.01, loss=0.1))
        got = []
        sub.subscribe("t", lambda topic, payload: got.append((sched.now_s(), payload)))
        for i in range(100):
            sched.call_at(i * 0.02, pub.publish, "t", str(i).encode())
        sched.run_until(3.0)
        return got
    first = run(4)
    assert run(4) == first and run(5) != first
    assert all(0.002 <= t_s - int(p) * 0.02 <= 0.022 + 1e-12 for t_s, p in first)  # latency + jitter bounds


def test_set_link_at_run_time_never_reorders():
    sched, broker = make()
    pub = broker.connect("pub", up=LinkProfile(latency_s=0.1))
    sub = broker.connect("sub", down=LinkProfile(latency_s=0.0))
    got = []
    sub.subscribe("t", lambda topic, payload: got.append((sched.now_s(), payload)))
    pub.publish("t", b"slow")
    broker.set_link("pub", up=LinkProfile(latency_s=0.01))
    pub.publish("t", b"fast")  # would arrive at 0.01 s, but may not overtake "slow" (0.1 s)
    sched.run_until(0.5)
    pub.publish("t", b"later")
    sched.run_until(1.0)
    assert got == [(pytest.approx(0.1), b"slow"), (pytest.approx(0.1), b"fast"), (pytest.approx(0.51), b"later")]
    with pytest.raises(BusError, match="nobody"):
        broker.set_link("nobody", up=LinkProfile())


def test_loss_rate_and_determinism():
    def run(seed):
        sched, broker = make(seed=seed)
        pub = broker.connect("pub", up=LinkProfile(loss=0.2))
        sub = broker.connect("sub")
        got = []
        sub.subscribe("t", lambda topic, payload: got.append(payload))
        for i in range(10_000):
            pub.publish("t", str(i).encode())
        sched.run_until(1.0)
        return got
    first = run(1)
    assert 1 - len(first) / 10_000 == pytest.approx(0.2, abs=0.02)
    assert run(1) == first and run(2) != first


def test_retained_and_deleted_by_empty_payload():
    sched, broker = make()
    pub = broker.connect("pub")
    pub.publish("status/A", b"online", retain=True)
    pub.publish("status/B", b"online", retain=True)
    pub.publish("status/B", b"", retain=True)
    sched.run_until(0.1)
    late = broker.connect("late", down=LinkProfile(latency_s=0.03))
    got = []
    late.subscribe("status/+", lambda topic, payload: got.append((sched.now_s(), topic, payload)))
    sched.run_until(0.2)
    assert got == [(pytest.approx(0.13), "status/A", b"online")]
    assert broker.stats["retained"] == 1


def test_will_on_kill_not_on_clean_disconnect():
    sched, broker = make()
    watcher = broker.connect("watcher")
    got = []
    watcher.subscribe("status/#", lambda topic, payload: got.append((topic, payload)))
    a = broker.connect("a", will=("status/a", b"offline", True))
    b = broker.connect("b", will=("status/b", b"offline", True))
    b.disconnect()
    broker.kill_client("a")
    sched.run_until(0.1)
    assert got == [("status/a", b"offline")]
    a.publish("status/a", b"ghost")  # a dead client sends nothing
    sched.run_until(0.2)
    assert len(got) == 1


def test_a_killed_clients_messages_in_flight_are_lost():
    sched, broker = make()
    pub = broker.connect("pub", up=LinkProfile(latency_s=0.05))
    sub = broker.connect("sub")
    got = []
    sub.subscribe("t", lambda topic, payload: got.append(payload))
    pub.publish("t", b"on the wire")
    sched.run_until(0.01)
    broker.kill_client("pub")
    sched.run_until(0.2)
    assert got == [] and broker.stats["dropped_down"] == 1


def test_takeover_closes_the_old_session_without_its_will():
    sched, broker = make()
    watcher = broker.connect("watcher")
    status = []
    watcher.subscribe("status/#", lambda topic, payload: status.append(payload))
    old = broker.connect("train-A", will=("status/A", b"offline", True))
    old.subscribe("cmd", lambda topic, payload: None)
    new = broker.connect("train-A", will=("status/A", b"offline", True))
    got = []
    new.subscribe("cmd", lambda topic, payload: got.append(payload))
    watcher.publish("cmd", b"go")
    sched.run_until(0.1)
    assert not old.connected and new.connected and got == [b"go"] and status == []


def test_keepalive_expiry_publishes_the_will():
    sched, broker = make()
    watcher = broker.connect("watcher")
    got = []
    watcher.subscribe("status/#", lambda topic, payload: got.append((sched.now_s(), payload)))
    train = broker.connect("train", will=("status/train", b"offline", True), keepalive_s=1.0,
                           up=LinkProfile(latency_s=0.01))
    sched.run_until(10.0)
    assert got == [] and train.connected, "an idle client that pings stays alive"
    broker.set_link("train", up=LinkProfile(latency_s=0.01, loss=1.0))  # last ping heard at 10.01 s
    sched.run_until(20.0)
    # declared dead 1.5 keep-alive periods after it was last heard, will delivered 2 ms later
    assert got == [(pytest.approx(10.01 + 1.5 + 0.002), b"offline")]
    assert not train.connected and broker.stats["keepalive_expired"] == 1


def test_broker_outage_drops_messages_and_clients_resubscribe_on_reconnect():
    sched, broker = make()
    pub = broker.connect("pub")
    sub = broker.connect("sub")
    got = []

    def subscribe(client):
        client.subscribe("t", lambda topic, payload: got.append(payload))
    sub.on_connect = subscribe
    subscribe(sub)
    pub.publish("t", b"in flight")  # still on the wire when the broker goes down
    broker.stop()
    pub.publish("t", b"lost")
    assert not sub.reconnect() and not sub.connected
    newcomer = broker.connect("newcomer")   # a client made while the broker is down waits to reconnect
    assert not newcomer.connected
    broker.start()
    assert pub.reconnect() and sub.reconnect() and newcomer.reconnect() and newcomer.connected
    pub.publish("t", b"after")
    sched.run_until(0.1)
    assert got == [b"after"] and broker.stats["dropped_down"] == 2


def test_a_failing_callback_is_counted_and_others_still_receive():
    sched, broker = make()
    pub = broker.connect("pub")
    bad = broker.connect("bad")
    good = broker.connect("good")
    got = []
    bad.subscribe("t", lambda topic, payload: 1 / 0)
    good.subscribe("t", lambda topic, payload: got.append(payload))
    pub.publish("t", b"x")
    sched.run_until(0.1)
    assert got == [b"x"] and broker.stats["callback_errors"] == 1
    assert "ZeroDivisionError" in broker.last_error and "bad" in broker.last_error


def test_payload_must_be_bytes():
    sched, broker = make()
    with pytest.raises(TypeError, match="t/1"):
        broker.connect("c").publish("t/1", "text")
