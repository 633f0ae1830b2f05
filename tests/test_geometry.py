"""Path maths: poses against hand-computed coordinates, exact projection, wrap-around, vectorised shapes."""

import math

import numpy as np
import pytest

from cbtc.layout_files import load_layout
from cbtc.railway.geometry import Path

R40_M = 0.32
QUARTER_M = math.pi / 2 * R40_M          # a 90-degree R40 corner
SQUARE_M = 4 * 1.2 + 4 * QUARTER_M


def circle(pieces=16):
    """`pieces` R40 curves turning left from the origin heading +x: centre (0, 0.32)."""
    return Path([("arc", R40_M, math.radians(22.5))] * pieces, closed=pieces == 16)


def along_error(layout_or_path, s_a, s_b):
    """|a - b| the short way round a loop."""
    length = layout_or_path.length_m
    return np.abs((np.asarray(s_a) - s_b + length / 2) % length - length / 2)


def test_square_length_is_analytic():
    assert load_layout("itb_square").length_m == pytest.approx(SQUARE_M, abs=1e-12)
    assert SQUARE_M == pytest.approx(6.8106, abs=1e-4)


# itb_square starts at (0.32, 0) heading +x; corners are R40 left turns; the straights are x/y = 0 or 1.84
@pytest.mark.parametrize("s_m, pose", [
    (0.0, (0.32, 0.0, 0.0)),                                       # start of the bottom straight
    (1.2 + QUARTER_M, (1.84, 0.32, math.pi / 2)),                  # start of the right side
    (2.4 + 2 * QUARTER_M, (1.52, 1.84, math.pi)),                  # start of the top side
    (3.6 + 3 * QUARTER_M, (0.0, 1.52, 3 * math.pi / 2)),           # start of the left side
    (0.6, (0.92, 0.0, 0.0)),                                       # station main, mid bottom
    # corner midpoints: centre + r * (sin, -cos) of the heading there (45, 135, 225, 315 degrees)
    (1.2 + QUARTER_M / 2, (1.52 + R40_M * math.sqrt(0.5), 0.32 - R40_M * math.sqrt(0.5), math.pi / 4)),
    (2.4 + 1.5 * QUARTER_M, (1.52 + R40_M * math.sqrt(0.5), 1.52 + R40_M * math.sqrt(0.5), 3 * math.pi / 4)),
    (3.6 + 2.5 * QUARTER_M, (0.32 - R40_M * math.sqrt(0.5), 1.52 + R40_M * math.sqrt(0.5), 5 * math.pi / 4)),
    (4.8 + 3.5 * QUARTER_M, (0.32 - R40_M * math.sqrt(0.5), 0.32 - R40_M * math.sqrt(0.5), 7 * math.pi / 4)),
])
def test_square_poses_by_hand(s_m, pose):
    sq = load_layout("itb_square")
    assert sq.pose(s_m) == pytest.approx(pose, abs=1e-12)
    x, y, h = sq.pose(np.array([s_m, s_m + sq.length_m]))          # vectorised and wrapped: the same place
    assert np.allclose(x, pose[0]) and np.allclose(y, pose[1]) and np.allclose(h, pose[2])


def test_sixteen_r40_pieces_are_a_circle_of_radius_0_32():
    path = circle()
    assert path.length_m == pytest.approx(2 * math.pi * R40_M, abs=1e-12)
    s = np.linspace(0.0, path.length_m, 96, endpoint=False)
    x, y, h = path.pose(s)
    np.testing.assert_allclose(x, R40_M * np.sin(s / R40_M), atol=1e-12)
    np.testing.assert_allclose(y, R40_M * (1 - np.cos(s / R40_M)), atol=1e-12)
    np.testing.assert_allclose(h, s / R40_M, atol=1e-12)
    assert path.end_pose[:2] == pytest.approx((0.0, 0.0), abs=1e-12)


def test_more_than_a_circle_keeps_going_round():
    path = Path([("arc", R40_M, math.radians(22.5))] * 20)         # 450 degrees, open: split into half circles inside
    assert path.run_count == 3
    s = np.linspace(0.0, path.length_m, 50)
    np.testing.assert_allclose(path.xy(s)[:, 1], R40_M * (1 - np.cos(s / R40_M)), atol=1e-12)


def test_right_turn_bends_towards_minus_y():
    path = Path([("straight", 1.0), ("arc", 0.5, -math.pi / 2)])
    assert path.pose(1.0 + 0.25 * math.pi) == pytest.approx((1.5, -0.5, -math.pi / 2), abs=1e-12)


def test_xy_shapes_and_scalar_path_agree_with_the_array_path():
    chicane = load_layout("lego_chicane")
    s = np.linspace(-1.0, 2 * chicane.length_m, 60).reshape(3, 4, 5)
    xy = chicane.xy(s)
    assert xy.shape == (3, 4, 5, 2)
    assert chicane.xy(1.3).shape == (2,)
    scalar = np.array([chicane.xy(float(v)) for v in s.ravel()])
    np.testing.assert_allclose(scalar, xy.reshape(-1, 2), atol=1e-12)
    x, y, h = chicane.pose(s)
    assert x.shape == y.shape == h.shape == (3, 4, 5)


