"""Tests of localizers.candidate_sets: the candidate-set method of the two-landmark bearings
paper against exact geometry (generation, propagation, eq. (1)-(2)), its set life cycle
(pruning, determination, abort, multiple sets, budget), the fusion rule and the localizer
contract."""

from __future__ import annotations

import dataclasses
import math
import re
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

from core.geometry import bearings_to, between, compose, wrap_angle
from core.schema import ConfigError, from_mapping, load_yaml
from localizers.base import BearingMeasurement, LandmarkMap, Localizer, MeasurementError, OdometryDelta
from localizers.candidate_sets import CandidateSetLocalizer, CandidateSetParams, fuse_poses, generate_candidates

CONFIG = Path(__file__).resolve().parents[2] / "configs" / "localizers" / "candidate_sets.yaml"
DT = 1.0 / 30.0

# Experiment 1 of the paper: a 10 m x 5 m field, the proposed method uses two goal posts only.
GOAL_POSTS = LandmarkMap(np.array([[10.0, 1.5], [10.0, 3.5]]), ("L6", "L7"), (0.0, 0.0, 10.0, 5.0))
# Experiment 2 layout: goal posts and corner poles of a 5 m x 5 m field.
FIELD8 = LandmarkMap(
    np.array([[0.0, 0.0], [0.0, 2.0], [0.0, 3.0], [0.0, 5.0], [5.0, 0.0], [5.0, 2.0], [5.0, 3.0], [5.0, 5.0]]),
    tuple(f"L{i + 1}" for i in range(8)),
    (0.0, 0.0, 5.0, 5.0),
)


def drive(waypoints: list[tuple[float, float]], speed_m_s: float = 0.5, turn_rad_s: float = 1.5) -> np.ndarray:
    """``(T, 3)`` poses along a polygon: straight lines, rotations in place at the vertices."""
    p = np.array([*waypoints[0], math.atan2(waypoints[1][1] - waypoints[0][1], waypoints[1][0] - waypoints[0][0])])
    poses = [p]
    for wx, wy in waypoints[1:]:
        heading = math.atan2(wy - p[1], wx - p[0])
        while abs(wrap_angle(heading - p[2])) > 1e-12:
            step = float(np.clip(wrap_angle(heading - p[2]), -turn_rad_s * DT, turn_rad_s * DT))
            p = np.array([p[0], p[1], wrap_angle(p[2] + step)])
            poses.append(p)
        dist = math.hypot(wx - p[0], wy - p[1])
        k = math.ceil(dist / (speed_m_s * DT))
        for _ in range(k):
            p = compose(p, [dist / k, 0.0, 0.0])
            poses.append(p)
    return np.array(poses)


def measure(landmarks: LandmarkMap, pose: np.ndarray, ids: list[int] | np.ndarray) -> BearingMeasurement:
    idx = np.asarray(ids, dtype=np.int64)
    return BearingMeasurement(idx, bearings_to(pose, landmarks.positions_xy_m[idx]))


def make(landmarks: LandmarkMap = GOAL_POSTS, params: CandidateSetParams | None = None) -> CandidateSetLocalizer:
    loc = CandidateSetLocalizer(landmarks, params or CandidateSetParams(), dt_s=DT)
    loc.reset(np.random.default_rng(0))
    return loc


def run_exact(loc: CandidateSetLocalizer, landmarks: LandmarkMap, poses: np.ndarray, ids: list[int]) -> list:
    """Exact odometry and bearings along ``poses``; returns the estimate after each update."""
    out = []
    for t in range(len(poses)):
        if t:
            loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
        loc.update(measure(landmarks, poses[t], ids))
        out.append(loc.estimate)
    return out


def test_is_a_localizer() -> None:
    assert isinstance(make(), Localizer)


# ----------------------------------------------------------------------------- full runs


