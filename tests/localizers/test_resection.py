"""Tests of localizers.resection: Cassini's resection against exact geometry (and its
refusal near the danger circle), the inscribed-angle arc, the all-triples combination and
the baseline (2) localizer contract."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from core.geometry import bearings_to, wrap_angle
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, MeasurementError, OdometryDelta
from localizers.resection import (
    DEFAULT_MIN_CONDITIONING,
    ResectionLocalizer,
    ResectionParams,
    cassini_resection,
    inscribed_arc_poses,
    resect_all_triples,
)

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "localizers" / "resection.yaml"
DT = 1.0 / 30.0


def bearings_from(pose: np.ndarray, landmarks_xy: np.ndarray) -> np.ndarray:
    """Exact bearings ``(..., L)`` from poses ``(..., 3)`` to per-case landmarks ``(..., L, 2)``."""
    d = landmarks_xy - pose[..., None, :2]
    return np.asarray(wrap_angle(np.arctan2(d[..., 1], d[..., 0]) - pose[..., 2, None]))


def min_triangle_angle(tri: np.ndarray) -> np.ndarray:
    angles = []
    for i in range(3):
        a = tri[:, (i + 1) % 3] - tri[:, i]
        b = tri[:, (i + 2) % 3] - tri[:, i]
        cos = np.sum(a * b, axis=1) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
        angles.append(np.arccos(np.clip(cos, -1.0, 1.0)))
    return np.min(angles, axis=0)


def inside_triangle(tri: np.ndarray, p: np.ndarray) -> np.ndarray:
    signs = []
    for i in range(3):
        a, b = tri[:, i], tri[:, (i + 1) % 3]
        signs.append(np.sign((b[:, 0] - a[:, 0]) * (p[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (p[:, 0] - a[:, 0])))
    s = np.array(signs)
    return (s == s[0]).all(axis=0) & (s[0] != 0)


def well_conditioned_cases(seed: int, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Robot strictly inside a landmark triangle whose angles are all >= 20 deg, >= 0.5 m from each landmark."""
    rng = np.random.default_rng(seed)
    tris, poses = [], []
    while len(tris) < count:
        tri = rng.uniform(0.0, 10.0, (512, 3, 2))
        pose = np.column_stack([rng.uniform(0.0, 10.0, (512, 2)), rng.uniform(-math.pi, math.pi, 512)])
        far = np.linalg.norm(tri - pose[:, None, :2], axis=2).min(axis=1) >= 0.5
        good = inside_triangle(tri, pose[:, :2]) & (min_triangle_angle(tri) >= math.radians(20.0)) & far
        tris.extend(tri[good])
        poses.extend(pose[good])
    return np.array(tris[:count]), np.array(poses[:count])


def circle_through(tri: np.ndarray) -> tuple[np.ndarray, float]:
    (ax, ay), (bx, by), (cx, cy) = tri
    d = 2.0 * (ax * (by - cy) + bx * (cy - ay) + cx * (ay - by))
    ux = ((ax**2 + ay**2) * (by - cy) + (bx**2 + by**2) * (cy - ay) + (cx**2 + cy**2) * (ay - by)) / d
    uy = ((ax**2 + ay**2) * (cx - bx) + (bx**2 + by**2) * (ax - cx) + (cx**2 + cy**2) * (bx - ax)) / d
    centre = np.array([ux, uy])
    return centre, float(np.linalg.norm(tri[0] - centre))


# ----------------------------------------------------------------------------- Cassini


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_cassini_exact_on_well_conditioned_geometry(seed: int) -> None:
    tris, poses = well_conditioned_cases(seed, 50)  # 4 x 50 = 200 cases
    solved, ok = cassini_resection(tris, bearings_from(poses, tris))
    assert ok.all()
    np.testing.assert_allclose(solved[:, :2], poses[:, :2], rtol=0.0, atol=1e-9)
    assert np.abs(wrap_angle(solved[:, 2] - poses[:, 2])).max() < 1e-9


