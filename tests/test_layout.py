"""Layouts: the shipped files, LEGO pieces, railway look-ups, validation errors that name file, key and fix, the CLI."""

import math

import numpy as np
import pytest
import yaml

from cbtc.cli import main as cbtc_main
from cbtc.errors import LayoutError
from cbtc.layout_files import layout_names, load_layout, path_layout_names
from cbtc.railway.layout import Block
from cbtc.railway.layout_dict import CLOSE_TOLERANCE_DEG, CLOSE_TOLERANCE_M, layout_from_dict

SHIPPED = {"itb_square", "lego_oval", "lego_chicane", "straight_test"}


def test_every_shipped_layout_loads_and_loops_close():
    assert SHIPPED <= set(layout_names())
    assert SHIPPED | {"lego_passing_loop", "lego_branch", "lego_merge"} <= set(layout_names())
    assert set(path_layout_names()) == set(layout_names()) - {"lego_passing_loop", "lego_branch", "lego_figure_eight",
                                                              "lego_merge"}
    for name in path_layout_names():
        layout = load_layout(name)
        assert layout.name == name and layout.length_m > 0
        if layout.closed:
            (x0, y0, h0), (x1, y1, h1) = layout.path.start_pose, layout.path.end_pose
            assert math.hypot(x1 - x0, y1 - y0) < CLOSE_TOLERANCE_M
            assert abs(math.degrees(h1 - h0) - 360.0) < CLOSE_TOLERANCE_DEG
    assert load_layout("itb_square.yaml").length_m == load_layout("itb_square").length_m


def test_itb_square_railway():
    sq = load_layout("itb_square")
    assert [st.name for st in sq.stations] == ["main", "A", "B"]
    corner_m = math.pi / 2 * 0.32
    for i, st in enumerate(sq.stations):                 # the middle of straights 1, 2, 3
        assert st.s_m == pytest.approx(0.6 + i * (1.2 + corner_m), abs=1e-4) and st.window_m == 0.03
    assert len(sq.tags) == 12 and len({t.uid for t in sq.tags}) == 12
    assert all(len(t.uid) == 8 and t.uid == t.uid.upper() for t in sq.tags)  # 4-byte UIDs, as an MFRC522 reads them
    assert [b.name for b in sq.blocks] == ["B1", "B2", "B3", "B4"]
    assert sum(sq.ahead_m(b.start_m, b.end_m) or sq.length_m for b in sq.blocks) == pytest.approx(sq.length_m)
    assert len(sq.ips.beacons) == 4 and all(z == 1.0 for _x, _y, z in sq.ips.beacons)


def test_lego_oval_length_from_pieces():
    oval = load_layout("lego_oval")
    assert oval.length_m == pytest.approx(24 * 0.128 + 2 * math.pi * 0.32, abs=1e-12)
    assert oval.segment_count == 40 and len(oval.blocks) == 6 and len(oval.stations) == 2


def test_chicane_turns_both_ways():
    chicane = load_layout("lego_chicane")
    _x, _y, h = chicane.pose(np.linspace(0.0, chicane.length_m, 2000, endpoint=False))
    turn = np.diff(h)
    assert (turn > 1e-6).any() and (turn < -1e-6).any()


@pytest.mark.parametrize("piece, radius_m", [("curve_r40", 0.320), ("curve_r56", 0.448), ("curve_r72", 0.576)])
def test_sixteen_curves_make_a_circle(piece, radius_m):
    circle = layout_from_dict({"closed": True, "segments": [{"piece": piece, "count": 16}]}, "circle.yaml")
    assert circle.length_m == pytest.approx(2 * math.pi * radius_m, abs=1e-12)
    assert circle.pose(circle.length_m / 2)[:2] == pytest.approx((0.0, 2 * radius_m), abs=1e-12)


def test_straight_pieces_and_the_generic_curve():
    line = layout_from_dict({"closed": False, "segments": [
        {"piece": "straight", "count": 2}, {"piece": "half_straight"}, {"piece": "quarter_straight"},
        {"piece": "curve", "radius_studs": 104, "angle_deg": 11.25, "turn": "right", "count": 8}]}, "line.yaml")
    straight_m = 2 * 0.128 + 0.064 + 0.032
    assert line.length_m == pytest.approx(straight_m + 0.832 * math.pi / 2, abs=1e-12)
    # 8 x 11.25 degrees right on R104 (0.832 m): a quarter circle ending heading -y
    assert line.pose(line.length_m) == pytest.approx((straight_m + 0.832, -0.832, -math.pi / 2), abs=1e-12)
    assert line.segment_count == 12


def test_lookups():
    sq = load_layout("itb_square")
    assert sq.station("A").s_m == pytest.approx(2.3027)
    with pytest.raises(LayoutError, match=r"\['main', 'A', 'B'\]"):
        sq.station("C")
    assert sq.tag_by_uid("04A100B2").s_m == pytest.approx(2.3027)
    assert sq.tag_by_uid("04a100b2") == sq.tag_by_uid("04A100B2")
    assert sq.tag_by_uid("DEADBEEF00") is None
    quarter = sq.length_m / 4
    assert sq.block_at(0.0).name == "B1" and sq.block_at(quarter - 1e-9).name == "B1"
    assert sq.block_at(quarter).name == "B2" and sq.block_at(sq.length_m - 1e-9).name == "B4"
    assert sq.block_at(sq.length_m + 0.1).name == "B1"
    assert load_layout("straight_test").block_at(1.0) is None