@pytest.mark.parametrize(
    "waypoints",
    [
        [(1.0, 1.0), (7.0, 1.0), (7.0, 4.0), (2.0, 4.0), (1.0, 1.0)],
        [(2.0, 4.0), (2.0, 1.0), (6.0, 1.0), (6.0, 4.0), (2.0, 4.0)],
        [(5.0, 2.5), (8.0, 1.0), (8.0, 4.0), (3.0, 3.0), (5.0, 2.5)],
    ],
)
def test_noise_free_two_goal_posts_determines_pose(waypoints: list[tuple[float, float]]) -> None:
    poses = drive(waypoints)
    estimates = run_exact(make(), GOAL_POSTS, poses, [0, 1])
    valid = [t for t, e in enumerate(estimates) if e.valid]
    assert valid, "never determined"
    first = valid[0]
    assert valid == list(range(first, len(poses)))  # valid from the first fix on
    errors = np.array([estimates[t].as_array() - poses[t] for t in valid])
    assert np.hypot(errors[:, 0], errors[:, 1]).max() < 0.05
    assert np.degrees(np.abs(wrap_angle(errors[:, 2]))).max() < 1.0


def test_noise_free_eight_landmarks_fixes_at_once() -> None:
    poses = drive([(1.0, 1.0), (4.0, 1.5), (4.0, 4.0)], speed_m_s=0.9)
    estimates = run_exact(make(FIELD8), FIELD8, poses, list(range(8)))
    assert not estimates[0].valid and estimates[1].valid  # generated, then determined at the next frame
    errors = np.array([e.as_array() - p for e, p in zip(estimates[1:], poses[1:])])
    assert np.abs(errors[:, :2]).max() < 1e-6
    assert np.abs(wrap_angle(errors[:, 2])).max() < 1e-6


@pytest.mark.parametrize("seed", [0, 1])
def test_noisy_random_occlusion_run_is_accurate(seed: int) -> None:
    """Exp. 2 style: a random subset of 8 landmarks per frame, 0.5 deg bearing noise, 1 % odometry noise."""
    rng = np.random.default_rng(seed)
    poses = drive([(1.0, 1.0), (4.0, 1.5), (4.0, 4.0), (1.5, 3.5), (2.5, 2.0)], speed_m_s=0.9)
    loc = make(FIELD8)
    errors = []
    for t in range(len(poses)):
        if t:
            d = between(poses[t - 1], poses[t])
            loc.predict(OdometryDelta(*(d * (1.0 + rng.normal(0.0, 0.01, 3)))))
        ids = np.flatnonzero(rng.random(8) < 0.3)
        b = bearings_to(poses[t], FIELD8.positions_xy_m[ids]) + rng.normal(0.0, math.radians(0.5), ids.size)
        loc.update(BearingMeasurement(ids, wrap_angle(b)))
        if loc.estimate.valid:
            errors.append(loc.estimate.as_array() - poses[t])
    e = np.array(errors)
    assert len(e) > 0.9 * len(poses)
    assert np.hypot(e[:, 0], e[:, 1]).mean() < 0.05
    assert np.degrees(np.abs(wrap_angle(e[:, 2]))).mean() < 0.5


# ----------------------------------------------------------------------------- the steps


def test_generation_two_landmarks_gives_n_candidates_on_the_arc() -> None:
    pose = np.array([4.0, 2.0, 0.3])
    loc = make()
    loc.update(measure(GOAL_POSTS, pose, [0, 1]))
    ov = loc.overlay()
    assert loc.set_sizes.tolist() == [360]
    assert ov.poses.shape == (360, 3)
    np.testing.assert_array_equal(loc.candidate_errors, 0.0)
    seen = bearings_to(ov.poses, GOAL_POSTS.positions_xy_m)
    np.testing.assert_allclose(wrap_angle(seen - bearings_to(pose, GOAL_POSTS.positions_xy_m)), 0.0, atol=1e-9)
    x, y = ov.poses[:, 0], ov.poses[:, 1]
    assert ((x >= -0.1) & (x <= 10.1) & (y >= -0.1) & (y <= 5.1)).all()  # bounds + margin


