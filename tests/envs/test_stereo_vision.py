"""The stereo paper's vision (envs.stereo.vision): edge types, the tall filter on synthetic
stripes, sub-pixel edges, trinocular matching, the paper's eqs. (2)-(5), the range noise,
drawing and bad input."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.schema import ConfigError
from envs.stereo.vision import (
    EDGE_TYPES,
    EdgeDetector,
    EdgeList,
    Matches,
    TrinocularRig,
    check_edge_types,
    concat_edges,
    detect_edges,
    disparity_window,
    draw_detections,
    edge_type,
    edge_type_parts,
    edge_types,
    edge_types_parts,
    empty_edges,
    filter_size,
    inverse_range_std,
    match_trinocular,
    paper_range_bearing,
    range_std_m,
    rig_range_bearing,
    triangulate,
    vertical_edge_response,
)

F = 500.0  # focal length (px)
CX = 320.0  # principal point: the middle of a 640-px-wide image
B = 0.19  # the paper's neighbour baseline (m)
ROWS_480 = (50, 100, 150, 200, 250)  # five detection rows for the 101-row filter at 480 rows


def project(forward: float, left: float, camera_left: float, rig_forward: float = 0.0) -> float:
    """Column of a robot-frame point in a forward camera at lateral offset ``camera_left`` (left positive).

    The camera's image x axis points right, i.e. to the robot's -left; the point lies
    ``camera_left - left`` to the camera's right at depth ``forward - rig_forward``, so
    ``u = cx + f (camera_left - left) / depth`` (the module's convention ``u = cx + f X / Z``).
    """
    return CX + F * (camera_left - left) / (forward - rig_forward)


def rig_columns(forward: float, left: float, rig_forward: float = 0.0, rig_left: float = 0.0) -> tuple[float, float, float]:
    """``(uL, uM, uR)`` of a robot-frame point in the rig (middle camera at ``rig_forward``, ``rig_left``)."""
    return tuple(project(forward, left, rig_left + c, rig_forward) for c in (B, 0.0, -B))  # type: ignore[return-value]


def stripes(width: int, height: int, boundaries: Sequence[int], colours: Sequence[tuple[int, int, int]]) -> np.ndarray:
    """Vertical stripes: ``colours[i]`` between boundaries ``i - 1`` and ``i`` (columns ``[b_{i-1}, b_i)``)."""
    img = np.empty((height, width, 3), np.uint8)
    cuts = [0, *boundaries, width]
    for a, b, colour in zip(cuts[:-1], cuts[1:], colours):
        img[:, a:b] = colour
    return img


def edges_of(u: Sequence[float], types: Sequence[int], strength: float = 100.0) -> EdgeList:
    return EdgeList(np.asarray(u, np.float64), np.asarray(types, np.int64), np.full(len(u), strength, np.float32))


# ---------------------------------------------------------------------------- edge types
@pytest.mark.parametrize(
    ("channel", "level", "falling", "t"),
    [(0, 0, False, 0), (0, 0, True, 1), (1, 0, False, 2), (2, 0, True, 5), (0, 1, False, 6), (1, 2, True, 15), (2, 4, True, 29)],
)
def test_edge_type_values_and_inverse(channel: int, level: int, falling: bool, t: int) -> None:
    assert edge_type(channel, level, falling) == t
    assert edge_type_parts(t) == (channel, level, falling)


def test_edge_types_cover_0_to_29_once_and_vectorize() -> None:
    c, lv, f = np.meshgrid(np.arange(3), np.arange(5), np.array([False, True]), indexing="ij")
    t = edge_types(c, lv, f)
    assert sorted(t.ravel().tolist()) == list(range(EDGE_TYPES))
    assert all(t[i, j, k] == edge_type(i, j, bool(k)) for i in range(3) for j in range(5) for k in range(2))
    back = edge_types_parts(t)
    for got, want in zip(back, (c, lv, f)):
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("bad", [30, -1, 31, 2.5, True])
def test_unknown_edge_type_is_refused_naming_it(bad: object) -> None:
    with pytest.raises(ValueError, match=re.escape(repr(bad))):
        check_edge_types(np.array([0, 3, bad] if not isinstance(bad, bool) else [bad]), "test")
    with pytest.raises(ValueError, match=re.escape(repr(bad))):
        edge_type_parts(bad)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("channel", "level", "falling", "named"),
    [
        (3, 0, False, "channel must be an integer in 0..2, got 3"),
        (-1, 0, False, "channel must be an integer in 0..2, got -1"),
        (0.0, 0, False, "channel must be an integer in 0..2, got 0.0"),
        (0, 5, False, "level must be an integer in 0..4, got 5"),
        (0, 0, 2, "falling must be a bool, got 2"),
    ],
)
def test_bad_edge_type_parts_are_refused_naming_them(channel: object, level: object, falling: object, named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        edge_type(channel, level, falling)  # type: ignore[arg-type]


def test_edge_type_arrays_refuse_floats_and_out_of_range() -> None:
    with pytest.raises(ValueError, match=r"channel 3 is outside 0\.\.2"):
        edge_types([0, 3], [0, 0], [False, False])
    with pytest.raises(ValueError, match=r"level.*1\.5"):
        edge_types([0], [1.5], [False])
    assert check_edge_types([], "empty").dtype == np.int64


# ---------------------------------------------------------------------------- filter size
@pytest.mark.parametrize(
    ("width", "height", "size"),
    [
        (640, 480, (101, 7)),
        (320, 240, (51, 3)),  # 50.5 -> 51, 3.5 -> 3
        (1280, 960, (203, 15)),  # 202 -> 203 (a tie goes up), 14 -> 15
        (800, 600, (127, 9)),  # 126.25 -> 127, 8.75 -> 9
        (160, 120, (25, 3)),  # 25.25 -> 25, 1.75 -> at least 3
        (40, 10, (3, 3)),
    ],
)
def test_filter_size_scales_the_papers_filter_to_odd_sizes(width: int, height: int, size: tuple[int, int]) -> None:
    got = filter_size(width, height)
    assert got == size
    assert all(s % 2 == 1 and s >= 3 for s in got)


@pytest.mark.parametrize(("width", "height", "bad"), [(0, 480, "0"), (640, -1, "-1"), (640.0, 480, "640.0")])
def test_filter_size_refuses_bad_sizes(width: object, height: object, bad: str) -> None:
    with pytest.raises(ValueError, match=re.escape(bad)):
        filter_size(width, height)  # type: ignore[arg-type]


# ---------------------------------------------------------------------------- the filter and edges
def expected_stripe_edges(
    boundaries: Sequence[int], colours: Sequence[tuple[int, int, int]], levels: int, threshold: float
) -> list[tuple[int, float, float]]:
    """``(type, u, strength)`` of every channel step of the stripes at every level, sorted by (type, u)."""
    out = []
    for lv in range(levels):
        for b, c0, c1 in zip(boundaries, colours[:-1], colours[1:]):
            for ch in range(3):
                delta = int(c1[ch]) - int(c0[ch])
                if abs(delta) >= threshold:
                    out.append((edge_type(ch, lv, delta < 0), float(b), float(abs(delta))))
    return sorted(out)


COLOURS = [(0, 0, 0), (255, 0, 0), (255, 255, 0), (0, 0, 255), (255, 255, 255), (128, 140, 120)]


@pytest.mark.parametrize(
    ("width", "height", "rows", "boundaries"),
    [
        (640, 480, ROWS_480, (100, 181, 263, 400, 517)),
        (320, 240, (25, 50, 75, 100, 125), (50, 91, 132, 200, 259)),
        (640, 480, (60, 300), (10, 181, 263, 400, 629)),  # boundaries near the borders, two levels
    ],
)
def test_stripe_boundaries_are_found_at_their_columns_channels_polarities_and_levels(
    width: int, height: int, rows: tuple[int, ...], boundaries: tuple[int, ...]
) -> None:
    img = stripes(width, height, boundaries, COLOURS)
    detector = EdgeDetector.for_image(width, height, rows, threshold=20.0)
    edges = detector.detect(img)
    want = expected_stripe_edges(boundaries, COLOURS, len(rows), 20.0)
    assert edges.type.tolist() == [t for t, _, _ in want]
    np.testing.assert_allclose(edges.u, [u for _, u, _ in want], atol=0.05)
    np.testing.assert_allclose(edges.u, [u for _, u, _ in want], atol=1e-6)  # sharp steps: exactly
    np.testing.assert_allclose(edges.strength, [s for _, _, s in want], rtol=1e-6)
    assert edges.u.dtype == np.float64 and edges.type.dtype == np.int64 and edges.strength.dtype == np.float32


def test_red_to_yellow_changes_only_green_rising() -> None:
    img = stripes(640, 480, [300], [(255, 0, 0), (255, 255, 0)])
    edges = EdgeDetector((100,), 101, 7, 10.0).detect(img)
    assert edges.type.tolist() == [edge_type(1, 0, False)]
    assert edges.u.tolist() == [300.0]


@pytest.mark.parametrize("filter_cols", [3, 7, 15])
def test_an_ideal_step_plateaus_at_both_sides_and_is_found_at_the_boundary(filter_cols: int) -> None:
    k = 299  # the step is between columns 299 and 300: at u = 300
    img = stripes(640, 480, [k + 1], [(10, 10, 10), (210, 10, 10)])
    resp = vertical_edge_response(img, [240], 101, filter_cols)
    assert resp.shape == (1, 640, 3) and resp.dtype == np.float32
    assert resp[0, k, 0] == resp[0, k + 1, 0] == 200.0
    h = filter_cols // 2
    assert resp[0, k - 1, 0] == resp[0, k + 2, 0] == pytest.approx(200.0 * (h - 1) / h)
    assert not resp[0, :, 1:].any()  # G and B do not change
    edges = detect_edges(resp, 5.0, border_px=h)
    assert edges.u.tolist() == pytest.approx([300.0], abs=1e-6)


@pytest.mark.parametrize("filter_cols", [3, 7, 15])
@pytest.mark.parametrize(("alpha", "falling"), [(0.1, False), (0.25, False), (0.5, True), (0.75, False), (0.9, True)])
def test_an_antialiased_step_is_found_at_its_sub_pixel_boundary(filter_cols: int, alpha: float, falling: bool) -> None:
    # the new colour covers the share alpha of column 200 (its right part): the boundary is at u = 201 - alpha
    lo, hi = (200, 0) if falling else (0, 200)
    img = stripes(640, 480, [201], [(0, lo, 0), (0, hi, 0)])
    img[:, 200, 1] = round((1 - alpha) * lo + alpha * hi)
    edges = detect_edges(vertical_edge_response(img, [100], 101, filter_cols), 5.0, border_px=filter_cols // 2)
    assert edges.type.tolist() == [edge_type(1, 0, falling)]
    assert edges.u[0] == pytest.approx(201.0 - alpha, abs=1e-4)


@pytest.mark.parametrize("covered", [1, 10, 50, 77, 100, 101])
def test_a_stripe_over_part_of_the_window_gives_the_fractional_response(covered: int) -> None:
    img = np.zeros((480, 640, 3), np.uint8)
    row = 240
    img[row - 50 : row - 50 + covered, 300:, 2] = 200  # blue over `covered` of the window's 101 rows
    resp = vertical_edge_response(img, [row], 101, 7)
    q = covered / 101
    assert resp[0, 299, 2] == pytest.approx(q * 200.0, rel=1e-6)
    assert resp[0, 300, 2] == pytest.approx(q * 200.0, rel=1e-6)
    edges = detect_edges(resp, 0.5, border_px=3)
    assert edges.type.tolist() == [edge_type(2, 0, False)]
    assert edges.u[0] == pytest.approx(300.0, abs=1e-6)
    assert edges.strength[0] == pytest.approx(q * 200.0, rel=1e-6)
    # rows just outside the window change nothing
    img[: row - 50, 300:, :] = 255
    img[row + 51 :, 300:, :] = 255
    np.testing.assert_array_equal(vertical_edge_response(img, [row], 101, 7), resp)


@pytest.mark.parametrize("level", range(5))
def test_an_edge_in_one_levels_window_has_that_level(level: int) -> None:
    rows = (50, 152, 254, 356, 458)  # windows of 101 rows that do not overlap
    img = np.zeros((560, 640, 3), np.uint8)
    img[rows[level] - 50 : rows[level] + 51, 300:340] = (0, 255, 0)
    edges = EdgeDetector(rows, 101, 7, 1.0).detect(img)
    assert edges.type.tolist() == [edge_type(1, level, False), edge_type(1, level, True)]
    assert edges.u.tolist() == pytest.approx([300.0, 340.0], abs=1e-6)


@pytest.mark.parametrize(
    ("delta", "threshold", "found"), [(15, 20.0, False), (15, 15.0, True), (25, 20.0, True), (19, 19.5, False)]
)
def test_no_edge_below_the_threshold(delta: int, threshold: float, found: bool) -> None:
    img = stripes(640, 480, [320], [(100, 100, 100), (100 + delta, 100, 100)])
    edges = EdgeDetector(ROWS_480, 101, 7, threshold).detect(img)
    assert edges.u.size == (5 if found else 0)


def test_a_texture_free_image_has_no_edges() -> None:
    img = np.full((480, 640, 3), (90, 160, 30), np.uint8)
    resp = vertical_edge_response(img, ROWS_480, 101, 7)
    assert not resp.any()
    assert detect_edges(resp, 1e-3).u.size == 0
    # mild noise averaged over the tall window stays below a sensible threshold
    rng = np.random.default_rng(3)
    noisy = np.clip(img + rng.normal(0.0, 8.0, img.shape), 0, 255).astype(np.uint8)
    assert EdgeDetector(ROWS_480, 101, 7, 10.0).detect(noisy).u.size == 0


def test_a_step_inside_the_filters_border_is_not_reported() -> None:
    # at u = 2 the 7-column filter's true peak lies in its zero border (columns 0..2)
    img = stripes(640, 480, [2, 638], [(0, 0, 0), (200, 200, 200), (0, 0, 0)])
    assert EdgeDetector((100,), 101, 7, 10.0).detect(img).u.size == 0
    # without the border the first known column would look like a peak
    assert detect_edges(vertical_edge_response(img, [100], 101, 7), 10.0).u.size > 0


def test_edges_are_sorted_by_type_then_u_and_concat_keeps_the_order() -> None:
    img = stripes(640, 480, (100, 181, 263, 400, 517), COLOURS)
    edges = EdgeDetector(ROWS_480, 101, 7, 20.0).detect(img)
    assert np.all(np.diff(edges.type) >= 0)
    same = np.diff(edges.type) == 0
    assert np.all(np.diff(edges.u)[same] > 0)
    half = edges.u.size // 2
    parts = [
        EdgeList(edges.u[half:], edges.type[half:], edges.strength[half:]),
        EdgeList(edges.u[:half], edges.type[:half], edges.strength[:half]),
    ]
    parts.append(empty_edges())
    joined = concat_edges(*parts)
    for got, want in zip(joined, edges):
        np.testing.assert_array_equal(got, want)


def test_response_is_the_same_on_a_non_contiguous_image() -> None:
    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    view = np.asarray(np.ascontiguousarray(img[:, ::-1])[:, ::-1])  # a negative-stride view of the same pixels
    assert not view.flags.c_contiguous
    np.testing.assert_array_equal(vertical_edge_response(view, ROWS_480, 101, 7), vertical_edge_response(img, ROWS_480, 101, 7))


def test_response_matches_a_direct_evaluation_of_the_filter() -> None:
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (120, 90, 3), dtype=np.uint8)
    rows, fr, fc = [11, 40, 108], 21, 9
    got = vertical_edge_response(img, rows, fr, fc)
    h = fc // 2
    want = np.zeros_like(got)
    for lv, r in enumerate(rows):
        window = img[r - fr // 2 : r + fr // 2 + 1].astype(np.float64)
        for u in range(h, 90 - h):
            want[lv, u] = window[:, u + 1 : u + h + 1].mean(axis=(0, 1)) - window[:, u - h : u].mean(axis=(0, 1))
    np.testing.assert_allclose(got, want, atol=1e-4)


# ---------------------------------------------------------------------------- eqs. (2)-(5)
def test_triangulation_against_hand_computed_values() -> None:
    # d = 345 - 326 = 19 px; outer baseline 0.38 m: x = 0.38 * 25 / 19 = 0.5, y = 500 * 0.38 / 19 = 10
    x, y = triangulate(345.0, 326.0, 500.0, 0.38, 320.0)
    assert float(x) == pytest.approx(0.5, abs=1e-12)
    assert float(y) == pytest.approx(10.0, abs=1e-12)
    r, theta = paper_range_bearing(x, y)
    assert float(r) == pytest.approx(math.sqrt(100.25), abs=1e-12)
    assert float(theta) == pytest.approx(math.atan(0.05), abs=1e-12)  # right of forward: positive in the paper
    x, y = triangulate(np.array([301.0, 320.0]), np.array([282.0, 300.0]), 500.0, 0.38, 320.0)
    np.testing.assert_allclose(x, [0.38 * -19 / 19, 0.0])
    np.testing.assert_allclose(y, [10.0, 9.5])
    r, theta = paper_range_bearing(x, y)
    np.testing.assert_allclose(theta, [math.atan(-0.38 / 10.0), 0.0])


@pytest.mark.parametrize(
    ("forward", "left", "rig_forward", "rig_left", "bearing_sign"),
    [
        (10.0, 0.0, 0.0, 0.0, 0),  # straight ahead
        (6.0, 2.0, 0.0, 0.0, 1),  # to the left: positive bearing
        (6.0, -2.0, 0.0, 0.0, -1),  # to the right: negative bearing
        (8.0, 0.0, 0.3, -0.1, 0),  # straight ahead of the robot centre, rig offset to the right
        (4.0, 1.5, 0.3, 0.2, 1),
        (3.0, -3.0, -0.2, 0.1, -1),
    ],
)
def test_rig_range_bearing_gives_the_robot_frame_point(
    forward: float, left: float, rig_forward: float, rig_left: float, bearing_sign: int
) -> None:
    ul, um, ur = rig_columns(forward, left, rig_forward, rig_left)
    assert um == pytest.approx((ul + ur) / 2, abs=1e-9)  # the middle camera sees the point half-way
    rng, bearing = rig_range_bearing(ul, ur, F, B, CX, rig_forward, rig_left)
    assert float(rng) == pytest.approx(math.hypot(forward, left), abs=1e-9)
    assert float(bearing) == pytest.approx(math.atan2(left, forward), abs=1e-12)
    assert np.sign(round(float(bearing), 9)) == bearing_sign


@settings(max_examples=200, deadline=None)
@given(
    forward=st.floats(1.0, 60.0),
    left=st.floats(-15.0, 15.0),
    rig_forward=st.floats(-0.5, 0.5),
    rig_left=st.floats(-0.3, 0.3),
)
def test_projecting_into_the_rig_and_back_recovers_the_point(
    forward: float, left: float, rig_forward: float, rig_left: float
) -> None:
    ul, _, ur = rig_columns(forward, left, rig_forward, rig_left)
    rng, bearing = rig_range_bearing(np.array([ul]), np.array([ur]), F, B, CX, rig_forward, rig_left)
    assert rng[0] == pytest.approx(math.hypot(forward, left), rel=1e-9)
    assert bearing[0] == pytest.approx(math.atan2(left, forward), abs=1e-9)


def test_the_rig_dataclass_recovers_matched_points() -> None:
    rig = TrinocularRig(F, CX, B, 2.0, 30.0, 0.5, rig_forward_m=0.25, rig_left_m=0.05)
    points = [(5.0, 1.0), (12.0, -2.0), (20.0, 0.0)]
    cols = [rig_columns(f, lft, 0.25, 0.05) for f, lft in points]
    t = [3, 8, 21]
    cams = [edges_of([c[i] for c in cols], t) for i in range(3)]
    m = rig.match(*cams)
    rng, bearing = rig.range_bearing(m)
    order = np.argsort(t)
    np.testing.assert_allclose(rng, [math.hypot(*points[i]) for i in order], rtol=1e-9)
    np.testing.assert_allclose(bearing, [math.atan2(points[i][1], points[i][0]) for i in order], atol=1e-9)


# ---------------------------------------------------------------------------- range noise
@pytest.mark.parametrize("sigma_px", [0.1, 0.25])
def test_triangulated_range_noise_grows_as_r_squared_and_inverse_range_noise_is_constant(sigma_px: float) -> None:
    n = 20_000
    rng = np.random.default_rng(42)
    outer = 2 * B
    sigma_d = math.sqrt(2.0) * sigma_px
    ranges = np.array([2.0, 5.0, 10.0, 20.0, 40.0])
    sds, inv_sds = [], []
    for r in ranges:
        # a point on the left camera's axis (x = 0): r = y, the paper's case
        ul = CX + rng.normal(0.0, sigma_px, n)
        ur = CX - F * outer / r + rng.normal(0.0, sigma_px, n)
        x, y = triangulate(ul, ur, F, outer, CX)
        est, _ = paper_range_bearing(x, y)
        sds.append(np.std(est, ddof=1))
        inv_sds.append(np.std(1.0 / est, ddof=1))
        # the tolerance: 5 standard errors of a sample sd, plus the second-order bias of 1/d (sd(1/(d + e)) ~ s (1 + 4 s^2), s = sigma_d / d)
        s = sigma_d / (F * outer / r)
        tol = 5.0 / math.sqrt(2.0 * (n - 1)) + 4.0 * s * s
        assert sds[-1] == pytest.approx(float(range_std_m(r, F, outer, sigma_d)), rel=tol)
        assert inv_sds[-1] == pytest.approx(inverse_range_std(F, outer, sigma_d), rel=5.0 / math.sqrt(2.0 * (n - 1)))
    # grows as r^2: the log-log slope is 2
    slope = np.polyfit(np.log(ranges), np.log(sds), 1)[0]
    assert slope == pytest.approx(2.0, abs=0.02)
    # and the sd of 1/r does not depend on r
    assert max(inv_sds) / min(inv_sds) < 1.0 + 10.0 / math.sqrt(2.0 * (n - 1))


def test_range_std_values() -> None:
    np.testing.assert_allclose(range_std_m(np.array([1.0, 10.0]), 500.0, 0.38, 0.2), [0.2 / 190.0, 100 * 0.2 / 190.0])
    assert inverse_range_std(500.0, 0.38, 0.2) == pytest.approx(0.2 / 190.0)


# ---------------------------------------------------------------------------- matching
SCENE = [  # (forward, left, type)
    (4.0, 0.5, 3),
    (8.0, -1.0, 3),
    (12.0, 0.2, 7),
    (6.0, 0.0, 12),
    (20.0, 2.0, 29),
    (3.0, -0.4, 0),
    (2.5, 0.6, 3),
]


def scene_edges(scene: Sequence[tuple[float, float, int]]) -> tuple[EdgeList, EdgeList, EdgeList]:
    """The left, middle and right cameras' edges of robot-frame points ``(forward, left, type)``."""
    cols = [rig_columns(f, lft) for f, lft, _ in scene]
    types = [t for _, _, t in scene]
    return edges_of([c[0] for c in cols], types), edges_of([c[1] for c in cols], types), edges_of([c[2] for c in cols], types)


def test_a_scene_of_points_is_matched_and_located() -> None:
    left, middle, right = scene_edges(SCENE)
    # edges seen by one camera only are ignored
    left = concat_edges(left, edges_of([100.0, 500.0], [3, 7]))
    right = concat_edges(right, edges_of([90.0, 333.0], [3, 12]))
    m = match_trinocular(left, middle, right, F, B, 2.0, 30.0, 0.5)
    assert isinstance(m, Matches)
    want = sorted((t, *rig_columns(f, lft)) for f, lft, t in SCENE)
    assert m.type.tolist() == [w[0] for w in want]
    for got, i in ((m.u_left, 1), (m.u_middle, 2), (m.u_right, 3)):
        np.testing.assert_allclose(got, [w[i] for w in want], atol=1e-12)
    rng, bearing = rig_range_bearing(m.u_left, m.u_right, F, B, CX)
    truth = sorted((t, math.hypot(f, lft), math.atan2(lft, f)) for f, lft, t in SCENE)
    np.testing.assert_allclose(rng, [w[1] for w in truth], rtol=1e-9)
    np.testing.assert_allclose(bearing, [w[2] for w in truth], atol=1e-9)


def test_unsorted_input_is_matched_like_sorted_input() -> None:
    cams = scene_edges(SCENE)
    rng = np.random.default_rng(5)
    perms = [rng.permutation(e.u.size) for e in cams]
    left, middle, right = (EdgeList(e.u[p], e.type[p], e.strength[p]) for e, p in zip(cams, perms))
    for got, want in zip(
        match_trinocular(left, middle, right, F, B, 2.0, 30.0, 0.5), match_trinocular(*cams, F, B, 2.0, 30.0, 0.5)
    ):
        np.testing.assert_array_equal(got, want)


def pole_row(count: int = 17, depth: float = 10.0, spacing_m: float = 0.24, t: int = 9) -> list[tuple[float, float, int]]:
    """Identical poles in a row across the view: a period of ``F spacing / depth`` = 12 px in every camera."""
    return [(depth, spacing_m * (i - count // 2), t) for i in range(count)]


def test_a_repetitive_pattern_is_resolved_by_the_middle_camera() -> None:
    poles = pole_row()
    left, middle, right = scene_edges(poles)
    d_min, d_max = disparity_window(F, B, 5.0, 20.0)  # 9.5 .. 38 px: the true 19 px and the wrong 31 px
    d = left.u[:, None] - right.u[None, :]
    pairs = int(((d >= d_min) & (d <= d_max)).sum())
    assert pairs > len(poles) + 10  # the left/right pairs alone are ambiguous
    m = match_trinocular(left, middle, right, F, B, 5.0, 20.0, 1.0)
    assert m.u_left.size == len(poles)
    np.testing.assert_allclose(m.u_left - m.u_right, F * 2 * B / 10.0, atol=1e-9)
    np.testing.assert_allclose(m.u_middle, (m.u_left + m.u_right) / 2, atol=1e-9)


def test_a_pair_without_middle_confirmation_is_dropped() -> None:
    poles = pole_row()
    left, middle, right = scene_edges(poles)
    gone = 5
    keep = np.arange(middle.u.size) != gone
    middle = EdgeList(middle.u[keep], middle.type[keep], middle.strength[keep])
    m = match_trinocular(left, middle, right, F, B, 5.0, 20.0, 1.0)
    assert m.u_left.size == len(poles) - 1
    assert left.u[gone] not in m.u_left.tolist()
    np.testing.assert_allclose(m.u_left - m.u_right, F * 2 * B / 10.0, atol=1e-9)
    # a middle edge of another type confirms nothing
    left2, middle2, right2 = scene_edges([(6.0, 0.3, 4)])
    other = EdgeList(middle2.u, np.array([5]), middle2.strength)
    assert match_trinocular(left2, other, right2, F, B, 2.0, 30.0, 1.0).u_left.size == 0
    assert match_trinocular(left2, middle2, right2, F, B, 2.0, 30.0, 1.0).u_left.size == 1


@pytest.mark.parametrize(
    ("offset", "matched"), [(0.0, True), (0.45, True), (-0.45, True), (0.55, False), (-0.55, False), (3.0, False)]
)
def test_the_middle_edge_must_be_within_the_tolerance_of_the_midpoint(offset: float, matched: bool) -> None:
    left, middle, right = scene_edges([(6.0, 0.3, 4)])
    moved = EdgeList(middle.u + offset, middle.type, middle.strength)
    assert match_trinocular(left, moved, right, F, B, 2.0, 30.0, 0.5).u_left.size == int(matched)


@pytest.mark.parametrize(
    ("forward", "matched"), [(40.0, False), (31.0, False), (29.0, True), (10.0, True), (2.1, True), (1.9, False)]
)
def test_disparities_outside_the_range_window_are_dropped(forward: float, matched: bool) -> None:
    m = match_trinocular(*scene_edges([(forward, 0.0, 2)]), F, B, 2.0, 30.0, 0.5)
    assert m.u_left.size == int(matched)


def test_conflicts_go_to_the_smallest_middle_residual_and_strength_is_the_least() -> None:
    left = edges_of([400.0], [6], 80.0)
    right = EdgeList(np.array([379.0, 381.0]), np.array([6, 6]), np.array([50.0, 90.0], np.float32))
    middle = EdgeList(np.array([390.4]), np.array([6]), np.array([70.0], np.float32))  # midpoints 389.5 and 390.5
    m = match_trinocular(left, middle, right, F, B, 2.0, 30.0, 1.0)
    assert m.u_right.tolist() == [381.0]
    assert m.strength.tolist() == [70.0]
    # each edge serves one pair: two lefts and two rights share the only middle edge; the
    # crossed pairs fit best (residuals 0.1 and 0.2), the first takes the middle edge
    left = edges_of([400.0, 401.2], [6, 6])
    right = edges_of([380.0, 380.6], [6, 6])
    middle = edges_of([390.5], [6])
    m = match_trinocular(left, middle, right, F, B, 2.0, 30.0, 1.0)
    assert (m.u_left.tolist(), m.u_right.tolist()) == ([401.2], [380.0])


def test_no_edges_give_no_matches() -> None:
    left, middle, right = scene_edges(SCENE)
    for cams in ((empty_edges(), middle, right), (left, empty_edges(), right), (left, middle, empty_edges())):
        m = match_trinocular(*cams, F, B, 2.0, 30.0, 0.5)
        assert m.u_left.size == 0 and m.type.dtype == np.int64 and m.strength.dtype == np.float32


def antialiased_stripes(
    width: int, height: int, boundaries: Sequence[float], colours: Sequence[tuple[int, int, int]]
) -> np.ndarray:
    """Stripes with boundaries at continuous columns: a cut pixel gets the area-weighted mean of its two colours."""
    img = np.empty((height, width, 3), np.uint8)
    cuts = [0.0, *boundaries, float(width)]
    for a, b, colour in zip(cuts[:-1], cuts[1:], colours):
        img[:, math.ceil(a) : math.floor(b)] = colour
    for b, c0, c1 in zip(boundaries, colours[:-1], colours[1:]):
        k = math.floor(b)
        alpha = k + 1 - b  # the share of column k right of the boundary
        img[:, k] = np.round((1 - alpha) * np.array(c0) + alpha * np.array(c1))
    return img


def test_images_of_a_scene_are_detected_matched_and_located() -> None:
    """End to end: three rendered images of a red pole's edge and a step to blue, then edges, matches, points."""
    width, height = 640, 480
    red, blue = (7.0, 0.4), (15.0, -1.2)  # (forward, left) in the robot frame
    images = []
    for cam in (B, 0.0, -B):
        boundaries = [project(*red, cam), project(*blue, cam)]
        images.append(antialiased_stripes(width, height, boundaries, [(0, 0, 0), (200, 0, 0), (200, 0, 180)]))
    detector = EdgeDetector.for_image(width, height, ROWS_480, threshold=30.0)
    left, middle, right = (detector.detect(img) for img in images)
    assert left.u.size == middle.u.size == right.u.size == 10  # two edges at five levels
    m = match_trinocular(left, middle, right, F, B, 2.0, 40.0, 0.2)
    is_red = [edge_type(0, lv, False) for lv in range(5)]
    assert sorted(m.type.tolist()) == sorted(is_red + [edge_type(2, lv, False) for lv in range(5)])
    rng, bearing = rig_range_bearing(m.u_left, m.u_right, F, B, CX)
    sel = np.isin(m.type, is_red)
    # uint8 rounding of the cut pixels moves an edge by at most 1/400 px: ~1e-4 of the disparity
    np.testing.assert_allclose(rng[sel], math.hypot(*red), rtol=1e-3)
    np.testing.assert_allclose(bearing[sel], math.atan2(red[1], red[0]), atol=1e-4)
    np.testing.assert_allclose(rng[~sel], math.hypot(*blue), rtol=1e-3)
    np.testing.assert_allclose(bearing[~sel], math.atan2(blue[1], blue[0]), atol=1e-4)


# ---------------------------------------------------------------------------- drawing
@pytest.mark.parametrize("channel", range(3))
@pytest.mark.parametrize("falling", [False, True])
def test_detections_are_drawn_in_their_channels_colour_hollow_or_filled(channel: int, falling: bool) -> None:
    img = np.full((480, 640, 3), 60, np.uint8)
    before = img.copy()
    rows = (100, 200)
    out = draw_detections(img, np.array([300.5]), np.array([edge_type(channel, 1, falling)]), rows, radius_px=5)
    np.testing.assert_array_equal(img, before)  # the input is not modified
    assert out.dtype == np.uint8 and out.shape == img.shape
    assert (out[100, 20] == 255).all() and (out[200, 20] == 255).all()  # the detection rows' white lines
    colour = np.array([(255, 0, 0), (0, 255, 0), (0, 0, 255)][channel])  # red, green, blue (RGB)
    np.testing.assert_array_equal(out[200 - 5, 300], colour)  # the circle's top
    centre = out[200 - 2, 300]  # inside the circle, off the white line
    np.testing.assert_array_equal(centre, colour if falling else [60, 60, 60])
    assert (out[300, 300] == 60).all()  # far from both lines and the marker


# ---------------------------------------------------------------------------- bad input
GOOD_IMAGE = np.zeros((480, 640, 3), np.uint8)


@pytest.mark.parametrize(
    ("image", "named"),
    [
        (np.zeros((480, 640, 3), np.float32), "float32"),
        (np.zeros((480, 640), np.uint8), "(480, 640)"),
        (np.zeros((480, 640, 4), np.uint8), "(480, 640, 4)"),
        (np.zeros((480, 640, 3), np.int64), "int64"),
    ],
)
def test_a_bad_image_is_refused_naming_its_dtype_and_shape(image: np.ndarray, named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        vertical_edge_response(image, ROWS_480, 101, 7)
    with pytest.raises(ValueError, match=re.escape(named)):
        draw_detections(image, [], [], ROWS_480)


@pytest.mark.parametrize(
    ("rows", "filter_rows", "filter_cols", "named"),
    [
        (ROWS_480, 100, 7, "filter_rows must be an odd integer >= 3, got 100"),
        (ROWS_480, 101, 6, "filter_cols must be an odd integer >= 3, got 6"),
        (ROWS_480, 1, 7, "got 1"),
        (ROWS_480, 101, 7.0, "got 7.0"),
        (ROWS_480, 101, 641, "filter_cols 641"),
        ((49, 100), 101, 7, "row 49"),
        ((100, 430), 101, 7, "row 430"),
        ((100, 100), 101, 7, "[100, 100]"),
        ((200, 100), 101, 7, "[200, 100]"),
        ((60, 100, 150, 200, 250, 300), 101, 7, "[60, 100, 150, 200, 250, 300]"),
        ((100.0,), 101, 7, "[100.0]"),
        ((), 101, 7, "[]"),
    ],
)
def test_bad_filters_and_rows_are_refused_naming_the_value(
    rows: object, filter_rows: object, filter_cols: object, named: str
) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        vertical_edge_response(GOOD_IMAGE, rows, filter_rows, filter_cols)  # type: ignore[arg-type]


@pytest.mark.parametrize("threshold", [0.0, -1.0, math.nan, math.inf])
def test_a_bad_threshold_is_refused_naming_it(threshold: float) -> None:
    with pytest.raises(ValueError, match=f"threshold.*{threshold}"):
        detect_edges(np.zeros((1, 10, 3), np.float32), threshold)
    with pytest.raises(ConfigError, match=f"threshold.*{threshold}"):
        EdgeDetector((100,), 101, 7, threshold)


@pytest.mark.parametrize("shape", [(6, 10, 3), (1, 10, 4), (10, 3)])
def test_a_bad_response_shape_is_refused(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=re.escape(str(shape))):
        detect_edges(np.zeros(shape, np.float32), 1.0)


@pytest.mark.parametrize(
    ("args", "named"),
    [
        ((0.0, B, 2.0, 30.0, 0.5), "focal_px must be finite and > 0, got 0.0"),
        ((-500.0, B, 2.0, 30.0, 0.5), "focal_px must be finite and > 0, got -500.0"),
        ((math.nan, B, 2.0, 30.0, 0.5), "focal_px must be finite and > 0, got nan"),
        ((F, 0.0, 2.0, 30.0, 0.5), "baseline_m must be finite and > 0, got 0.0"),
        ((F, -0.19, 2.0, 30.0, 0.5), "baseline_m must be finite and > 0, got -0.19"),
        ((F, B, 0.0, 30.0, 0.5), "min_range_m must be finite and > 0, got 0.0"),
        ((F, B, 2.0, math.inf, 0.5), "max_range_m must be finite and > 0, got inf"),
        ((F, B, 30.0, 30.0, 0.5), "got 30.0 >= 30.0"),
        ((F, B, 40.0, 30.0, 0.5), "got 40.0 >= 30.0"),
        ((F, B, 2.0, 30.0, 0.0), "tolerance_px must be finite and > 0, got 0.0"),
        ((F, B, 2.0, 30.0, -1.0), "tolerance_px must be finite and > 0, got -1.0"),
    ],
)
def test_bad_matching_parameters_are_refused_naming_the_value(args: tuple[float, ...], named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        match_trinocular(*scene_edges(SCENE), *args)


@pytest.mark.parametrize(
    ("edges", "named"),
    [
        (EdgeList(np.array([1.0, math.nan]), np.array([0, 0]), np.ones(2, np.float32)), "nan"),
        (EdgeList(np.array([1.0, math.inf]), np.array([0, 0]), np.ones(2, np.float32)), "inf"),
        (EdgeList(np.array([1.0, 2.0]), np.array([0, 30]), np.ones(2, np.float32)), "30"),
        (EdgeList(np.array([1.0, 2.0]), np.array([-1, 0]), np.ones(2, np.float32)), "-1"),
        (EdgeList(np.array([1.0, 2.0]), np.array([0]), np.ones(2, np.float32)), "(2,), (1,), (2,)"),
        (EdgeList(np.array([1.0]), np.array([0]), np.array([-3.0], np.float32)), "-3.0"),
        (EdgeList(np.array(["left"]), np.array([0]), np.ones(1, np.float32)), "'left'"),
    ],
)
def test_bad_edge_lists_are_refused_naming_the_value(edges: EdgeList, named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        match_trinocular(edges, edges_of([1.0], [0]), edges_of([1.0], [0]), F, B, 2.0, 30.0, 0.5)
    with pytest.raises(ValueError, match=re.escape(named)):
        concat_edges(edges)


@pytest.mark.parametrize(
    ("ul", "ur", "f", "b", "named"),
    [
        (320.0, 320.0, F, 0.38, "disparity u_left - u_right must be > 0, got 0.0"),
        (np.array([330.0, 300.0]), np.array([320.0, 310.0]), F, 0.38, "got -10.0"),
        (math.nan, 300.0, F, 0.38, "u_left must be finite, got nan"),
        (320.0, math.nan, F, 0.38, "u_right must be finite, got nan"),
        (320.0, 300.0, 0.0, 0.38, "focal_px must be finite and > 0, got 0.0"),
        (320.0, 300.0, F, -0.38, "baseline_m must be finite and > 0, got -0.38"),
        ("left", 300.0, F, 0.38, "u_left must be numbers, got 'left'"),
    ],
)
def test_bad_triangulation_input_is_refused_naming_the_value(ul: object, ur: object, f: float, b: float, named: str) -> None:
    with pytest.raises(ValueError, match=re.escape(named)):
        triangulate(ul, ur, f, b, CX)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=re.escape(named.replace("-0.38", "-0.19"))):
        rig_range_bearing(ul, ur, f, b / 2, CX)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"focal_px": 0.0}, "focal_px must be finite and > 0, got 0.0"),
        ({"neighbour_baseline_m": -0.19}, "neighbour_baseline_m must be finite and > 0, got -0.19"),
        ({"min_range_m": 30.0}, "got 30.0 >= 30.0"),
        ({"cx_px": math.nan}, "cx_px must be finite, got nan"),
        ({"tolerance_px": 0}, "tolerance_px must be finite and > 0, got 0"),
    ],
)
def test_bad_rig_configs_are_refused_naming_the_value(kwargs: dict[str, float], named: str) -> None:
    base = {"focal_px": F, "cx_px": CX, "neighbour_baseline_m": B, "min_range_m": 2.0, "max_range_m": 30.0, "tolerance_px": 1.0}
    with pytest.raises(ConfigError, match=re.escape(named)):
        TrinocularRig(**{**base, **kwargs})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"rows": (100, 50)}, "(100, 50)"),
        ({"rows": ()}, "()"),
        ({"filter_rows": 100}, "filter_rows must be an odd integer >= 3, got 100"),
        ({"filter_cols": 2}, "filter_cols must be an odd integer >= 3, got 2"),
    ],
)
def test_bad_detector_configs_are_refused_naming_the_value(kwargs: dict[str, object], named: str) -> None:
    base: dict[str, object] = {"rows": ROWS_480, "filter_rows": 101, "filter_cols": 7, "threshold": 20.0}
    with pytest.raises(ConfigError, match=re.escape(named)):
        EdgeDetector(**{**base, **kwargs})  # type: ignore[arg-type]


def test_bad_drawing_input_is_refused_naming_the_value() -> None:
    with pytest.raises(ValueError, match="30"):
        draw_detections(GOOD_IMAGE, [10.0], [30], ROWS_480)
    with pytest.raises(ValueError, match="nan"):
        draw_detections(GOOD_IMAGE, [math.nan], [0], ROWS_480)
    with pytest.raises(ValueError, match=r"level 4 but only 2 rows"):
        draw_detections(GOOD_IMAGE, [10.0], [edge_type(0, 4, False)], (100, 200))
    with pytest.raises(ValueError, match="radius_px.*0"):
        draw_detections(GOOD_IMAGE, [10.0], [0], ROWS_480, radius_px=0)
