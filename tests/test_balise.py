"""Balises that carry their position: telegram images, decoding with bit errors, the reader's fall-backs, the wire."""

import pytest

from cbtc.layout_files import load_layout
from cbtc.protocol import wire, wire_zc
from cbtc.railway import balise
from cbtc.sim.simulation import Simulation
from cbtc.zone.config import paper_scenario

KEY = b"0123456789abcdef"


def test_image_round_trip_and_every_single_bit_error_corrected():
    data = balise.image(7, 4.0053)
    assert len(data) == 16 and data[-1] & 0x03 == 0          # 126 bits packed, two pad bits
    assert balise.read(data.hex()) == (7, 4.005, "ok")
    for bit in range(balise.FRAME_BITS):
        bad = bytearray(data)
        bad[bit >> 3] ^= 0x80 >> (bit & 7)
        assert balise.read(bad.hex()) == (7, 4.005, "corrected"), bit


def test_two_bit_errors_are_rejected_and_bad_hex_is_named():
    bad = bytearray(balise.image(7, 4.0053))
    bad[0] ^= 0x01
    bad[9] ^= 0x20
    assert balise.read(bad.hex()) == (None, None, "detected")
    with pytest.raises(ValueError, match="not hex"):
        balise.read("zz" * 16)
    with pytest.raises(ValueError, match="16"):
        balise.read("00" * 8)


def test_the_reader_trusts_a_telegram_checks_it_against_the_layout_and_falls_back_to_the_uid():
    layout = load_layout("itb_square")
    tag = layout.tags[4]
    reader = balise.BaliseReader(layout)
    # a telegram alone locates a tag the layout does not list: no survey table needed
    assert reader.position_m("0000BEEF", balise.image(99, 3.2).hex()) == pytest.approx(3.2)
    # the telegram agrees with the layout
    assert reader.position_m(tag.uid, balise.image(5, tag.s_m).hex()) == pytest.approx(tag.s_m, abs=5e-4)
    # the tag was moved 10 cm but the layout says otherwise: neither is trusted
    assert reader.position_m(tag.uid, balise.image(5, tag.s_m + 0.1).hex()) is None
    # a rejected telegram: the uid's entry in the layout
    bad = bytearray(balise.image(5, tag.s_m))
    bad[0] ^= 0x03
    assert reader.position_m(tag.uid, bad.hex()) == tag.s_m
    # a plain tag (no data) that the layout does not list
    assert reader.position_m("0000BEEF") is None
    assert reader.counts == {"telegram_ok": 3, "telegram_corrected": 0, "telegram_rejected": 1, "mismatch": 1,
                             "unknown": 1}


def test_reports_carry_balise_data_and_malformed_data_is_refused():
    data = balise.image(1, 0.15).hex()
    payload = wire.encode_report(KEY, "A", 1, 1, 1000, 150, 400, 50, "run", -1, -1, None,
                                 [["04A100A1", 150, 990, 8, data]], [], None)
    report = wire_zc.decode_report(KEY, "cbtc/train/A/report", payload)
    assert report["tags"] == [["04A100A1", 150, 990, 8, data]]
    payload = wire.encode_report(KEY, "A", 1, 2, 1000, 150, 400, 50, "run", -1, -1, None,
                                 [["04A100A1", 150, 990, 8, "abc"]], [], None)
    with pytest.raises(wire.WireError, match="32 hex digits"):
        wire_zc.decode_report(KEY, "cbtc/train/A/report", payload)


def test_trains_locate_on_balise_telegrams_alone():
    """The controller's layout lists no tag at all; the tags' telegrams still place the trains as well as a surveyed
    layout does (this seed: RMSE 10.3 and 8.0 mm both ways, from the first fix on)."""
    layout = load_layout("itb_square")
    sim = Simulation(paper_scenario(layout, seed=1, laps=1, duration_s=40.0))
    for state in sim.zc.trains.values():
        state.estimator.balises.layout = _WithoutTags(layout)
    summary = sim.run().summary()
    assert summary["collisions"] == 0 and summary["authority_overruns"] == 0
    for train in summary["trains"]:
        assert train["estimation_rmse_m"] < 0.015
    counts = sim.zc.state_of("A").estimator.counters()
    assert counts["balise_telegram_ok"] + counts["balise_telegram_corrected"] >= 6
    assert counts["unknown_tags"] == counts["balise_telegram_rejected"]


class _WithoutTags:
    """A layout that knows no tags (as if nobody surveyed them)."""

    def __init__(self, layout):
        self._layout = layout

    def tag_by_uid(self, uid):
        return None

    def __getattr__(self, name):
        return getattr(self._layout, name)