def test_generation_three_or_more_uses_the_ok_triples() -> None:
    pose = np.array([2.0, 1.5, -2.5])
    ids = [0, 3, 5, 6]
    poses = generate_candidates(
        FIELD8, np.array(ids), bearings_to(pose, FIELD8.positions_xy_m[ids]),
        candidates_per_arc=360, min_conditioning=0.1, bounds_margin_m=0.1,
    )  # fmt: skip
    assert 1 <= poses.shape[0] <= len(list(combinations(ids, 3)))
    np.testing.assert_allclose(poses[:, :2] - pose[:2], 0.0, atol=1e-9)
    np.testing.assert_allclose(wrap_angle(poses[:, 2] - pose[2]), 0.0, atol=1e-9)


def test_propagation_composes_each_candidate_in_its_own_frame() -> None:
    loc = make()
    loc.update(measure(GOAL_POSTS, np.array([4.0, 2.0, 0.3]), [0, 1]))
    expected = loc.overlay().poses
    rng = np.random.default_rng(3)
    for _ in range(50):
        d = rng.normal([0.02, 0.0, 0.0], [0.02, 0.01, 0.2])
        loc.predict(OdometryDelta(*d))
        expected = compose(expected, d)
    got = loc.overlay().poses
    np.testing.assert_allclose(got[:, :2], expected[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angle(got[:, 2] - expected[:, 2]), 0.0, atol=1e-9)


@pytest.mark.parametrize("n_seen", [1, 2, 3, 5, 8])
def test_evaluation_matches_equation_1(n_seen: int) -> None:
    params = CandidateSetParams(prune_error_rad=1e6, abort_error_rad=1e6, determine_below=1)
    loc = make(FIELD8, params)
    loc.update(measure(FIELD8, np.array([1.0, 4.0, 0.3]), [1, 6]))
    loc.predict(OdometryDelta(0.3, -0.1, 0.4))
    poses = loc.overlay().poses
    rng = np.random.default_rng(n_seen)
    ids = rng.permutation(8)[:n_seen]
    b = rng.uniform(-math.pi, math.pi, n_seen)
    before = loc.candidate_errors
    loc.update(BearingMeasurement(ids, b))
    increment = loc.candidate_errors - before
    # Independent per-candidate loop over eq. (1).
    predicted = bearings_to(poses, FIELD8.positions_xy_m[ids])
    expected = np.zeros(len(poses))
    for k in range(n_seen):
        expected += np.abs(wrap_angle(b[k] - predicted[:, k]))
    for j, k in combinations(range(n_seen), 2):
        psi = wrap_angle(b[k] - b[j])
        psi_pred = wrap_angle(predicted[:, k] - predicted[:, j])
        expected += np.abs(wrap_angle(psi - psi_pred))
    np.testing.assert_allclose(increment, expected, rtol=0.0, atol=1e-4)  # float32 evaluation


def test_pruning_deletes_candidates_over_threshold() -> None:
    params = CandidateSetParams(prune_error_rad=0.5, abort_error_rad=0.5, determine_below=1)
    poses = drive([(1.0, 1.0), (7.0, 1.0)])
    loc = make(GOAL_POSTS, params)
    sizes = []
    for t in range(120):
        if t:
            loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
        loc.update(measure(GOAL_POSTS, poses[t], [0, 1]))
        sizes.append(int(loc.set_sizes.sum()))
        assert (loc.candidate_errors <= 0.5).all()
    assert sizes[0] == 360 and 0 < sizes[-1] < 360
    assert all(a >= b for a, b in zip(sizes, sizes[1:]))


def test_abort_discards_set_and_regenerates_at_the_next_frame() -> None:
    loc = make(GOAL_POSTS, CandidateSetParams(prune_error_rad=3.0, abort_error_rad=2.0))
    pose = np.array([4.0, 2.0, 0.3])
    loc.update(measure(GOAL_POSTS, pose, [0, 1]))
    assert loc.set_sizes.size == 1
    # Bearings no candidate can explain: every error jumps by 4 + |wrap(-4)| = 6.28 rad.
    b = bearings_to(pose, GOAL_POSTS.positions_xy_m) + np.array([2.0, -2.0])
    loc.update(BearingMeasurement(np.array([0, 1]), wrap_angle(b)))
    assert loc.set_sizes.size == 0  # discarded, and not regenerated from the bearings that failed it
    loc.update(measure(GOAL_POSTS, pose, [0]))  # one landmark: no generation
    assert loc.set_sizes.size == 0
    loc.update(measure(GOAL_POSTS, pose, [0, 1]))
    assert loc.set_sizes.tolist() == [360]


def test_abort_by_least_error_threshold() -> None:
    """A set whose best candidate exceeds the abort threshold goes, although none is over the prune one."""
    params = CandidateSetParams(prune_error_rad=100.0, abort_error_rad=0.2, determine_below=1)
    loc = make(GOAL_POSTS, params)
    pose = np.array([4.0, 2.0, 0.3])
    loc.update(measure(GOAL_POSTS, pose, [0, 1]))
    b = bearings_to(pose, GOAL_POSTS.positions_xy_m) + np.array([0.15, -0.15])
    loc.update(BearingMeasurement(np.array([0, 1]), b))
    assert loc.set_sizes.size == 0


@pytest.mark.parametrize(("ids", "landmarks"), [([0, 1], GOAL_POSTS), ([0, 3, 6], FIELD8)])
def test_multiple_sets_up_to_k(ids: list[int], landmarks: LandmarkMap) -> None:
    loc = make(landmarks, CandidateSetParams(max_sets=3))
    poses = drive([(1.0, 1.0), (7.0, 1.0), (7.0, 4.0), (2.0, 4.0), (1.0, 1.0), (7.0, 1.0), (7.0, 4.0)])
    if landmarks is FIELD8:
        poses = drive([(1.0, 1.0), (4.0, 1.0), (4.0, 4.0), (1.0, 4.0)])
    counts, determined = [], []
    for t in range(len(poses)):
        if t:
            loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
        loc.update(measure(landmarks, poses[t], ids))
        counts.append(loc.set_sizes.size)
        determined.append(int(loc.sets_determined.sum()))
    assert max(counts) == 3
    # Set B appears at the frame where A first determines, C where B does (paper sec. 3).
    t_b, t_c = counts.index(2), counts.index(3)
    assert determined[t_b] == 1 and determined[t_b - 1] == 0
    assert determined[t_c] == 2 and determined[t_c - 1] == 1
    assert loc.estimate.valid


def test_compute_budget_stops_new_sets() -> None:
    params = CandidateSetParams(max_live_candidates=400, determine_below=360)
    loc = make(GOAL_POSTS, params)
    poses = drive([(1.0, 1.0), (7.0, 1.0)])
    for t in range(60):
        if t:
            loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
        loc.update(measure(GOAL_POSTS, poses[t], [0, 1]))
        assert loc.set_sizes.sum() <= 400
    assert loc.sets_determined.tolist() == [True]  # determined, but the next set would not fit


def test_coasting_after_all_determined_sets_are_discarded() -> None:
    loc = make(FIELD8)
    pose = np.array([1.0, 2.5, 0.2])
    loc.update(measure(FIELD8, pose, [0, 3, 6]))
    loc.update(measure(FIELD8, pose, [0, 3, 6]))
    before = loc.estimate
    assert before.valid
    b = bearings_to(pose, FIELD8.positions_xy_m[[0, 3, 6]]) + np.array([2.0, -2.0, 2.5])
    loc.update(BearingMeasurement(np.array([0, 3, 6]), wrap_angle(b)))
    assert loc.set_sizes.size == 0
    held = loc.estimate
    assert held.valid
    np.testing.assert_allclose(held.as_array(), before.as_array(), atol=1e-9)
    d = np.array([0.5, 0.1, 0.3])
    loc.predict(OdometryDelta(*d))
    loc.update(BearingMeasurement.empty())
    moved = loc.estimate
    np.testing.assert_allclose(moved.as_array(), compose(before.as_array(), d), atol=1e-9)
    assert moved.position_spread_m > held.position_spread_m


# ----------------------------------------------------------------------------- fusion


def test_fusion_drops_outlier_and_averages_heading_circularly() -> None:
    poses = np.array([[1.0, 1.0, 3.10], [1.1, 1.0, -3.10], [1.0, 1.1, 3.12], [6.0, 4.0, 0.0]])
    pose, kept = fuse_poses(poses, 0.5)
    assert kept.tolist() == [True, True, True, False]
    np.testing.assert_allclose(pose[:2], [31.0 / 30.0, 31.0 / 30.0])
    unwrapped_mean = (3.10 + (2.0 * math.pi - 3.10) + 3.12) / 3.0  # about pi; the naive mean is 1.04
    assert abs(wrap_angle(pose[2] - unwrapped_mean)) < 1e-4
    assert -math.pi <= pose[2] < math.pi


def test_fusion_single_pose_is_returned() -> None:
    pose, kept = fuse_poses(np.array([[2.0, 3.0, 7.0]]), 0.1)
    np.testing.assert_allclose(pose, [2.0, 3.0, wrap_angle(7.0)])
    assert kept.tolist() == [True]


def test_fusion_without_agreement_keeps_the_most_central() -> None:
    poses = np.array([[0.0, 0.0, 0.0], [3.0, 0.0, 0.1], [10.0, 0.0, 0.2]])
    pose, kept = fuse_poses(poses, 0.5)
    assert kept.tolist() == [False, True, False]
    np.testing.assert_allclose(pose, poses[1])


@pytest.mark.parametrize("shape", [(0, 3), (3,), (2, 2)])
def test_fusion_bad_shape_raises(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match=r"\(K, 3\)"):
        fuse_poses(np.zeros(shape), 0.5)


# ----------------------------------------------------------------------------- contract


def test_zero_landmarks_is_legal_and_invalid_before_first_fix() -> None:
    loc = make()
    for _ in range(5):
        loc.predict(OdometryDelta(0.01, 0.0, 0.0))
        loc.update(BearingMeasurement.empty())
        assert not loc.estimate.valid
    loc.update(measure(GOAL_POSTS, np.array([4.0, 2.0, 0.3]), [1]))
    assert not loc.estimate.valid and loc.set_sizes.size == 0
    assert loc.overlay().poses.shape == (0, 3)


def test_reset_mid_episode_clears_state() -> None:
    loc = make(FIELD8)
    pose = np.array([1.0, 2.5, 0.2])
    for _ in range(3):
        loc.update(measure(FIELD8, pose, [0, 3, 6, 7]))
    assert loc.estimate.valid and loc.set_sizes.size > 0
    loc.reset(np.random.default_rng(1))
    assert not loc.estimate.valid
    assert loc.set_sizes.size == 0 and loc.candidate_errors.size == 0
    assert loc.overlay().poses.shape == (0, 3)
    loc.update(measure(FIELD8, pose, [0, 3, 6, 7]))  # starts over: generated, not yet determined
    assert not loc.estimate.valid and loc.set_sizes.size == 1


@pytest.mark.parametrize(("bad", "text"), [(float("nan"), "nan"), (4.0, "4.0")])
def test_bad_bearing_raises_with_value(bad: float, text: str) -> None:
    loc = make()
    with pytest.raises(MeasurementError, match=text):
        loc.update(BearingMeasurement(np.array([0, 1]), np.array([0.1, bad])))


def test_bad_odometry_raises() -> None:
    with pytest.raises(MeasurementError, match="nan"):
        make().predict(OdometryDelta(0.1, float("nan"), 0.0))


def test_needs_reset() -> None:
    loc = CandidateSetLocalizer(GOAL_POSTS, CandidateSetParams(), dt_s=DT)
    with pytest.raises(RuntimeError, match="reset"):
        loc.update(BearingMeasurement.empty())


@pytest.mark.parametrize("dt_s", [0.0, -0.1, float("inf")])
def test_bad_dt_raises(dt_s: float) -> None:
    with pytest.raises(ValueError, match="dt_s"):
        CandidateSetLocalizer(GOAL_POSTS, CandidateSetParams(), dt_s=dt_s)


def test_deterministic() -> None:
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    loc_a, loc_b = make(FIELD8), make(FIELD8)
    loc_a.reset(np.random.default_rng(9))
    loc_b.reset(np.random.default_rng(9))
    poses = drive([(1.0, 1.0), (4.0, 1.5), (4.0, 4.0)], speed_m_s=0.9)
    for t in range(len(poses)):
        ids = np.flatnonzero(rng_a.random(8) < 0.4)
        assert (ids == np.flatnonzero(rng_b.random(8) < 0.4)).all()
        b = wrap_angle(bearings_to(poses[t], FIELD8.positions_xy_m[ids]) + rng_a.normal(0.0, 0.02, ids.size))
        rng_b.normal(0.0, 0.02, ids.size)
        for loc in (loc_a, loc_b):
            if t:
                loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
            loc.update(BearingMeasurement(ids, b))
        ea, eb = loc_a.estimate, loc_b.estimate
        assert ea.valid == eb.valid
        np.testing.assert_array_equal(ea.as_array(), eb.as_array())
        np.testing.assert_array_equal(ea.covariance, eb.covariance)
        np.testing.assert_array_equal(loc_a.overlay().poses, loc_b.overlay().poses)


def test_estimate_covariance_is_floored_and_symmetric() -> None:
    params = CandidateSetParams(position_floor_m=0.07, heading_floor_rad=0.02)
    loc = make(FIELD8, params)
    pose = np.array([1.0, 2.5, 0.2])
    for _ in range(3):
        loc.update(measure(FIELD8, pose, [0, 3, 6, 7]))
    cov = loc.estimate.covariance
    np.testing.assert_allclose(cov, cov.T)
    assert (np.diag(cov) >= np.array([0.07**2, 0.07**2, 0.02**2]) - 1e-15).all()
    assert np.linalg.eigvalsh(cov).min() > 0.0


def test_overlay_weights_follow_errors() -> None:
    loc = make()
    poses = drive([(1.0, 1.0), (7.0, 1.0)])
    for t in range(90):
        if t:
            loc.predict(OdometryDelta(*between(poses[t - 1], poses[t])))
        loc.update(measure(GOAL_POSTS, poses[t], [0, 1]))
    ov = loc.overlay()
    err = loc.candidate_errors
    assert ov.poses.shape == (err.size, 3) and ov.weights.shape == (err.size,)
    assert ((ov.weights >= 0.0) & (ov.weights <= 1.0)).all()
    assert np.argmax(ov.weights) == np.argmin(err)
    assert (np.diff(ov.weights[np.argsort(err)]) <= 0.0).all()


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("candidates_per_arc", 0),
        ("max_sets", 0),
        ("determine_below", -3),
        ("max_live_candidates", 0),
        ("prune_error_rad", 0.0),
        ("abort_error_rad", float("nan")),
        ("fusion_median_m", -1.0),
        ("min_conditioning", 0.0),
        ("bounds_margin_m", -0.1),
        ("position_floor_m", float("inf")),
        ("heading_floor_rad", -1.0),
        ("coast_growth_per_m", -0.5),
    ],
)
def test_params_out_of_range_raise(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"{field}.*{value!r}"):
        CandidateSetParams(**{field: value})


