"""``core.raycast`` against closed-form distances and a brute-force numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from core.raycast import cast_rays, cast_rays_from, sight_lines_clear

NO_POINTS = np.zeros((0, 2))
NO_RADII = np.zeros(0)
MAX_RANGE = 30.0


def box_segments(xmin: float, ymin: float, xmax: float, ymax: float) -> tuple[np.ndarray, np.ndarray]:
    corners = np.array([[xmin, ymin], [xmax, ymin], [xmax, ymax], [xmin, ymax]])
    return corners, np.roll(corners, -1, axis=0)


def box_distance(origin: np.ndarray, angles: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    """Distance from a point inside an axis-aligned box to its boundary along each angle."""
    xmin, ymin, xmax, ymax = box
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (xmax - origin[0]) / c, np.where(c < 0, (xmin - origin[0]) / c, np.inf))
        ty = np.where(s > 0, (ymax - origin[1]) / s, np.where(s < 0, (ymin - origin[1]) / s, np.inf))
    return np.minimum(tx, ty)


def reference_ranges(
    origin: np.ndarray,
    angles: np.ndarray,
    max_range: float,
    seg_a: np.ndarray,
    seg_b: np.ndarray,
    centres: np.ndarray,
    radii: np.ndarray,
    eps: float = 1e-9,
) -> tuple[np.ndarray, np.ndarray]:
    """Brute force over every (ray, obstacle) pair with plain numpy broadcasting.

    Returns the ranges and a mask of rays whose answer is numerically ambiguous (a ray
    grazing a circle, passing a segment's end point, or running along a segment).
    """
    d = np.stack([np.cos(angles), np.sin(angles)], axis=1)  # (B, 2)
    best = np.full(angles.shape[0], float(max_range))
    ambiguous = np.zeros(angles.shape[0], dtype=bool)
    if seg_a.shape[0]:
        e = seg_b - seg_a  # (S, 2)
        w = seg_a - origin  # (S, 2)
        # solve origin + t d = a + u e with Cramer's rule, every ray against every segment
        det = d[:, None, 0] * e[None, :, 1] - d[:, None, 1] * e[None, :, 0]  # (B, S)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            t = (w[None, :, 0] * e[None, :, 1] - w[None, :, 1] * e[None, :, 0]) / det
            u = (w[None, :, 0] * d[:, None, 1] - w[None, :, 1] * d[:, None, 0]) / det
        parallel = np.abs(det) < 1e-9
        hit = ~parallel & (t >= 0) & (u >= 0) & (u <= 1)
        best = np.minimum(best, np.where(hit, t, np.inf).min(axis=1))
        near_end = ~parallel & (t >= -eps) & (((u > -eps) & (u < eps)) | ((u > 1 - eps) & (u < 1 + eps)))
        ambiguous |= (near_end | parallel).any(axis=1)
    if centres.shape[0]:
        f = origin - centres  # (C, 2)
        b = d @ f.T  # (B, C): d . (o - c)
        cc = np.sum(f * f, axis=1) - radii**2  # (C,)
        disc = b**2 - cc[None, :]
        inside = cc <= 0
        root = -b - np.sqrt(np.maximum(disc, 0.0))
        hit = (disc >= 0) & (root >= 0)
        t = np.where(inside[None, :], 0.0, np.where(hit, root, np.inf))
        best = np.minimum(best, t.min(axis=1))
        ambiguous |= ((np.abs(disc) < eps) & (-b > 0) & ~inside[None, :]).any(axis=1)
        ambiguous |= (np.abs(cc) < eps)[None, :].any(axis=1)
    return np.minimum(best, max_range), ambiguous


def scan_angles(first: float, fov: float, beams: int) -> np.ndarray:
    return first + np.linspace(0.0, fov, beams)


# ---------------------------------------------------------------------------- walls


@pytest.mark.parametrize("origin", [(1.0, 0.5), (3.3, 2.1), (0.2, 2.9)])
@pytest.mark.parametrize(
    "angles",
    [
        scan_angles(-math.pi, 2 * math.pi * 359 / 360, 360),
        scan_angles(-0.75 * math.pi, 1.5 * math.pi, 1081),
        scan_angles(2.0, 1.5 * math.pi, 97),  # angles run past pi
    ],
    ids=["full-turn", "270deg", "past-pi"],
)
def test_cast_rays_in_a_box_matches_the_analytic_wall_distance(origin: tuple[float, float], angles: np.ndarray) -> None:
    box = (0.0, 0.0, 4.0, 3.0)
    seg_a, seg_b = box_segments(*box)
    o = np.array(origin)
    ranges = cast_rays(o, angles, MAX_RANGE, seg_a, seg_b, NO_POINTS, NO_RADII)
    np.testing.assert_allclose(ranges, box_distance(o, angles, box), rtol=0, atol=1e-9)


def test_cast_rays_clips_at_max_range() -> None:
    seg_a, seg_b = box_segments(0.0, 0.0, 40.0, 3.0)
    angles = np.array([0.0, math.pi / 2, math.pi])
    ranges = cast_rays(np.array([1.0, 1.0]), angles, 10.0, seg_a, seg_b, NO_POINTS, NO_RADII)
    np.testing.assert_allclose(ranges, [10.0, 2.0, 1.0], atol=1e-12)


def test_cast_rays_ignores_walls_behind_and_beside_the_ray() -> None:
    # one wall behind the origin, one parallel to the ray, one off to the side
    seg_a = np.array([[-1.0, -1.0], [0.0, 1.0], [2.0, 0.5]])
    seg_b = np.array([[-1.0, 1.0], [5.0, 1.0], [2.0, 3.0]])
    ranges = cast_rays(np.zeros(2), np.array([0.0]), MAX_RANGE, seg_a, seg_b, NO_POINTS, NO_RADII)
    assert ranges[0] == MAX_RANGE


# ---------------------------------------------------------------------------- circles


@pytest.mark.parametrize(
    ("centre", "radius", "expected"),
    [
        ((3.0, 0.0), 0.5, 2.5),  # straight on: d - r
        ((7.25, 0.0), 0.25, 7.0),
        ((5.0, 0.5), 0.5, 5.0),  # tangent: the ray grazes the circle at x = 5
        ((5.0, 0.75), 0.5, MAX_RANGE),  # misses by 0.25 m
        ((-3.0, 0.0), 0.5, MAX_RANGE),  # behind the origin
        ((40.0, 0.0), 0.5, MAX_RANGE),  # beyond max range
    ],
    ids=["ahead", "ahead-far", "tangent", "miss", "behind", "beyond-range"],
)
def test_cast_rays_single_beam_against_a_circle(centre: tuple[float, float], radius: float, expected: float) -> None:
    ranges = cast_rays(np.zeros(2), np.array([0.0]), MAX_RANGE, NO_POINTS, NO_POINTS, np.array([centre]), np.array([radius]))
    assert ranges[0] == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("heading", [0.0, 1.0, math.pi - 0.05, -math.pi + 0.02])
@pytest.mark.parametrize("offset", [0.0, -0.04, 0.04, 0.1], ids=["on-first-beam", "before-first", "after-first", "inside"])
def test_cast_rays_circle_straddling_the_first_beam_of_a_270deg_scan(heading: float, offset: float) -> None:
    first = heading - 0.75 * math.pi
    angles = scan_angles(first, 1.5 * math.pi, 1081)
    d, r = 3.0, 0.3  # the circle covers +-asin(0.1) = +-0.1 rad around its centre
    centre_angle = first + offset
    centre = np.array([[d * math.cos(centre_angle), d * math.sin(centre_angle)]])
    origin = np.array([0.4, -0.7])
    ranges = cast_rays(origin, angles, MAX_RANGE, NO_POINTS, NO_POINTS, centre + origin, np.array([r]))
    # closed form for a beam at angle delta off the centre line: d cos(delta) - sqrt(r^2 - d^2 sin^2(delta))
    delta = (angles - centre_angle + math.pi) % (2 * math.pi) - math.pi
    h2 = r**2 - (d * np.sin(delta)) ** 2
    expected = np.where((h2 >= 0) & (np.abs(delta) < math.pi / 2), d * np.cos(delta) - np.sqrt(np.maximum(h2, 0)), MAX_RANGE)
    np.testing.assert_allclose(ranges, expected, atol=1e-9)
    assert ranges[0] < MAX_RANGE  # the first beam is blocked in every case here
    assert np.count_nonzero(ranges < MAX_RANGE) >= 10


def test_cast_rays_circle_straddling_the_seam_of_a_full_turn_scan() -> None:
    beams = 360
    angles = scan_angles(0.0, 2 * math.pi * (beams - 1) / beams, beams)
    d, r = 2.0, 0.2
    centre = np.array([[d, 0.0]])  # centred on beam 0: beams 359, 0 and 1 ... see it
    ranges = cast_rays(np.zeros(2), angles, MAX_RANGE, NO_POINTS, NO_POINTS, centre, np.array([r]))
    expected, _ = reference_ranges(np.zeros(2), angles, MAX_RANGE, NO_POINTS, NO_POINTS, centre, np.array([r]))
    np.testing.assert_allclose(ranges, expected, atol=1e-9)
    assert ranges[0] == pytest.approx(d - r, abs=1e-12)
    assert ranges[-1] < MAX_RANGE and ranges[1] < MAX_RANGE
    assert ranges[-1] == pytest.approx(ranges[1], abs=1e-12)


@pytest.mark.parametrize(
    "angles",
    [np.array([0.0, 0.1, 0.2, 3.0]), np.array([-1.0, 0.2, 0.21, 0.5, 4.0])],
    ids=["uneven-a", "uneven-b"],
)
def test_cast_rays_uneven_beam_spacing(angles: np.ndarray) -> None:
    # the docstring allows any ascending angles, not only a uniform LIDAR fan
    centres = np.array([[5.0 * math.cos(a), 5.0 * math.sin(a)] for a in angles[1:]])
    radii = np.full(centres.shape[0], 0.3)
    ranges = cast_rays(np.zeros(2), angles, MAX_RANGE, NO_POINTS, NO_POINTS, centres, radii)
    np.testing.assert_allclose(ranges[1:], 4.7, atol=1e-12)


def test_cast_rays_origin_inside_a_circle_blinds_every_beam() -> None:
    seg_a, seg_b = box_segments(-5.0, -5.0, 5.0, 5.0)
    angles = scan_angles(-0.75 * math.pi, 1.5 * math.pi, 181)
    centres = np.array([[0.1, 0.1], [3.0, 0.0]])
    ranges = cast_rays(np.zeros(2), angles, MAX_RANGE, seg_a, seg_b, centres, np.array([0.25, 0.5]))
    np.testing.assert_array_equal(ranges, np.zeros_like(angles))


def test_cast_rays_nearest_obstacle_wins() -> None:
    seg_a = np.array([[4.0, -1.0]])
    seg_b = np.array([[4.0, 1.0]])
    centres = np.array([[2.0, 0.0], [6.0, 0.0]])
    radii = np.array([0.5, 0.5])
    ranges = cast_rays(np.zeros(2), np.array([0.0, math.pi]), MAX_RANGE, seg_a, seg_b, centres, radii)
    np.testing.assert_allclose(ranges, [1.5, MAX_RANGE], atol=1e-12)
    ranges = cast_rays(np.zeros(2), np.array([0.0]), MAX_RANGE, seg_a, seg_b, centres[1:], radii[1:])
    assert ranges[0] == pytest.approx(4.0, abs=1e-12)


def test_cast_rays_empty_scan() -> None:
    ranges = cast_rays(np.zeros(2), np.zeros(0), MAX_RANGE, NO_POINTS, NO_POINTS, np.array([[1.0, 0.0]]), np.array([0.1]))
    assert ranges.shape == (0,)


# ---------------------------------------------------------------------------- property test

coord = st.floats(-6.0, 6.0, allow_nan=False, allow_infinity=False)


@st.composite
def scenes(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    origin = np.array([draw(coord), draw(coord)])
    beams = draw(st.integers(1, 200))
    first = draw(st.floats(-2 * math.pi, 2 * math.pi))
    full = 2 * math.pi * (beams - 1) / beams if beams > 1 else 0.0
    fov = draw(st.floats(0.0, 1.0)) * full
    even = draw(st.booleans())
    if even or beams == 1:
        angles = first + np.linspace(0.0, fov, beams)
    else:
        steps = np.array(draw(st.lists(st.floats(0.0, 1.0), min_size=beams - 1, max_size=beams - 1)))
        angles = first + np.concatenate([[0.0], np.cumsum(steps)]) * (fov / max(steps.sum(), 1e-9))
    max_range = draw(st.floats(0.5, 20.0))
    n_seg = draw(st.integers(0, 6))
    seg = np.array(draw(st.lists(coord, min_size=4 * n_seg, max_size=4 * n_seg)), dtype=np.float64).reshape(n_seg, 4)
    n_circ = draw(st.integers(0, 8))
    centres = np.array(draw(st.lists(coord, min_size=2 * n_circ, max_size=2 * n_circ)), dtype=np.float64).reshape(n_circ, 2)
    radii = np.array(draw(st.lists(st.floats(0.02, 1.5), min_size=n_circ, max_size=n_circ)), dtype=np.float64)
    return (
        origin,
        np.ascontiguousarray(angles),
        max_range,
        np.ascontiguousarray(seg[:, :2]),
        np.ascontiguousarray(seg[:, 2:]),
        centres,
        radii,
    )


@settings(max_examples=300, deadline=None)
@given(scene=scenes())
def test_cast_rays_matches_brute_force_reference(scene: tuple) -> None:
    origin, angles, max_range, seg_a, seg_b, centres, radii = scene
    got = cast_rays(origin, angles, max_range, seg_a, seg_b, centres, radii)
    want, ambiguous = reference_ranges(origin, angles, max_range, seg_a, seg_b, centres, radii)
    assert got.shape == angles.shape
    assert np.all((got >= 0) & (got <= max_range))
    np.testing.assert_allclose(got[~ambiguous], want[~ambiguous], rtol=0, atol=1e-7)


@settings(max_examples=300, deadline=None)
@given(
    scene=scenes(),
    shift=st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1)),
    turn=st.floats(-1.0, 7.0),
    shuffled=st.booleans(),
)
def test_cast_rays_from_matches_the_reference_from_each_origin(scene: tuple, shift: tuple, turn: float, shuffled: bool) -> None:
    """A swept scan: ray i from its own origin (up to 14 cm apart), its direction turned by up to
    7 rad over the scan (past a full turn: the culling's 3 pi limit), or the rays out of order
    (every beam tested)."""
    origin, angles, max_range, seg_a, seg_b, centres, radii = scene
    n = angles.shape[0]
    along = np.linspace(0.0, 1.0, n)
    origins = origin + along[:, None] * np.array(shift)
    angles = angles + turn * along
    if shuffled:
        angles = np.random.default_rng(n).permutation(angles)
    got = cast_rays_from(origins, np.ascontiguousarray(angles), max_range, seg_a, seg_b, centres, radii)
    want = np.empty(n)
    ambiguous = np.empty(n, dtype=bool)
    for i in range(n):
        r, a = reference_ranges(origins[i], angles[i : i + 1], max_range, seg_a, seg_b, centres, radii)
        want[i], ambiguous[i] = r[0], a[0]
    assert got.shape == (n,)
    np.testing.assert_allclose(got[~ambiguous], want[~ambiguous], rtol=0, atol=1e-7)


@pytest.mark.parametrize("beams", [1, 97, 1081])
def test_cast_rays_from_one_origin_equals_cast_rays_bit_for_bit(beams: int) -> None:
    """Every ray from one point: the same culling, the same ranges (a swept LIDAR on a robot standing still)."""
    rng = np.random.default_rng(beams)
    seg_a = rng.uniform(-5, 5, (12, 2))
    seg_b = seg_a + rng.uniform(-3, 3, (12, 2))
    centres, radii = rng.uniform(-5, 5, (20, 2)), rng.uniform(0.05, 0.5, 20)
    origin = np.array([0.3, -0.2])
    angles = scan_angles(-0.75 * math.pi, 1.5 * math.pi, beams)
    one = cast_rays(origin, angles, MAX_RANGE, seg_a, seg_b, centres, radii)
    each = cast_rays_from(np.tile(origin, (beams, 1)), angles, MAX_RANGE, seg_a, seg_b, centres, radii)
    assert np.array_equal(one, each)


# ---------------------------------------------------------------------------- sight lines


def visible(
    origin: tuple[float, float],
    targets: list[tuple[float, float]],
    *,
    target_radii: float = 0.05,
    max_range: float = math.inf,
    walls: list[tuple[float, float, float, float]] = (),  # type: ignore[assignment]
    circles: list[tuple[float, float, float]] = (),  # type: ignore[assignment]
) -> list[bool]:
    t = np.array(targets, dtype=np.float64).reshape(-1, 2)
    w = np.array(walls, dtype=np.float64).reshape(-1, 4)
    c = np.array(circles, dtype=np.float64).reshape(-1, 3)
    out = sight_lines_clear(
        np.array(origin, dtype=np.float64),
        t,
        np.full(t.shape[0], target_radii),
        np.full(t.shape[0], max_range),
        np.ascontiguousarray(w[:, :2]),
        np.ascontiguousarray(w[:, 2:]),
        np.ascontiguousarray(c[:, :2]),
        np.ascontiguousarray(c[:, 2]),
    )
    assert out.dtype == np.bool_
    return out.tolist()


@pytest.mark.parametrize(
    ("kwargs", "expected"),
    [
        ({}, [True, True]),
        ({"circles": [(2.0, 0.0, 0.3)]}, [False, True]),  # a person on the first sight line
        ({"circles": [(2.0, 0.5, 0.3)]}, [True, True]),  # beside it (0.5 m off, r = 0.3 m)
        ({"circles": [(6.0, 0.0, 0.3)]}, [True, True]),  # behind the first target
        ({"circles": [(-2.0, 0.0, 0.3)]}, [True, True]),  # behind the viewer
        ({"circles": [(0.0, 0.0, 0.3)]}, [False, False]),  # the viewer stands inside an occluder
        ({"walls": [(2.0, -1.0, 2.0, 1.0)]}, [False, True]),  # a wall across the first line
        ({"walls": [(2.0, 0.5, 2.0, 1.0)]}, [True, True]),  # a wall that stops short of it
        ({"walls": [(6.0, -1.0, 6.0, 1.0)]}, [True, True]),  # a wall behind the target
        ({"max_range": 4.5}, [True, False]),  # second target at 5 m
        ({"max_range": 3.9}, [False, False]),
    ],
)
def test_sight_lines_clear_hand_built_cases(kwargs: dict, expected: list[bool]) -> None:
    # targets: 4 m along +x, and 5 m along +y
    assert visible((0.0, 0.0), [(4.0, 0.0), (0.0, 5.0)], **kwargs) == expected


def test_sight_lines_clear_occluder_grazing_the_pole_does_not_hide_it() -> None:
    # an occluder behind the pole's near side (it touches the pole from behind) does not hide it
    assert visible((0.0, 0.0), [(4.0, 0.0)], target_radii=0.1, circles=[(4.3, 0.0, 0.25)]) == [True]
    # the same occluder moved in front of the pole's near side hides it
    assert visible((0.0, 0.0), [(4.0, 0.0)], target_radii=0.1, circles=[(3.6, 0.0, 0.25)]) == [False]


def test_sight_lines_clear_without_targets() -> None:
    assert visible((0.0, 0.0), [], circles=[(1.0, 0.0, 0.2)]) == []