def test_cassini_ok_solutions_are_never_wrong() -> None:
    """On arbitrary geometry every accepted solution is the true pose; the rest are NaN."""
    rng = np.random.default_rng(7)
    tris = rng.uniform(0.0, 10.0, (5000, 3, 2))
    poses = np.column_stack([rng.uniform(-5.0, 15.0, (5000, 2)), rng.uniform(-math.pi, math.pi, 5000)])
    solved, ok = cassini_resection(tris, bearings_from(poses, tris))
    assert 0.3 < ok.mean() < 1.0  # both branches exercised
    np.testing.assert_allclose(solved[ok, :2], poses[ok, :2], rtol=0.0, atol=1e-8)
    assert np.isnan(solved[~ok]).all()


def test_cassini_noisy_error_bounded_by_conditioning() -> None:
    """No wild poses: with 1e-3 rad noise an accepted solution stays within 10 % of the landmark distance."""
    rng = np.random.default_rng(11)
    tris = rng.uniform(0.0, 10.0, (5000, 3, 2))
    poses = np.column_stack([rng.uniform(-5.0, 15.0, (5000, 2)), rng.uniform(-math.pi, math.pi, 5000)])
    noisy = bearings_from(poses, tris) + rng.normal(0.0, 1e-3, (5000, 3))
    solved, ok = cassini_resection(tris, noisy)
    d_rms = np.sqrt(np.mean(np.sum((tris - poses[:, None, :2]) ** 2, axis=2), axis=1))
    error = np.linalg.norm(solved[:, :2] - poses[:, :2], axis=1)
    assert ok.sum() > 2000
    assert (error[ok] <= 0.1 * d_rms[ok]).all()


@pytest.mark.parametrize("landmark_deg", [(0.0, 120.0, 240.0), (0.0, 100.0, 220.0), (10.0, 50.0, 200.0)])
@pytest.mark.parametrize("robot_deg", [70.0, 160.0, 300.0])
@pytest.mark.parametrize("relative_offset", [0.0, 1e-4, -1e-4, 1e-3, -1e-3, 1e-2, -1e-2])
def test_cassini_refuses_near_danger_circle(
    landmark_deg: tuple[float, float, float], robot_deg: float, relative_offset: float
) -> None:
    radius = 5.0
    ang = np.radians(landmark_deg)
    tri = np.column_stack([radius * np.cos(ang), radius * np.sin(ang)]) + [3.0, -2.0]
    centre, r = circle_through(tri)
    assert r == pytest.approx(radius)
    a = math.radians(robot_deg)
    pose = np.array([*(centre + r * (1.0 + relative_offset) * np.array([math.cos(a), math.sin(a)])), 0.7])
    solved, ok = cassini_resection(tri, bearings_to(pose, tri))
    assert not ok
    assert np.isnan(solved).all()


def test_cassini_accepts_well_off_the_danger_circle() -> None:
    """The same geometry as above, the robot at the circle's centre: solved exactly."""
    ang = np.radians([0.0, 120.0, 240.0])
    tri = np.column_stack([5.0 * np.cos(ang), 5.0 * np.sin(ang)])
    pose = np.array([0.0, 0.0, -2.0])
    solved, ok = cassini_resection(tri, bearings_to(pose, tri))
    assert ok
    np.testing.assert_allclose(solved, pose, atol=1e-12)


@pytest.mark.parametrize("robot_xy", [(2.0, 0.0), (7.5, 0.0), (-3.0, 0.0), (14.0, 0.0)])
def test_cassini_collinear_landmarks_robot_on_their_line_has_no_solution(robot_xy: tuple[float, float]) -> None:
    tri = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    pose = np.array([*robot_xy, 0.4])
    solved, ok = cassini_resection(tri, bearings_to(pose, tri))
    assert not ok
    assert np.isnan(solved).all()


@pytest.mark.parametrize("bearings", [(0.3, 0.3, 0.3), (0.3, 0.3 + math.pi, 0.3), (1.0, 1.0, -2.0)])
def test_cassini_collinear_bearings_have_no_solution(bearings: tuple[float, float, float]) -> None:
    """Bearings that are all equal up to pi put the robot on one line with all three landmarks."""
    tri = np.array([[0.0, 0.0], [4.0, 1.0], [1.0, 6.0]])
    solved, ok = cassini_resection(tri, np.array(bearings))
    assert not ok
    assert np.isnan(solved).all()