def test_yaml_defaults_match_dataclass_and_paper() -> None:
    params = from_mapping(CandidateSetParams, load_yaml(CONFIG), str(CONFIG))
    assert params == CandidateSetParams()
    assert (params.candidates_per_arc, params.max_sets) == (360, 10)  # N and K of the paper


# ----------------------------------------------------------------------------- forgetting (ours)


def _noisy_run(landmarks: LandmarkMap, p_seen: float, params: CandidateSetParams) -> list:
    """A fixed noisy sequence (2 % odometry, 1 deg bearings, a random landmark subset per frame,
    empty frames included); the same summary the pinned numbers below were recorded with."""
    rng = np.random.default_rng(11)
    poses = drive([(1.0, 1.0), (4.0, 1.5), (4.0, 4.0), (1.5, 3.5)], speed_m_s=0.9)
    loc = make(landmarks, params)
    acc, n_valid, errors = np.zeros(3), 0, 0.0
    for t in range(len(poses)):
        if t:
            d = between(poses[t - 1], poses[t])
            loc.predict(OdometryDelta(*(d * (1.0 + rng.normal(0.0, 0.02, 3)))))
        ids = np.flatnonzero(rng.random(landmarks.count) < p_seen)
        b = bearings_to(poses[t], landmarks.positions_xy_m[ids]) + rng.normal(0.0, math.radians(1.0), ids.size)
        loc.update(BearingMeasurement(ids, wrap_angle(b)))
        e = loc.estimate
        if e.valid:
            acc += e.as_array()
            n_valid += 1
        errors += float(loc.candidate_errors.sum())
    return [len(poses), n_valid, *acc.tolist(), errors, loc.set_sizes.tolist()]