@pytest.mark.parametrize("name", ["itb_square", "lego_oval", "lego_chicane", "straight_test"])
def test_project_inverts_pose_everywhere(name):
    layout = load_layout(name)
    s = np.linspace(0.0, layout.length_m, 1001, endpoint=not layout.closed)
    xy = layout.xy(s)
    back = layout.project(xy[:, 0], xy[:, 1])
    assert back.shape == s.shape
    assert along_error(layout, back, s).max() < 1e-9 if layout.closed else np.abs(back - s).max() < 1e-9
    hinted = layout.project(xy[:, 0], xy[:, 1], s_hint_m=layout.wrap(s + 0.2))
    assert np.abs(hinted - back).max() < 1e-9 or along_error(layout, hinted, s).max() < 1e-9
    assert isinstance(layout.project(*xy[17]), float)


def test_project_of_points_off_the_track():
    sq = load_layout("itb_square")
    # on a straight the perpendicular foot: 3 cm right of the bottom straight at x = 1.0 -> s = 1.0 - 0.32
    assert sq.project(1.0, -0.03) == pytest.approx(0.68, abs=1e-12)
    # on a corner the radial foot: any point on the ray from the corner centre (1.52, 0.32) at -45 degrees
    mid_s = 1.2 + QUARTER_M / 2
    for r_m in (0.25, 0.30, 0.35, 0.40):
        x, y = 1.52 + r_m * math.sqrt(0.5), 0.32 - r_m * math.sqrt(0.5)
        assert sq.project(x, y) == pytest.approx(mid_s, abs=1e-12)
        assert sq.project(x, y, s_hint_m=mid_s + 0.3) == pytest.approx(mid_s, abs=1e-12)
    # beyond the end of an open line: its end
    line = load_layout("straight_test")
    assert line.project(3.4, 0.1) == 3.0 and line.project(-1.0, 0.0) == 0.0


def test_hint_keeps_the_local_solution_where_two_stretches_pass_close():
    chicane = load_layout("lego_chicane")
    s_bottom, s_top = 1.0146, 4.0492                     # the two chicane apexes, 0.265 m apart (y 0.187 and 0.452)
    (xb, yb), (xt, yt) = chicane.xy(s_bottom), chicane.xy(s_top)
    assert yt - yb == pytest.approx(0.265, abs=1e-3)
    x, y = (xb + xt) / 2, yb + 0.6 * (yt - yb)          # a bad fix, nearer the top stretch
    assert along_error(chicane, chicane.project(x, y), s_top) < 0.05
    local = chicane.project(x, y, s_hint_m=s_bottom)
    assert along_error(chicane, local, s_bottom) < 0.05
    # vectorised with one hint per point
    both = chicane.project(np.array([x, x]), np.array([y, y]), s_hint_m=np.array([s_bottom, s_top]))
    assert along_error(chicane, both, np.array([s_bottom, s_top])).max() < 0.05


def test_hint_window_reaches_round_the_seam():
    sq = load_layout("itb_square")
    x, y = sq.xy(sq.length_m - 0.05)
    assert sq.project(x, y, s_hint_m=0.1) == pytest.approx(sq.length_m - 0.05, abs=1e-12)
    assert sq.project(x, y, s_hint_m=0.1, window_m=0.1) == pytest.approx(0.0, abs=1e-12)   # clamped to the window


def test_wrap_and_ahead_across_the_seam():
    sq = load_layout("itb_square")
    length = sq.length_m
    assert sq.wrap(-0.1) == pytest.approx(length - 0.1)
    assert sq.wrap(length + 0.25) == pytest.approx(0.25)
    np.testing.assert_allclose(sq.wrap(np.array([-0.1, 0.3, length + 0.25])), [length - 0.1, 0.3, 0.25])
    assert sq.ahead_m(length - 0.1, 0.2) == pytest.approx(0.3)
    assert sq.ahead_m(0.2, length - 0.1) == pytest.approx(length - 0.3)
    np.testing.assert_allclose(sq.ahead_m(np.array([length - 0.1, 1.0]), 0.2), [0.3, length - 0.8])
    line = load_layout("straight_test")
    assert line.wrap(5.0) == 3.0 and line.wrap(-2.0) == 0.0
    assert line.ahead_m(2.0, 1.0) == -1.0
    assert line.pose(5.0) == pytest.approx((3.0, 0.0, 0.0))


@pytest.mark.parametrize("name", ["itb_square", "lego_chicane", "straight_test", "lego_long_oval"])
def test_projecting_one_point_on_floats_agrees_with_the_array_version(name):
    """A float point takes the scalar projection (the filter's IPS fixes, one at a time): it finds what the array
    version finds, junctions and points off either end of a line included."""
    layout = load_layout(name)
    rng = np.random.default_rng(3)
    points = [layout.xy_m(s) for s in layout.path._starts]
    for s in rng.uniform(-0.3, layout.length_m + 0.3, 500):
        x, y = layout.xy_m(float(s))
        points.append((x + rng.normal(0, 0.3), y + rng.normal(0, 0.3)))
    arr = np.array(points, dtype=float)
    ours = [layout.project(float(x), float(y)) for x, y in points]
    assert all(isinstance(s, float) for s in ours)
    assert np.max(np.abs(np.array(ours) - layout.project(arr[:, 0], arr[:, 1]))) < 1e-12