def test_cassini_collinear_landmarks_robot_off_their_line_is_solved() -> None:
    """A line of landmarks is the danger 'circle' of infinite radius: off it the pose is unique."""
    tri = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])
    pose = np.array([5.0, 3.0, 0.2])
    solved, ok = cassini_resection(tri, bearings_to(pose, tri))
    assert ok
    np.testing.assert_allclose(solved, pose, atol=1e-9)


def test_cassini_robot_between_two_landmarks_is_solved() -> None:
    """Two landmarks seen 180 deg apart (robot on their segment) defeat one Cassini pivot, not the solver."""
    tri = np.array([[5.0, 0.0], [-2.5, 4.330127018922193], [-2.5, -4.330127018922193]])
    pose = np.array([*(0.5 * (tri[0] + tri[1])), 1.0])
    solved, ok = cassini_resection(tri, bearings_to(pose, tri))
    assert ok
    np.testing.assert_allclose(solved, pose, atol=1e-9)


def test_cassini_broadcasts_over_leading_axes() -> None:
    tris, poses = well_conditioned_cases(5, 12)
    solved, ok = cassini_resection(tris.reshape(3, 4, 3, 2), bearings_from(poses, tris).reshape(3, 4, 3))
    assert solved.shape == (3, 4, 3) and ok.shape == (3, 4)
    np.testing.assert_allclose(solved.reshape(12, 3)[:, :2], poses[:, :2], atol=1e-9)


def test_cassini_rejected_inconsistent_bearings() -> None:
    """A landmark reported behind the robot (bearing + pi) matches the lines but not the rays."""
    tris, poses = well_conditioned_cases(9, 20)
    b = bearings_from(poses, tris)
    b[:, 0] = wrap_angle(b[:, 0] + math.pi)
    solved, ok = cassini_resection(tris, b)
    assert not ok.any()
    assert np.isnan(solved).all()


@pytest.mark.parametrize(
    ("landmarks_shape", "bearings_shape"), [((3, 2), (2,)), ((4, 2), (4,)), ((2, 3, 2), (3, 3)), ((3, 3), (3,))]
)
def test_cassini_bad_shapes_raise(landmarks_shape: tuple[int, ...], bearings_shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=r"\(\.\.\., 3, 2\)"):
        cassini_resection(np.zeros(landmarks_shape), np.zeros(bearings_shape))


def test_cassini_min_conditioning_must_be_positive() -> None:
    with pytest.raises(ValueError, match="-1.0"):
        cassini_resection(np.zeros((3, 2)), np.zeros(3), min_conditioning=-1.0)


# ----------------------------------------------------------------------------- inscribed arc

L1 = np.array([10.0, 1.5])
L2 = np.array([10.0, 3.5])


@pytest.mark.parametrize(
    "pose",
    [(5.0, 2.5, 0.3), (2.0, 1.0, -2.0), (9.5, 2.5, 1.0), (11.0, 2.0, 3.0), (1.0, 4.9, -0.1), (10.5, 6.0, -1.5)],
)
@pytest.mark.parametrize("n", [36, 360])
def test_arc_contains_true_pose_within_one_spacing(pose: tuple[float, float, float], n: int) -> None:
    true = np.array(pose)
    b1, b2 = bearings_to(true, np.stack([L1, L2]))
    arc = inscribed_arc_poses(L1, L2, b1, b2, n)
    assert arc.shape == (n, 3)
    # Independent arc length: radius D / (2 |sin psi|), the arc spans 2 pi - 2 |psi|.
    psi = abs(wrap_angle(b2 - b1))
    arc_length = np.linalg.norm(L2 - L1) / (2.0 * math.sin(psi)) * (2.0 * math.pi - 2.0 * psi)
    spacing = arc_length / n
    dist = np.linalg.norm(arc[:, :2] - true[:2], axis=1)
    i = int(np.argmin(dist))
    assert dist[i] <= spacing
    heading_bound = 1e-6 + spacing / np.linalg.norm(L1 - true[:2])
    assert abs(wrap_angle(arc[i, 2] - true[2])) <= heading_bound