# The paper's method: recorded with forgetting off, lost detection and ``max_spread_m`` off (``_CLAIMS_OFF``).
_BEFORE_FORGETTING = {
    "field8": [337, 336, 1082.3808193666277, 867.5631939141178, -17.307550641408568, 224882.17455808865,
               [3, 38, 3, 29, 1, 72, 28, 3, 4, 360]],
    "goal_posts": [337, 300, 2647.089196590066, 850.7133046387544, 179.83823019011479, 327025.8175253914, [216, 241]],
}  # fmt: skip


@pytest.mark.parametrize(("case", "landmarks", "p_seen"), [("field8", FIELD8, 0.3), ("goal_posts", GOAL_POSTS, 0.8)])
def test_forgetting_off_is_the_papers_method_exactly(case: str, landmarks: LandmarkMap, p_seen: float) -> None:
    """The default (no forgetting) and an explicit ``inf`` give the paper's method's recorded numbers, bit for bit
    (with what changes which estimates are claimed switched off: lost detection and ``max_spread_m``)."""
    assert CandidateSetParams().error_time_constant_s == math.inf and not CandidateSetParams().forgets
    assert _noisy_run(landmarks, p_seen, CandidateSetParams(**_CLAIMS_OFF)) == _BEFORE_FORGETTING[case]
    assert (
        _noisy_run(landmarks, p_seen, CandidateSetParams(error_time_constant_s=math.inf, **_CLAIMS_OFF))
        == _BEFORE_FORGETTING[case]
    )
    # and forgetting does change them (the comparison can fail)
    assert _noisy_run(landmarks, p_seen, CandidateSetParams(error_time_constant_s=2.0, **_CLAIMS_OFF)) != _BEFORE_FORGETTING[case]


