"""Layouts: geometry against hand-computed poses, projection, wrap-around, validation errors that name the key."""

import math

import numpy as np
import pytest
import yaml

from cbtc.cli import main as cbtc_main
from cbtc.errors import LayoutError
from cbtc.layout import layout_from_dict, layout_names, load_layout


def test_every_shipped_layout_loads():
    names = layout_names()
    assert {"itb_square", "lego_oval", "lego_chicane", "straight_test"} <= set(names)
    for name in names:
        layout = load_layout(name)
        assert layout.length_m > 0


def test_square_length_and_poses_by_hand():
    sq = load_layout("itb_square")
    arc = math.pi / 2 * 0.32
    assert sq.length_m == pytest.approx(4 * 1.2 + 4 * arc)
    assert sq.pose(0.0) == pytest.approx((0.32, 0.0, 0.0))
    assert sq.pose(0.6) == pytest.approx((0.92, 0.0, 0.0))
    # middle of the first arc: centre (1.52, 0.32), 45 degrees round
    x, y, h = sq.pose(1.2 + arc / 2)
    assert (x, y, h) == pytest.approx((1.52 + 0.32 * math.sin(math.pi / 4), 0.32 - 0.32 * math.cos(math.pi / 4), math.pi / 4))
    # start of the right side, heading north
    assert sq.pose(1.2 + arc) == pytest.approx((1.84, 0.32, math.pi / 2))
    # a loop: s and s + length are the same place
    assert sq.pose(sq.length_m + 0.6) == pytest.approx(sq.pose(0.6))


def test_sixteen_r40_pieces_make_a_circle():
    circle = layout_from_dict({"closed": True, "segments": [{"piece": "curve_r40", "count": 16}]}, "circle.yaml")
    assert circle.length_m == pytest.approx(2 * math.pi * 0.32)
    assert circle.pose(circle.length_m / 2)[:2] == pytest.approx((0.0, 0.64))


def test_projection_inverts_pose_everywhere_vectorised():
    for name in ("itb_square", "lego_chicane"):
        layout = load_layout(name)
        s = np.linspace(0.0, layout.length_m, 700, endpoint=False)
        xy = layout.xy(s)
        assert xy.shape == (700, 2)
        back = np.array([layout.project(x, y, s_hint_m=h) for (x, y), h in zip(xy, s)])
        err = np.abs((back - s + layout.length_m / 2) % layout.length_m - layout.length_m / 2)
        assert err.max() < 1e-6


def test_projection_of_a_noisy_point_lands_nearby():
    sq = load_layout("itb_square")
    x, y = sq.xy(2.0)
    assert sq.project(x + 0.02, y, s_hint_m=2.0) == pytest.approx(2.0, abs=1e-6)  # right side: x offset is lateral


def test_wrap_and_ahead_across_the_seam():
    sq = load_layout("itb_square")
    assert sq.wrap(-0.1) == pytest.approx(sq.length_m - 0.1)
    assert sq.ahead_m(sq.length_m - 0.1, 0.2) == pytest.approx(0.3)
    line = load_layout("straight_test")
    assert line.wrap(5.0) == 3.0 and line.ahead_m(2.0, 1.0) == -1.0


def write(tmp_path, data):
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


GOOD = {"closed": True, "segments": [{"piece": "curve_r40", "count": 16}],
        "stations": [{"name": "S", "s_m": 0.5}], "tags": [{"uid": "04AA", "s_m": 0.2}], "blocks": {"count": 4}}


@pytest.mark.parametrize("change, key, words", [
    ({"segments": [{"piece": "curve_r40", "count": 15}]}, "segments", "does not close"),
    ({"segments": [{"piece": "monorail"}]}, "segments[0].piece", "unknown piece"),
    ({"segments": [{"straight": {"length_m": -1}}]}, "segments[0].straight.length_m", "must be > 0"),
    ({"segments": [{"arc": {"radius_m": 0.3, "angle_deg": 0}}]}, "segments[0].arc.angle_deg", "non-zero"),
    ({"tags": [{"uid": "04AA", "s_m": 9.0}]}, "tags[0].s_m", "off the track"),
    ({"tags": [{"uid": "04AA", "s_m": 0.1}, {"uid": "04aa", "s_m": 0.3}]}, "tags[1].uid", "duplicate uid"),
    ({"tags": [{"uid": "XYZ", "s_m": 0.1}]}, "tags[0].uid", "hex"),
    ({"stations": [{"name": "S", "s_m": 5.0}]}, "stations[0].s_m", "off the track"),
    ({"stations": [{"name": "S", "s_m": 0.1}, {"name": "S", "s_m": 0.3}]}, "stations[1].name", "duplicate"),
    ({"blocks": [{"name": "X", "start_m": 0.0, "end_m": 1.0}, {"name": "Y", "start_m": 0.8, "end_m": 2.0106}]},
     "blocks (X)", "overlaps"),
    ({"closed": "yes"}, "closed", "true"),
])
def test_invalid_layouts_name_file_key_and_fix(tmp_path, change, key, words):
    data = dict(GOOD)
    data.update(change)
    path = write(tmp_path, data)
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    message = str(err.value)
    assert path in message and key in message and words in message


def test_missing_file_and_bad_yaml(tmp_path):
    with pytest.raises(LayoutError, match="itb_square"):
        load_layout("no_such_layout")
    bad = tmp_path / "broken.yaml"
    bad.write_text("closed: [true\n")
    with pytest.raises(LayoutError, match="not valid YAML"):
        load_layout(str(bad))


def test_layout_show_prints_and_draws(tmp_path, capsys):
    png = tmp_path / "square.png"
    assert cbtc_main(["layout", "show", "itb_square", "--png", str(png)]) == 0
    out = capsys.readouterr().out
    assert "6.8106 m" in out and "04A10000A1" in out and "main" in out
    assert png.stat().st_size > 10_000
    assert cbtc_main(["layout", "show", str(tmp_path / "nope.yaml")]) == 2