@pytest.mark.parametrize("bearings", [(0.2, 1.4), (-2.0, 2.5), (3.0, -3.0), (1.0, -0.5)])
def test_arc_candidates_reproduce_both_bearings(bearings: tuple[float, float]) -> None:
    """Every candidate sees both landmarks exactly at the measured bearings: only the correct side of the chord."""
    arc = inscribed_arc_poses(L1, L2, *bearings, 360)
    seen = bearings_to(arc, np.stack([L1, L2]))
    assert np.abs(wrap_angle(seen - np.array(bearings))).max() < 1e-9


def test_arc_is_evenly_spaced_and_excludes_endpoints() -> None:
    arc = inscribed_arc_poses(L1, L2, 0.2, 0.9, 100)
    steps = np.linalg.norm(np.diff(arc[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, steps[0], rtol=1e-9)
    for landmark in (L1, L2):
        assert np.linalg.norm(arc[:, :2] - landmark, axis=1).min() == pytest.approx(steps[0], rel=1e-6)


@pytest.mark.parametrize("bearings", [(0.5, 0.5), (0.5, 0.5 + math.pi), (-1.0, -1.0 - math.pi)])
def test_arc_degenerate_angle_gives_nan(bearings: tuple[float, float]) -> None:
    arc = inscribed_arc_poses(L1, L2, *bearings, 10)
    assert arc.shape == (10, 3)
    assert np.isnan(arc).all()


def test_arc_needs_positive_count() -> None:
    with pytest.raises(ValueError, match="0"):
        inscribed_arc_poses(L1, L2, 0.1, 0.5, 0)


# ----------------------------------------------------------------------------- all triples

FIELD = np.array([[0.0, 0.0], [0.0, 2.0], [0.0, 3.0], [0.0, 5.0], [10.0, 0.0], [10.0, 2.0], [10.0, 3.0], [10.0, 5.0]])


def test_all_triples_exact() -> None:
    pose = np.array([3.0, 1.5, 2.0])
    ids = np.array([0, 2, 5, 7, 4])
    res = resect_all_triples(FIELD, ids, bearings_to(pose, FIELD[ids]))
    assert res.triples.shape == (10, 3) and res.poses.shape == (10, 3)
    assert res.valid and res.ok.sum() >= 8
    np.testing.assert_allclose(res.pose, pose, atol=1e-9)
    assert set(map(int, res.triples.ravel())) == set(map(int, ids))


def test_all_triples_rejects_one_false_detection() -> None:
    pose = np.array([6.0, 3.5, -0.7])
    ids = np.arange(8)
    b = bearings_to(pose, FIELD)
    b[3] = wrap_angle(b[3] + 0.6)  # a false detection
    res = resect_all_triples(FIELD, ids, b)
    assert res.valid
    np.testing.assert_allclose(res.pose[:2], pose[:2], atol=1e-9)
    assert abs(wrap_angle(res.pose[2] - pose[2])) < 1e-9
    bad = (res.triples == 3).any(axis=1)
    assert not (res.inliers & bad).any()


@pytest.mark.parametrize("count", [0, 1, 2])
def test_all_triples_needs_three(count: int) -> None:
    res = resect_all_triples(FIELD, np.arange(count), np.zeros(count))
    assert not res.valid and res.poses.shape == (0, 3) and np.isnan(res.pose).all()


def test_all_triples_without_agreement_gives_no_pose() -> None:
    """Solutions that disagree (one corrupted bearing of four): no inlier near the median, no pose."""
    lm = np.array([[0.0, 0.0], [6.0, 0.0], [3.0, 5.0], [3.0, -5.0]])
    pose = np.array([3.0, 1.5, 0.0])
    b = bearings_to(pose, lm)
    b[3] = wrap_angle(b[3] + 0.3)
    res = resect_all_triples(lm, np.arange(4), b, inlier_radius_m=0.05)
    assert res.ok.sum() >= 2
    assert np.ptp(res.poses[res.ok, :2], axis=0).max() > 0.5  # the corrupted triples disagree with the clean one
    assert not res.valid and not res.inliers.any()
    assert np.isnan(res.pose).all()
    loose = resect_all_triples(lm, np.arange(4), b, inlier_radius_m=10.0)
    assert loose.valid and (loose.inliers == loose.ok).all()


# ----------------------------------------------------------------------------- localizer


def make_map() -> LandmarkMap:
    return LandmarkMap(FIELD, tuple(f"L{i + 1}" for i in range(8)), (0.0, 0.0, 10.0, 5.0))


def make(params: ResectionParams | None = None) -> ResectionLocalizer:
    loc = ResectionLocalizer(make_map(), params or ResectionParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    return loc


def measure(pose: np.ndarray, ids: list[int]) -> BearingMeasurement:
    idx = np.array(ids, dtype=np.int64)
    return BearingMeasurement(idx, bearings_to(pose, FIELD[idx]))


def test_localizer_is_a_localizer() -> None:
    assert isinstance(make(), Localizer)


@pytest.mark.parametrize("ids", [[], [1], [2, 6]])
def test_localizer_no_output_below_three(ids: list[int]) -> None:
    loc = make()
    loc.update(measure(np.array([4.0, 2.0, 0.5]), ids))
    assert not loc.estimate.valid


@pytest.mark.parametrize("ids", [[0, 5, 7], [1, 2, 4, 6], list(range(8))])
def test_localizer_exact_with_three_or_more(ids: list[int]) -> None:
    pose = np.array([4.0, 2.0, 0.5])
    loc = make()
    loc.update(measure(pose, ids))
    est = loc.estimate
    assert est.valid
    np.testing.assert_allclose(est.as_array(), pose, atol=1e-9)
    assert np.isfinite(est.covariance).all()
    assert np.linalg.eigvalsh(est.covariance).min() > 0.0  # floored
    assert loc.overlay().poses.shape[1] == 3


def test_localizer_predict_drops_the_fix() -> None:
    loc = make()
    loc.update(measure(np.array([4.0, 2.0, 0.5]), [0, 5, 7]))
    loc.predict(OdometryDelta(0.1, 0.0, 0.0))
    assert not loc.estimate.valid


def test_localizer_reset_clears() -> None:
    loc = make()
    loc.update(measure(np.array([4.0, 2.0, 0.5]), [0, 5, 7]))
    loc.reset(np.random.default_rng(1))
    assert not loc.estimate.valid
    assert loc.overlay().poses.shape == (0, 3)


@pytest.mark.parametrize(("bad", "text"), [(float("nan"), "nan"), (4.0, "4.0")])
def test_localizer_bad_bearing_raises_with_value(bad: float, text: str) -> None:
    loc = make()
    with pytest.raises(MeasurementError, match=text):
        loc.update(BearingMeasurement(np.array([0, 5, 7]), np.array([0.1, bad, 0.2])))


def test_localizer_needs_reset() -> None:
    loc = ResectionLocalizer(make_map(), ResectionParams(), dt_s=DT)
    with pytest.raises(RuntimeError, match="reset"):
        loc.update(BearingMeasurement.empty())


@pytest.mark.parametrize("dt_s", [0.0, -1.0, float("nan")])
def test_localizer_bad_dt_raises(dt_s: float) -> None:
    with pytest.raises(ValueError, match="dt_s"):
        ResectionLocalizer(make_map(), ResectionParams(), dt_s=dt_s)


@pytest.mark.parametrize(
    ("field", "value"), [("min_conditioning", 0.0), ("inlier_radius_m", -0.5), ("bearing_std_rad", float("nan"))]
)
def test_params_out_of_range_raise(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"{field}.*{value!r}"):
        ResectionParams(**{field: value})


def test_yaml_defaults_match_dataclass() -> None:
    assert from_mapping(ResectionParams, load_yaml(CONFIG), str(CONFIG)) == ResectionParams()
    assert ResectionParams().min_conditioning == DEFAULT_MIN_CONDITIONING