@pytest.mark.parametrize(("case", "landmarks", "p_seen"), [("field8", FIELD8, 0.3), ("goal_posts", GOAL_POSTS, 0.8)])
def test_the_defaults_keep_the_papers_sets(case: str, landmarks: LandmarkMap, p_seen: float) -> None:
    """Lost detection and ``max_spread_m`` (ours, on by default) change what is claimed, not the
    sets: the accumulated Errors and set sizes stay the paper's. On the goal posts the paper's
    method coasts on a pose the bearings contradict; the defaults stop claiming it."""
    default = _noisy_run(landmarks, p_seen, CandidateSetParams())
    paper = _BEFORE_FORGETTING[case]
    assert default[5:] == paper[5:]
    assert default[1] <= paper[1]


#: the parts of lost detection (ours) that change which estimates are claimed, off
_CLAIMS_OFF = {"lost_after_s": math.inf, "max_spread_m": math.inf}


def test_forgetting_is_an_exponential_decay_per_elapsed_frame() -> None:
    """Error <- exp(-elapsed / tau) Error + eq. (1), elapsed counting the frames without bearings too."""
    tau = 0.5
    params = CandidateSetParams(prune_error_rad=1e6, abort_error_rad=1e6, determine_below=1, error_time_constant_s=tau)
    loc, paper = make(GOAL_POSTS, params), make(GOAL_POSTS, dataclasses.replace(params, error_time_constant_s=math.inf))
    rng = np.random.default_rng(4)
    pose = np.array([4.0, 2.0, 0.3])
    for loc_ in (loc, paper):
        loc_.update(measure(GOAL_POSTS, pose, [0, 1]))
    for frames in (1, 1, 3, 1, 2):
        b = wrap_angle(bearings_to(pose, GOAL_POSTS.positions_xy_m) + rng.normal(0.0, 0.05, 2))
        before, before_paper = loc.candidate_errors, paper.candidate_errors
        for loc_ in (loc, paper):
            for _ in range(frames - 1):
                loc_.update(BearingMeasurement(np.zeros(0, dtype=np.int64), np.zeros(0)))  # nothing seen
            loc_.update(BearingMeasurement(np.array([0, 1]), b))
        increment = paper.candidate_errors - before_paper  # eq. (1) of this frame
        expected = math.exp(-frames * DT / tau) * before + increment
        np.testing.assert_allclose(loc.candidate_errors, expected, rtol=1e-12, atol=1e-12)
        if before.any():  # (the first frame's Errors start from 0)
            assert (loc.candidate_errors < paper.candidate_errors).all()


