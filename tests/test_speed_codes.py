"""Fixed-block speed codes reach the trains as Hamming-coded telegrams: corrected, rejected to the lowest code, safe."""

import pytest

from cbtc.authority.speed_code_channel import SpeedCodeChannel
from cbtc.layout_files import load_layout
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import paper_scenario


def test_a_clean_channel_delivers_every_code():
    channel = SpeedCodeChannel(0.0)
    assert [channel.transmit(7, code) for code in range(8)] == list(range(8))
    assert channel.counts == {"sent": 8, "ok": 8, "corrected": 0, "detected": 0, "undetected": 0}


def test_a_noisy_channel_corrects_single_errors_and_rejects_to_the_lowest_code():
    channel = SpeedCodeChannel(0.01, seed=5)
    received = [channel.transmit(3, 2) for _ in range(3000)]
    counts = channel.counts
    assert counts["corrected"] > 300 and counts["detected"] > 50 and counts["undetected"] == 0
    assert set(received) == {0, 2}                       # the sent code, or the lowest one when rejected
    assert received.count(0) == counts["detected"]


def test_bad_bit_error_rate_is_refused():
    with pytest.raises(ValueError, match="ber"):
        SpeedCodeChannel(0.7)


def test_fixed_block_with_corrupted_codes_stays_safe():
    layout = load_layout("itb_square")
    config = paper_scenario(layout, seed=2, laps=1, duration_s=60.0, policy="fixed_block",
                            policy_options={"code_ber": 0.01})
    sim = Simulation(config)
    summary = sim.run().summary()
    counts = sim.policy.codes.counts
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    assert counts["corrected"] > 0 and counts["detected"] > 0 and counts["undetected"] == 0
