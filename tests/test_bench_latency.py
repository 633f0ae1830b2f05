"""`cbtc bench latency` over a real Mosquitto on a free loopback port: the controller's report -> command figures,
the raw paho ping-pong reference from the same run, lost and unanswered reports, the controller's CPU. No timing is
asserted (the figures are for people); the test checks that every figure is measured."""

import json

import pytest

from cbtc.cli import main

pytestmark = pytest.mark.mosquitto


def test_bench_latency_sets_the_controller_beside_raw_paho(capsys, mosquitto):
    argv = ["bench", "latency", "--broker", mosquitto.url, "--trains", "3", "--rate", "10", "--duration", "1",
            "--warmup", "2", "--train-procs", "1", "--json"]
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["trains"] == 3 and out["rate_hz"] == 10.0
    # every train reported at 10 Hz or faster (the controller may ask a followed train for fast reports)
    assert out["reports_published"] >= 3 * 10 * 1 - 3
    assert out["reports_dropped"] == 0 and out["reports_unanswered"] == 0
    assert out["report_to_cmd_ms"]["n"] == out["reports_answered"] and out["report_to_cmd_ms"]["p99"] > 0
    ref = out["reference"]
    assert ref["pings_sent"] >= 3 * 10 * 1 - 3 and ref["pings_lost"] == 0
    assert ref["round_trip_ms"]["p50"] > 0 and out["p99_over_reference"] > 0
    assert 0.0 < out["controller_cpu_core_share"] < 2.0 and 0.0 < ref["answering_cpu_core_share"] < 2.0


def test_bench_latency_refuses_a_rate_the_board_cannot_send(capsys):
    assert main(["bench", "latency", "--rate", "500"]) == 2
    err = capsys.readouterr().err
    assert "--rate" in err and "<= 50" in err