@pytest.mark.parametrize("tau", [0.5, 1.0])
def test_forgetting_bounds_a_correct_candidates_error_on_a_long_static_run(tau: float) -> None:
    """Standing still before the goal posts for 60 s with 1 deg noise (every arc candidate explains
    the bearings equally well): without forgetting the least Error grows linearly and the shipped
    thresholds abort every set after a few seconds; with ``tau`` it settles at ``mean eq. (1)
    error per frame / (1 - exp(-dt / tau))`` and the first set lives on."""
    sigma = math.radians(1.0)
    pose = np.array([4.0, 2.0, 0.3])
    frames = round(60.0 / DT)
    abort = CandidateSetParams().abort_error_rad
    runs = {}
    for key, p in (("paper", CandidateSetParams()), ("ours", CandidateSetParams(error_time_constant_s=tau))):
        rng = np.random.default_rng(8)
        loc = make(GOAL_POSTS, p)
        least, sets_generated, first = [], 0, None
        for _ in range(frames):
            b = wrap_angle(bearings_to(pose, GOAL_POSTS.positions_xy_m) + rng.normal(0.0, sigma, 2))
            n_before = loc.set_sizes.size
            loc.update(BearingMeasurement(np.array([0, 1]), b))
            sets_generated += loc.set_sizes.size > n_before
            errors = loc.candidate_errors
            least.append(errors.min() if errors.size else math.nan)
            if first is None:
                first = loc.overlay().poses.copy()
        runs[key] = (np.array(least), sets_generated, first, loc.overlay().poses)
    paper_least, paper_sets, _, _ = runs["paper"]
    ours_least, ours_sets, first, last = runs["ours"]
    # the paper's: the Error grows by about the same amount every frame until the set is aborted, again and again.
    # Its first set is ours (same frame, same candidates), so its growth is ours' eq. (1) per frame.
    steps = np.diff(paper_least)
    first_life = int(np.argmax(~(steps > 0)))  # the first abort (NaN: no set until the next frame)
    assert first_life > 30
    per_frame = float(steps[:first_life].mean())
    assert np.nanmax(paper_least) > abort - 3 * per_frame
    assert paper_sets >= 0.5 * frames * per_frame / abort
    # ours: bounded at the steady state for the whole run, below the abort threshold; one set, never aborted
    steady = per_frame / (1.0 - math.exp(-DT / tau))
    assert np.nanmax(ours_least) < min(1.5 * steady, abort)
    assert np.nanmean(ours_least[frames // 2 :]) == pytest.approx(steady, rel=0.15)
    assert ours_sets == 1 and np.array_equal(last, first)


@pytest.mark.parametrize("value", [0.0, -1.0, -math.inf, math.nan])
def test_bad_forgetting_time_constant_is_refused(value: float) -> None:
    with pytest.raises(ConfigError, match=rf"error_time_constant_s must be a number > 0.*got {re.escape(repr(value))}"):
        CandidateSetParams(error_time_constant_s=value)


def test_forgetting_time_constant_from_yaml_names_the_field() -> None:
    with pytest.raises(ConfigError, match=r"error_time_constant_s.*'fast'"):
        from_mapping(CandidateSetParams, {"error_time_constant_s": "fast"}, "test")
    with pytest.raises(ConfigError, match=r"error_time_constant_s must be a number > 0.*got -2\.0"):
        from_mapping(CandidateSetParams, {"error_time_constant_s": -2.0}, "test")
    assert from_mapping(CandidateSetParams, {"error_time_constant_s": 20}, "test").error_time_constant_s == 20.0
