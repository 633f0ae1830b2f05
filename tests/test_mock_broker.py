"""The mock broker: MQTT matching, latency on the virtual clock, ordering, loss, retained, wills, outages."""

import pytest

from cbtc.bus import topic_matches, validate_filter, validate_topic
from cbtc.mock_broker import LinkProfile, MockBroker
from cbtc.scheduler import VirtualScheduler


@pytest.mark.parametrize("filt, topic, expected", [
    ("a/b/c", "a/b/c", True), ("a/+/c", "a/x/c", True), ("a/+/c", "a/x/y/c", False), ("a/#", "a", True),
    ("a/#", "a/b/c", True), ("#", "a/b", True), ("#", "$SYS/x", False), ("+/x", "$SYS/x", False),
    ("$SYS/#", "$SYS/x", True), ("a/+", "a", False), ("cbtc/train/+/report", "cbtc/train/A/report", True),
])
def test_topic_matching(filt, topic, expected):
    assert topic_matches(filt, topic) is expected


@pytest.mark.parametrize("bad", ["a/#/b", "a/b#", "a/+b", ""])
def test_invalid_filters_are_named(bad):
    with pytest.raises(ValueError) as err:
        validate_filter(bad)
    assert repr(bad) in str(err.value)


def test_publish_topics_reject_wildcards():
    with pytest.raises(ValueError, match="wildcards"):
        validate_topic("a/+/b")


def make(seed=0):
    sched = VirtualScheduler()
    return sched, MockBroker(sched, seed=seed)


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
    late = broker.connect("late")
    got = []
    late.subscribe("status/+", lambda topic, payload: got.append((topic, payload)))
    sched.run_until(0.2)
    assert got == [("status/A", b"online")]


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


def test_broker_outage_drops_messages_and_clients_resubscribe_on_reconnect():
    sched, broker = make()
    pub = broker.connect("pub")
    sub = broker.connect("sub")
    got = []

    def subscribe(client):
        client.subscribe("t", lambda topic, payload: got.append(payload))
    sub.on_connect = subscribe
    subscribe(sub)
    broker.stop()
    pub.publish("t", b"lost")
    assert not sub.reconnect()
    broker.start()
    assert pub.reconnect() and sub.reconnect()
    pub.publish("t", b"after")
    sched.run_until(0.1)
    assert got == [b"after"] and broker.stats["dropped_down"] >= 1


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