def test_explicit_blocks_may_wrap_the_seam_and_are_joined_exactly():
    data = {"closed": True, "segments": [{"piece": "curve_r40", "count": 16}],
            "blocks": [{"name": "N", "start_m": 0.5, "end_m": 1.5}, {"name": "S", "start_m": 1.5, "end_m": 0.5004}]}
    layout = layout_from_dict(data, "wrap.yaml")
    assert layout.blocks == (Block("N", 0.5, 1.5), Block("S", 1.5, 0.5))       # 0.4 mm gap joined
    assert layout.block_at(0.1).name == "S" and layout.block_at(1.0).name == "N" and layout.block_at(1.9).name == "S"
    whole = layout_from_dict({**data, "blocks": [{"name": "all", "start_m": 0.0, "end_m": layout.length_m}]}, "w.yaml")
    assert whole.block_at(1.234).name == "all"


def write(tmp_path, data):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


GOOD = {"closed": True, "segments": [{"piece": "curve_r40", "count": 16}],      # a 2.0106 m circle
        "stations": [{"name": "S", "s_m": 0.5}], "tags": [{"uid": "04AA0001", "s_m": 0.2}], "blocks": {"count": 4}}


@pytest.mark.parametrize("change, key, words", [
    # 15 of 16 R40 curves: the gap is the chord of 22.5 degrees, 2 * 0.32 * sin(11.25 deg) = 124.9 mm
    ({"segments": [{"piece": "curve_r40", "count": 15}]}, "segments", "does not close: its end is 124.9 mm and 22.50"),
    ({"segments": [{"piece": "monorail"}]}, "segments[0].piece", "known: straight, half_straight"),
    ({"segments": [{"piece": "curve_r40", "turn": "up", "count": 16}]}, "segments[0].turn", "'left' or 'right'"),
    ({"segments": [{"piece": "straight", "count": 0}]}, "segments[0].count", "from 1 to 1000"),
    ({"segments": [{"straight": {"length_m": -1}}]}, "segments[0].straight.length_m", "must be > 0"),
    ({"segments": [{"straight": {"length_m": "long"}}]}, "segments[0].straight.length_m", "must be a number"),
    ({"segments": [{"straight": {}}]}, "segments[0].straight.length_m", "missing"),
    ({"segments": [{"piece": "straight"}, {"arc": {"radius_m": 0.0, "angle_deg": 90}}]},
     "segments[1].arc.radius_m", "must be > 0"),
    ({"segments": [{"arc": {"radius_m": 0.3, "angle_deg": 0}}]}, "segments[0].arc.angle_deg", "non-zero"),
    ({"segments": [{"arc": {"radius_m": 0.3, "angel_deg": 90}}]}, "segments[0].arc.angel_deg", "did you mean"),
    ({"segments": [{"bridge": {"length_m": 1}}]}, "segments[0]", "one of 'straight', 'arc' or 'piece'"),
    ({"segments": []}, "segments", "empty"),
    ({"segments": {"piece": "straight"}}, "segments", "must be a list"),
    ({"tags": [{"uid": "04AA0001", "s_m": 9.0}]}, "tags[0].s_m", "off the track"),
    ({"tags": [{"uid": "04AA0001", "s_m": 2.0106193}]}, "tags[0].s_m", "off the track"),       # s = length is s = 0
    ({"tags": [{"uid": "04AA0001", "s_m": 0.1}, {"uid": "04aa0001", "s_m": 0.3}]}, "tags[1].uid",
     "duplicate uid 04AA0001"),
    ({"tags": [{"uid": "04AA00", "s_m": 0.1}]}, "tags[0].uid", "8, 14 or 20 digits"),
    ({"tags": [{"uid": "XYZ10001", "s_m": 0.1}]}, "tags[0].uid", "hex"),
    ({"tags": [{"uid": 455000001, "s_m": 0.1}]}, "tags[0].uid", "quoted"),
    ({"tags": [{"s_m": 0.1}]}, "tags[0].uid", "missing"),
    ({"stations": [{"name": "S", "s_m": 5.0}]}, "stations[0].s_m", "off the track"),
    ({"stations": [{"name": "S", "s_m": 0.1}, {"name": "S", "s_m": 0.3}]}, "stations[1].name", "duplicate"),
    ({"stations": [{"name": "S"}]}, "stations[0].s_m", "missing"),
    ({"stations": [{"name": "S", "s_m": 0.1, "window_m": 0}]}, "stations[0].window_m", "must be > 0"),
    ({"stations": [{"name": "S", "s_m": 0.1, "window_m": 0.002}]}, "stations[0].window_m", "give at least 0.01"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 1.0}, {"name": "Y", "start_m": 0.8, "end_m": 0.0}]},
     "blocks[0]", "overlaps block Y"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 1.0}, {"name": "Y", "start_m": 1.2, "end_m": 0.0}]},
     "blocks[0]", "uncovered"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 1.0}]}, "blocks[0]", "uncovered"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 1.0}, {"name": "Y", "start_m": 0.0, "end_m": 1.5}]},
     "blocks[0]", "overlaps block Y"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 3.0}]}, "blocks[0].end_m", "off the track"),
    ({"blocks": {"count": 0}}, "blocks.count", "from 1 to 1000"),
    ({"blocks": {"count": 10 ** 9}}, "blocks.count", "from 1 to 1000"),       # no billion-block tuple
    ({"segments": [{"piece": "straight", "count": 10 ** 9}]}, "segments[0].count", "from 1 to 1000"),
    ({"closed": "yes"}, "closed", "true"),
    ({"closed": None}, "closed", "true"),
    ({"ips": {"beacons": [[0, 0]]}}, "ips.beacons[0]", "[x, y, z]"),
    ({"start": {"heading": 90}}, "start.heading", "did you mean 'heading_deg'"),
    ({"tagz": []}, "tagz", "did you mean 'tags'"),
])
def test_invalid_layouts_name_file_key_and_fix(tmp_path, change, key, words):
    data = dict(GOOD)
    data.update(change)
    path = write(tmp_path, data)
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    message = str(err.value)
    assert message.startswith(f"{path}: {key}: ") and words in message


def test_missing_keys_and_open_line_checks(tmp_path):
    for data, key in (({"segments": [{"piece": "straight"}]}, "closed"), ({"closed": False}, "segments")):
        with pytest.raises(LayoutError, match=f"x.yaml: {key}: missing"):
            layout_from_dict(data, "x.yaml")
    line = {"closed": False, "segments": [{"straight": {"length_m": 3.0}}]}
    far_end = {**line, "tags": [{"uid": "04000001", "s_m": 3.0}]}
    assert layout_from_dict(far_end, "x.yaml").tags[0].s_m == 3.0
    with pytest.raises(LayoutError, match=r"blocks\[1\]\.end_m: must be beyond start_m"):
        layout_from_dict({**line, "blocks": [{"start_m": 0.0, "end_m": 1.0}, {"start_m": 2.0, "end_m": 1.5}]}, "x.yaml")
    gappy = layout_from_dict({**line, "blocks": [{"start_m": 0.0, "end_m": 1.0}, {"start_m": 2.0, "end_m": 3.0}]}, "x")
    assert gappy.block_at(1.5) is None and gappy.block_at(2.5).name == "B2"     # a line may leave gaps


def test_missing_file_bad_yaml_and_empty_file(tmp_path):
    with pytest.raises(LayoutError, match=r"not found.*'itb_square'"):
        load_layout("no_such_layout")
    with pytest.raises(LayoutError, match="not found"):
        load_layout(str(tmp_path / "itb_square"))          # a path is not a packaged name
    bad = tmp_path / "broken.yaml"
    bad.write_text("closed: [true\n")
    with pytest.raises(LayoutError, match=f"{bad}: not valid YAML"):
        load_layout(str(bad))
    empty = tmp_path / "empty.yaml"
    empty.write_text("# nothing yet\n")
    with pytest.raises(LayoutError, match="the file is empty"):
        load_layout(str(empty))


def test_layout_show_prints_and_draws(tmp_path, capsys):
    png = tmp_path / "square.png"
    assert cbtc_main(["layout", "show", "itb_square", "--plot", str(png)]) == 0
    out = capsys.readouterr().out
    assert "closed loop, 6.8106 m, 8 segments" in out
    assert "04A100A1    0.15  0.47   0.0" in out            # uid, s, x = 0.32 + 0.15, y
    assert "main" in out and "5.108  6.8106    1.7027" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    older = tmp_path / "older.png"   # --png, the older name of --plot, still draws
    assert cbtc_main(["layout", "show", "itb_square", "--png", str(older)]) == 0 and older.stat().st_size > 20_000


def test_layout_list_and_errors_without_traceback(tmp_path, capsys):
    assert cbtc_main(["layout", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in SHIPPED) and "6.811" in out
    bad = write(tmp_path, {**GOOD, "segments": [{"piece": "monorail"}]})
    assert cbtc_main(["layout", "show", bad]) == 2
    err = capsys.readouterr().err
    assert "segments[0].piece: unknown piece 'monorail'" in err and "Traceback" not in err
    assert cbtc_main(["layout", "show", str(tmp_path / "nope.yaml")]) == 2


def test_the_path_layouts_load_as_they_did_before_networks():
    # the digests of the single-path layouts as they were before track networks came: the same railway, to the mm
    digests = {"itb_square": "809624ee47f76163", "lego_chicane": "fb46077d923f4f0f",
               "lego_long_oval": "c54b258cf27738f9", "lego_oval": "7b43949a1b974845",
               "straight_test": "c3c0aa846c06d5e9", "sumo_square": "1d53fde4ae5e09bd"}
    assert {name: load_layout(name).digest() for name in digests} == digests
