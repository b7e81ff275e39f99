"""``far_landmark_pf`` and its map of scenes: far emphasis, association, the likelihood, the map's
file and world, bad input, and tracking the campus route."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gymnasium as gym
import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import envs  # noqa: F401  (registers crowdloc/*)
from agents.experiments.scene_maps import MappingDrive, build_scene_map, default_map_path
from agents.policies import make_policy
from core.schema import ConfigError
from envs.stereo.vision import edge_type
from localizers.base import (
    EDGE_CHANNELS,
    EDGE_LEVELS,
    EDGE_POLARITIES,
    EDGE_TYPES,
    EdgeMeasurement,
    LandmarkMap,
    MeasurementError,
    OdometryDelta,
    PoseEstimate,
)
from localizers.far_landmark_pf import SELECTIONS, FarLandmarkParams, FarLandmarkPF, order_detections
from localizers.far_landmark_pf.kernels import (
    detection_distances,
    detection_log_likelihood,
    particle_log_weights,
    position_votes,
    top_cells,
)
from localizers.far_landmark_pf.scene_map import SceneMap, geometry_fingerprint
from tests.pinning import PINNED_DIR, assert_same_numbers

CAMPUS = "crowdloc/StereoCampus-v0"
SQUARE = LandmarkMap(np.zeros((0, 2)), (), (0.0, 0.0, 50.0, 50.0), np.array([[0.0, 0.0, 50.0, 0.0]]), {})


def toy_map(landmarks: list[tuple[int, float, float]]) -> SceneMap:
    """One scene at the origin facing +x holding ``(type, x, y)`` landmarks."""
    types = np.array([t for t, _, _ in landmarks], dtype=np.int64)
    xy = np.array([(x, y) for _, x, y in landmarks], dtype=np.float64).reshape(-1, 2)
    return SceneMap(np.zeros((1, 3)), np.array([0, len(landmarks)]), types, xy, "toy", geometry_fingerprint(SQUARE))


def grouped(types: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    order = np.argsort(types, kind="stable")
    return np.ascontiguousarray(xy[order]), np.searchsorted(types[order], np.arange(31)).astype(np.int64)


# ------------------------------------------------------------------ the likelihood and the association


def test_the_inverse_range_and_bearing_likelihood_matches_hand_values() -> None:
    lm_xy, starts = grouped(np.array([4]), np.array([[10.0, 0.0]]))
    # from (0, 0) facing +x the landmark is at r* = 10 (1/r* = 0.1), theta* = 0
    ll = detection_log_likelihood(0.0, 0.0, 0.0, 4, 0.1 + 0.01, 0.02, lm_xy, starts, 1 / 0.005, 1 / 0.01)
    assert ll == pytest.approx(-0.5 * ((0.01 / 0.005) ** 2 + (0.02 / 0.01) ** 2))
    # facing +y the landmark is 90 deg to the right: theta* = -pi/2
    ll = detection_log_likelihood(0.0, 0.0, math.pi / 2, 4, 0.1, -math.pi / 2, lm_xy, starts, 1.0, 1.0)
    assert ll == pytest.approx(0.0, abs=1e-12)
    # no landmark of that type: no likelihood
    assert detection_log_likelihood(0.0, 0.0, 0.0, 5, 0.1, 0.0, lm_xy, starts, 1.0, 1.0) == -math.inf


def test_association_takes_the_same_type_landmark_of_largest_likelihood() -> None:
    types = np.array([7, 7, 8])
    xy = np.array([[10.0, 0.0], [10.0, 1.0], [10.0, 0.1]])  # a type-8 landmark nearer the detection does not count
    lm_xy, starts = grouped(types, xy)
    bearing = math.atan2(0.9, 10.0)  # closest to the second type-7 landmark
    ll = detection_log_likelihood(0.0, 0.0, 0.0, 7, 1 / math.hypot(10.0, 0.9), bearing, lm_xy, starts, 1 / 0.005, 1 / 0.01)
    expected = -0.5 * (
        ((1 / math.hypot(10, 0.9) - 1 / math.hypot(10, 1)) / 0.005) ** 2 + ((bearing - math.atan2(1, 10)) / 0.01) ** 2
    )
    assert ll == pytest.approx(expected)


def test_a_detection_beyond_the_gate_is_a_mismatch_and_weighs_nothing() -> None:
    lm_xy, starts = grouped(np.array([2]), np.array([[10.0, 0.0]]))
    particles = np.zeros((3, 1))
    chosen = np.full(1, -1, dtype=np.int64)
    args = (np.array([0]), np.array([0, 1], dtype=np.int64), True, lm_xy, starts, 1 / 0.005, 1 / 0.01, -0.5 * 9.0, 7.0, chosen)
    near = particle_log_weights(particles, np.array([2]), np.array([0.1]), np.array([0.02]), *args)  # 2 sd: matches
    assert near[0] == pytest.approx(7.0 - 0.5 * 4.0) and chosen[0] == 0
    far = particle_log_weights(particles, np.array([2]), np.array([0.1]), np.array([0.05]), *args)  # 5 sd: rejected
    assert far[0] == 0.0 and chosen[0] == -1


# ------------------------------------------------------------------ the kernels' savings change no number


@numba.njit(cache=True)
def reference_particle_log_weights(
    particles: np.ndarray, det_type: np.ndarray, det_inv_r: np.ndarray, det_bearing: np.ndarray, order: np.ndarray,
    starts: np.ndarray, first_only: bool, lm_xy: np.ndarray, type_start: np.ndarray, inv_sigma_r: float,
    inv_sigma_t: float, log_gate: float, log_norm: float, chosen: np.ndarray,
) -> np.ndarray:  # fmt: skip
    """:func:`particle_log_weights` as first written: every same-type landmark's likelihood for every detection weighed."""
    n = particles.shape[1]
    out = np.zeros(n)
    for i in range(n):
        total = 0.0
        for g in range(starts.shape[0] - 1):
            if i == n - 1:
                chosen[g] = -1
            for q in range(starts[g], starts[g + 1]):
                k = order[q]
                best = -math.inf
                for m in range(type_start[det_type[k]], type_start[det_type[k] + 1]):
                    dx = lm_xy[m, 0] - particles[0, i]
                    dy = lm_xy[m, 1] - particles[1, i]
                    r = math.sqrt(dx * dx + dy * dy)
                    if r <= 0.0:
                        continue
                    e_r = (det_inv_r[k] - 1.0 / r) * inv_sigma_r
                    e_t = det_bearing[k] - (math.atan2(dy, dx) - particles[2, i])
                    e_t = ((e_t + math.pi) % (2.0 * math.pi) - math.pi) * inv_sigma_t
                    best = max(best, -0.5 * (e_r * e_r + e_t * e_t))
                if best >= log_gate:
                    total += best + log_norm
                    if i == n - 1:
                        chosen[g] = k
                    if first_only:
                        break
        out[i] = total
    return out


@numba.njit(cache=True)
def reference_position_votes(
    cx: float, cy: float, headings: np.ndarray, half_cells: int, cell_m: float, det_type: np.ndarray,
    det_inv_r: np.ndarray, det_bearing: np.ndarray, order: np.ndarray, lm_xy: np.ndarray, type_start: np.ndarray,
    inv_r_gate: float,
) -> np.ndarray:  # fmt: skip
    """:func:`position_votes` as first written: every ray walked over its whole reach."""
    n = 2 * half_cells + 1
    ox = cx - (half_cells + 0.5) * cell_m
    oy = cy - (half_cells + 0.5) * cell_m
    reach = (half_cells + 1) * cell_m * 1.5
    votes = np.zeros((headings.shape[0], n, n), dtype=np.int64)
    stamp = np.empty((n, n), dtype=np.int64)
    for h in range(headings.shape[0]):
        stamp[:, :] = -1
        for q in range(order.shape[0]):
            k = order[q]
            inv = det_inv_r[k]
            rho_hi = 1.0 / (inv - inv_r_gate) if inv > inv_r_gate else 1e9
            ux = math.cos(det_bearing[k] + headings[h])
            uy = math.sin(det_bearing[k] + headings[h])
            for m in range(type_start[det_type[k]], type_start[det_type[k] + 1]):
                lx = lm_xy[m, 0]
                ly = lm_xy[m, 1]
                d = math.hypot(lx - cx, ly - cy)
                rho = max(1.0 / (inv + inv_r_gate), d - reach)
                while rho <= min(rho_hi, d + reach):
                    i = int(math.floor((lx - rho * ux - ox) / cell_m))
                    j = int(math.floor((ly - rho * uy - oy) / cell_m))
                    if 0 <= i < n and 0 <= j < n and stamp[i, j] != q:
                        stamp[i, j] = q
                        votes[h, i, j] += 1
                    rho += 0.5 * cell_m
    return votes


@numba.njit(cache=True)
def reference_detection_distances(
    px: float, py: float, pth: float, det_type: np.ndarray, det_inv_r: np.ndarray, det_bearing: np.ndarray,
    order: np.ndarray, lm_xy: np.ndarray, type_start: np.ndarray, inv_sigma_r: float, inv_sigma_t: float, cover_rad: float,
) -> np.ndarray:  # fmt: skip
    """:func:`detection_distances` as first written: every landmark's bearing computed again for every detection."""
    out = np.empty(order.shape[0])
    for q in range(order.shape[0]):
        k = order[q]
        covered = False
        for m in range(lm_xy.shape[0]):
            e = det_bearing[k] - (math.atan2(lm_xy[m, 1] - py, lm_xy[m, 0] - px) - pth)
            covered = covered or abs((e + math.pi) % (2.0 * math.pi) - math.pi) <= cover_rad
        ll = detection_log_likelihood(px, py, pth, det_type[k], det_inv_r[k], det_bearing[k], lm_xy, type_start,
                                      inv_sigma_r, inv_sigma_t)  # fmt: skip
        out[q] = (math.sqrt(-2.0 * ll) if ll > -math.inf else math.inf) if covered else math.nan
    return out


def random_frame(rng: np.random.Generator, landmarks: int, detections: int) -> tuple[np.ndarray, ...]:
    """Landmarks of random types in a 60 m square, their type-grouped ``(xy, type_start)``, the pose
    ``(30, 30, heading)`` and detections of them seen from it (noise of the filter's size), half of them
    clutter: ``(lm_xy, type_start, pose, types, inverse ranges, bearings)``."""
    types = rng.integers(0, 30, landmarks)
    lm_xy, type_start = grouped(types, rng.uniform(0.0, 60.0, (landmarks, 2)))
    lm_types = np.repeat(np.arange(30), np.diff(type_start))
    pose = np.array([30.0, 30.0, rng.uniform(-math.pi, math.pi)])
    seen = rng.integers(0, landmarks, detections)
    rel = lm_xy[seen] - pose[:2]
    inv_r = 1.0 / np.hypot(rel[:, 0], rel[:, 1]) + rng.normal(0.0, 0.005, detections)
    bearings = np.arctan2(rel[:, 1], rel[:, 0]) - pose[2] + rng.normal(0.0, 0.01, detections)
    clutter = rng.random(detections) < 0.5
    inv_r[clutter] = rng.uniform(0.01, 0.3, clutter.sum())
    bearings[clutter] = rng.uniform(-math.pi, math.pi, clutter.sum())
    bearings = (bearings + math.pi) % (2.0 * math.pi) - math.pi
    return lm_xy, type_start, pose, lm_types[seen], np.abs(inv_r) + 1e-3, bearings


@pytest.mark.parametrize("seed", range(6))
def test_particle_log_weights_is_bit_identical_to_the_plain_kernel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    lm_xy, type_start, pose, types, inv_r, bearings = random_frame(rng, 150, 60)
    particles = pose[:, None] + rng.normal(0.0, 1.0, (3, 300)) * np.array([[0.5], [0.5], [0.05]])
    if seed % 2:  # headings a few turns off (no span of headings to prune by)
        particles[2, :50] += 2.0 * math.pi * rng.integers(-3, 4, 50)
    particles[:2, 50] = lm_xy[0]  # a particle on a landmark (r = 0: that landmark is skipped)
    gate = [3.0, 3.0, 100.0][seed % 3]  # 100 sd: a gate wider than the bearing cone the kernel skips by
    for selection in SELECTIONS:
        order, starts = order_detections(inv_r, bearings, math.radians(30.0), 3.0, selection)
        args = (particles, types, inv_r, bearings, order, starts, selection != "all", lm_xy, type_start, 1 / 0.005,
                1 / 0.01, -0.5 * gate**2, 7.0)  # fmt: skip
        chosen, expected_chosen = np.full(starts.size - 1, -9), np.full(starts.size - 1, -9)
        got, expected = particle_log_weights(*args, chosen), reference_particle_log_weights(*args, expected_chosen)
        assert (expected != 0.0).sum() > 100  # detections match: the comparison is about numbers, not zeros
        np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))  # bit for bit
        np.testing.assert_array_equal(chosen, expected_chosen)


@pytest.mark.parametrize("seed", range(4))
def test_detection_distances_are_those_of_the_plain_kernel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    lm_xy, type_start, pose, types, inv_r, bearings = random_frame(rng, 100, 60)
    order, _ = order_detections(inv_r, bearings, math.radians(30.0), 3.0, "all")
    for heading in (pose[2], pose[2] + 4.0 * math.pi):
        args = (pose[0], pose[1], heading, types, inv_r, bearings, order, lm_xy, type_start, 1 / 0.005, 1 / 0.01, 0.02)
        got, expected = detection_distances(*args), reference_detection_distances(*args)
        assert np.isfinite(expected).sum() >= 5 and np.isnan(expected).any()  # near ones, far ones, uncovered ones
        np.testing.assert_array_equal(got.view(np.int64), expected.view(np.int64))


def test_top_cells_are_the_stable_sorts_last_cells() -> None:
    """The search refines its three best cells: the largest votes, a tie to the later cell, as the stable sort read
    backwards had them (vote grids are full of ties)."""
    rng = np.random.default_rng(0)
    for _ in range(300):
        shape = tuple(int(n) for n in rng.integers(1, 7, size=rng.integers(1, 4)))
        votes = rng.integers(0, rng.integers(1, 5), size=shape)
        for k in (0, 1, 3, 500):
            expected = np.argsort(votes, axis=None, kind="stable")[::-1][:k]
            np.testing.assert_array_equal(top_cells(votes, k), expected)


@pytest.mark.parametrize("seed", range(4))
def test_position_votes_are_those_of_the_plain_kernel(seed: int) -> None:
    rng = np.random.default_rng(seed)
    lm_xy, type_start, pose, types, inv_r, bearings = random_frame(rng, 200, 40)
    bearings[0] = -pose[2]  # a ray along the x axis at the middle heading (a sine of exactly 0)
    headings = pose[2] + np.arange(-5, 6) * 0.02
    order, _ = order_detections(inv_r, bearings, math.radians(30.0), 3.0, "all")
    args = (pose[0] + 1.3, pose[1] - 0.7, headings, 12, 0.5, types, inv_r, bearings, order, lm_xy, type_start, 0.015)
    votes = position_votes(*args)
    assert votes.max() >= 5  # the true pose's cell gathers its detections' votes
    np.testing.assert_array_equal(votes, reference_position_votes(*args))


# ------------------------------------------------------------------ far emphasis


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.floats(0.5, 80.0), st.floats(-math.pi + 1e-6, math.pi - 1e-6), st.booleans()), min_size=1, max_size=25)
)
def test_far_emphasis_uses_per_sector_the_farthest_matching_detection(
    detections: list[tuple[float, float, bool]],
) -> None:
    # each detection is of its own type; those flagged match (a map landmark of that type where it is seen)
    n = len(detections)
    ranges = np.array([r for r, _, _ in detections])
    bearings = np.array([b for _, b, _ in detections])
    matches = np.array([m for _, _, m in detections])
    types = np.arange(n) % 30
    lm = [(t, r * math.cos(b), r * math.sin(b)) for t, (r, b, m) in zip(types, detections) if m]
    lm_types = np.array([t for t, _, _ in lm], dtype=np.int64)
    lm_xy, starts = grouped(lm_types, np.array([(x, y) for _, x, y in lm]).reshape(-1, 2))
    if n > 30:
        return
    sector = math.radians(30.0)
    order, groups = order_detections(1.0 / ranges, bearings, sector, 3.0, "farthest")
    chosen = np.full(groups.size - 1, -1, dtype=np.int64)
    particle_log_weights(np.zeros((3, 1)), types, 1.0 / ranges, bearings, order, groups, True, lm_xy, starts, 1 / 0.005,
                         1 / 0.01, -4.5, 0.0, chosen)  # fmt: skip
    used = set(chosen[chosen >= 0].tolist())
    # expected: per sector, among the detections at 3 m or more that match, the farthest
    expected = set()
    for s in set(np.floor((bearings + math.pi) / sector).astype(int)):
        cand = [i for i in range(n) if math.floor((bearings[i] + math.pi) / sector) == s and ranges[i] >= 3.0 and matches[i]]
        if cand:
            expected.add(max(cand, key=lambda i: ranges[i]))
    assert used == expected


def test_order_detections_drops_near_ones_and_orders_sectors() -> None:
    inv = 1.0 / np.array([2.0, 10.0, 30.0, 5.0, 40.0])
    bearings = np.array([0.1, 0.1, 0.2, -0.9, -0.9])
    order, starts = order_detections(inv, bearings, math.radians(30.0), 3.0, "farthest")
    groups = [order[starts[g] : starts[g + 1]].tolist() for g in range(starts.size - 1)]
    assert groups == [[4, 3], [2, 1]]  # the 2 m one is gone; within a sector farthest first
    order, starts = order_detections(inv, bearings, math.radians(30.0), 3.0, "nearest")
    assert [order[starts[g] : starts[g + 1]].tolist() for g in range(starts.size - 1)] == [[3, 4], [1, 2]]
    order, starts = order_detections(inv, bearings, math.radians(30.0), 3.0, "all")
    assert sorted(order.tolist()) == [1, 2, 3, 4] and starts.tolist() == [0, 4]


# ------------------------------------------------------------------ the map


def test_a_scene_map_round_trips_through_its_file(tmp_path: Path) -> None:
    scenes = SceneMap(np.array([[1.0, 2.0, 0.5], [3.0, 2.0, 0.0]]), np.array([0, 2, 3]), np.array([4, 9, 4]),
                      np.array([[5.0, 1.0], [8.0, -2.0], [4.0, 0.0]]), "toy", "abc", {"focal_px": 554.26}, {"pose": "truth"})  # fmt: skip
    back = SceneMap.load(scenes.save(tmp_path / "m.npz"))
    for name in ("poses", "first", "types", "relative_xy"):
        np.testing.assert_array_equal(getattr(back, name), getattr(scenes, name))
    assert (back.world, back.fingerprint, dict(back.camera), dict(back.source)) == (
        "toy",
        "abc",
        {"focal_px": 554.26},
        {"pose": "truth"},
    )
    # a scene's landmarks in the world frame: its pose composed with them
    np.testing.assert_allclose(
        back.world_xy(0)[0], [1.0 + 5 * math.cos(0.5) - math.sin(0.5), 2.0 + 5 * math.sin(0.5) + math.cos(0.5)]
    )


def test_a_map_of_another_world_or_camera_is_refused_naming_the_mismatch(tmp_path: Path) -> None:
    scenes = toy_map([(1, 10.0, 0.0)])
    other = LandmarkMap(np.zeros((0, 2)), (), (0.0, 0.0, 60.0, 50.0), SQUARE.walls_m, {})
    with pytest.raises(ConfigError, match="another geometry"):
        scenes.check_world(other)
    with pytest.raises(ConfigError, match="made in world 'toy', not 'campus'"):
        scenes.check_world(SQUARE, "campus")
    with pytest.raises(ConfigError, match="focal_px: map None, camera 600"):
        scenes.check_world(SQUARE, "toy", {"focal_px": 600})
    with pytest.raises(ConfigError, match="does not exist"):
        SceneMap.load(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a map")
    with pytest.raises(ConfigError, match="is not a scene map"):
        SceneMap.load(tmp_path / "junk.npz")


def test_scene_pose_covariances_round_trip_default_to_exact_and_refuse_bad_values(tmp_path: Path) -> None:
    covs = np.stack([np.diag([0.01, 0.02, 0.001]), np.diag([0.03, 0.01, 0.002])])
    scenes = SceneMap(
        np.zeros((2, 3)), np.array([0, 1, 2]), np.array([1, 2]), np.ones((2, 2)), "toy", "abc", pose_covariances=covs
    )
    np.testing.assert_array_equal(SceneMap.load(scenes.save(tmp_path / "m.npz")).pose_covariances, covs)
    np.testing.assert_allclose(scenes.pose_covariance(np.array([0, 1])), covs.mean(axis=0))
    np.testing.assert_array_equal(scenes.pose_covariance(np.zeros(0, dtype=np.int64)), np.zeros((3, 3)))
    np.testing.assert_array_equal(toy_map([(1, 10.0, 0.0)]).pose_covariances, np.zeros((1, 3, 3)))  # none given: exact poses
    with pytest.raises(ValueError, match=r"must be \(2, 3, 3\), one per scene, got \(1, 3, 3\)"):
        SceneMap(
            np.zeros((2, 3)), np.array([0, 1, 2]), np.array([1, 2]), np.ones((2, 2)), "toy", "abc", pose_covariances=covs[:1]
        )
    with pytest.raises(ValueError, match="variances >= 0"):
        SceneMap(np.zeros((2, 3)), np.array([0, 1, 2]), np.array([1, 2]), np.ones((2, 2)), "toy", "abc", pose_covariances=-covs)


def test_a_map_of_the_first_format_is_refused_naming_both_formats(tmp_path: Path) -> None:
    path = toy_map([(1, 10.0, 0.0)]).save(tmp_path / "m.npz")
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files if k not in ("pose_covariances", "meta")}
        meta = str(data["meta"]).replace("crowdloc-scene-map-v2", "crowdloc-scene-map-v1")
    np.savez(tmp_path / "old.npz", **arrays, meta=np.array(meta))
    with pytest.raises(
        ConfigError, match="not a scene map of format 'crowdloc-scene-map-v2' .found 'crowdloc-scene-map-v1'.: make it"
    ):
        SceneMap.load(tmp_path / "old.npz")


def test_the_reported_covariance_adds_the_matched_scenes_pose_covariance_and_nothing_else() -> None:
    cov = np.diag([0.04, 0.09, 0.0025])
    scenes = SceneMap(np.zeros((1, 3)), np.array([0, 2]), np.array([3, 5]), np.array([[20.0, 4.0], [30.0, -6.0]]), "toy",
                      geometry_fingerprint(SQUARE), pose_covariances=cov[None])  # fmt: skip
    seen = EdgeMeasurement(np.array([3, 5]), 1.0 / np.hypot([20.0, 30.0], [4.0, -6.0]), np.arctan2([4.0, -6.0], [20.0, 30.0]))
    out = []
    for map_error in (True, False):
        pf = FarLandmarkPF(SQUARE, FarLandmarkParams(map_error=map_error), dt_s=0.1, scenes=scenes)
        pf.reset(np.random.default_rng(3), PoseEstimate(0.0, 0.0, 0.0))
        before = pf.estimate.covariance  # no update yet: no scene matched, nothing added
        pf.predict(OdometryDelta(0.05, 0.0, 0.01))
        pf.update(seen)
        out.append((before, pf.estimate))
    (before_on, on), (before_off, off) = out
    np.testing.assert_array_equal(before_on, before_off)
    assert on.as_array().tolist() == off.as_array().tolist()  # the estimate itself is the same
    np.testing.assert_allclose(on.covariance, off.covariance + cov, rtol=1e-12)


def test_the_localizer_refuses_a_map_of_another_world(tmp_path: Path) -> None:
    path = toy_map([(1, 10.0, 0.0)]).save(tmp_path / "toy.npz")
    with pytest.raises(ConfigError, match="made in world 'toy', not 'stereo_campus'"):
        gym.make(CAMPUS, localizer="far_landmark_pf", localizer_params={"scene_map": str(path)})


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize(("inverse_range", "words"), [(math.nan, "got nan"), (0.0, "got 0.0"), (-0.2, "got -0.2")])
def test_detections_with_a_bad_range_are_refused_naming_the_value(inverse_range: float, words: str) -> None:
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(), dt_s=0.1, scenes=toy_map([(1, 10.0, 0.0)]))
    pf.reset(np.random.default_rng(0), PoseEstimate(0.0, 0.0, 0.0))
    with pytest.raises(MeasurementError, match=words):
        pf.update(EdgeMeasurement(np.array([1]), np.array([inverse_range]), np.array([0.0])))


@pytest.mark.parametrize("measurement", [None, "edges", np.zeros(3)])
def test_a_measurement_that_is_no_edge_measurement_is_refused_naming_its_type(measurement: object) -> None:
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(), dt_s=0.1, scenes=toy_map([(1, 10.0, 0.0)]))
    pf.reset(np.random.default_rng(0), PoseEstimate(0.0, 0.0, 0.0))
    with pytest.raises(MeasurementError, match=f"far_landmark_pf: expected an EdgeMeasurement, got {type(measurement).__name__}"):
        pf.update(measurement)  # type: ignore[arg-type]


def test_edge_types_run_from_0_to_29_and_others_are_refused_naming_them() -> None:
    assert (EDGE_CHANNELS, EDGE_LEVELS, EDGE_POLARITIES, EDGE_TYPES) == (3, 5, 2, 30)  # the paper's 3 x 5 x 2
    assert EDGE_TYPES == max(edge_type(c, lv, f) for c in range(3) for lv in range(5) for f in (False, True)) + 1
    ok = EdgeMeasurement(np.array([0, 29]), np.array([0.1, 0.1]), np.array([0.0, 0.1])).validated()
    assert ok.types.tolist() == [0, 29]
    with pytest.raises(MeasurementError, match=r"edge types must be integers in 0\.\.29, got \[0, 30\]"):
        EdgeMeasurement(np.array([0, 30]), np.array([0.1, 0.1]), np.array([0.0, 0.1])).validated()


def test_without_a_start_pose_or_a_map_it_says_what_it_needs() -> None:
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(), dt_s=0.1, scenes=toy_map([]))
    with pytest.raises(ValueError, match="needs a valid initial pose"):
        pf.reset(np.random.default_rng(0), None)
    with pytest.raises(ConfigError, match="needs a scene map"):
        FarLandmarkPF(SQUARE, FarLandmarkParams(), dt_s=0.1)


@pytest.mark.parametrize(
    ("key", "value"),
    [("sigma_inv_r", 0.0), ("match_gate", -1.0), ("selection", "middle"), ("scenes", 0), ("lost_gate", math.nan),
     ("lost_after_s", 0.0), ("search_radius_m", -1.0), ("search_cell_m", 0.0), ("search_radius_m", 1e4),
     ("frame_gap_s", -0.01), ("frame_gap_s", math.inf), ("baseline_m", 0.0)],
)  # fmt: skip
def test_bad_parameters_are_refused_naming_them(key: str, value: object) -> None:
    with pytest.raises(ConfigError, match=key):
        FarLandmarkParams(**{key: value})  # type: ignore[arg-type]


# ------------------------------------------------------------------ lost and found

#: the toy campus: one scene at (5, 25) facing +x, 80 landmarks of random types 10-40 m ahead of it
_RNG = np.random.default_rng(27)
_TYPES = _RNG.integers(0, EDGE_TYPES, 80)
_RELATIVE = np.column_stack([_RNG.uniform(10.0, 40.0, 80), _RNG.uniform(-15.0, 15.0, 80)])
TOY_CAMPUS = SceneMap(np.array([[5.0, 25.0, 0.0]]), np.array([0, 80]), _TYPES, _RELATIVE, "toy", geometry_fingerprint(SQUARE))


def seen_from(pose: tuple[float, float, float], rng: np.random.Generator) -> EdgeMeasurement:
    """The toy campus's landmarks within 60 deg of the heading, as detected from ``pose`` (with the filter's noise)."""
    xy = TOY_CAMPUS.world_xy(0)
    r = np.hypot(xy[:, 0] - pose[0], xy[:, 1] - pose[1])
    b = np.arctan2(xy[:, 1] - pose[1], xy[:, 0] - pose[0]) - pose[2]
    keep = np.abs(b) < math.radians(60.0)
    inv = 1.0 / r[keep] + rng.normal(0.0, 0.002, keep.sum())
    return EdgeMeasurement(_TYPES[keep], inv, b[keep] + rng.normal(0.0, 0.004, keep.sum()))


def kidnapped_run(frames: int = 30, **params: object) -> tuple[list[PoseEstimate], FarLandmarkPF]:
    """Ten frames standing at (5, 25) facing +x, then ``frames`` frames from 3 m ahead and 1 m to the left,
    the odometry none the wiser (zero increments): a kidnap."""
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(**params), dt_s=0.1, scenes=TOY_CAMPUS)  # type: ignore[arg-type]
    rng = np.random.default_rng(5)
    pf.reset(rng, PoseEstimate(5.0, 25.0, 0.0))
    out = []
    for n in range(10 + frames):
        pf.predict(OdometryDelta(0.0, 0.0, 0.0))
        pf.update(seen_from((5.0, 25.0, 0.0) if n < 10 else (8.0, 26.0, 0.0), rng))
        out.append(pf.estimate)
    return out, pf


def test_a_kidnapped_filter_says_it_is_lost_within_lost_after_s() -> None:
    estimates, pf = kidnapped_run(search_radius_m=0.0)  # no re-localization: it can only say so
    before, after = estimates[:10], estimates[10:]
    assert all(e.valid and math.hypot(e.x_m - 5.0, e.y_m - 25.0) < 0.2 for e in before)  # standing where it thinks
    assert all(e.valid for e in after[:4])  # the first frames after the jump: not yet contradicted for 0.5 s
    assert not any(e.valid for e in after[4:20])  # then no pose claimed (for as long as no frame agrees with it)
    assert pf.searches == 0


def test_a_kidnapped_filter_relocalizes_from_the_scene_map() -> None:
    estimates, pf = kidnapped_run()
    after = estimates[10:]
    assert sum(e.valid and math.hypot(e.x_m - 8.0, e.y_m - 26.0) > 1.0 for e in after) <= 5  # at most 0.5 s confidently wrong
    found = [e.valid and math.hypot(e.x_m - 8.0, e.y_m - 26.0) < 0.3 for e in after]
    assert all(found[4:]) and not pf.lost  # re-localized at the first search, 0.5 s after the jump, and stays there
    assert pf.searches == 1


def test_a_filter_that_stays_put_never_searches() -> None:
    estimates, pf = kidnapped_run(frames=0)
    pf.reset(np.random.default_rng(1), PoseEstimate(5.0, 25.0, 0.0))
    rng = np.random.default_rng(2)
    for _ in range(100):
        pf.predict(OdometryDelta(0.0, 0.0, 0.0))
        pf.update(seen_from((5.0, 25.0, 0.0), rng))
        assert pf.estimate.valid
    assert pf.searches == 0 and not pf.lost


def turning_run(frames: int = 30, rate_rps: float = 0.4, gap_s: float = 0.03, **params: object) -> list[PoseEstimate]:
    """Ten frames standing at (5, 25) facing +x, then ``frames`` frames turning in place at ``rate_rps`` (the odometry
    reports the turn exactly) on free-running cameras whose outer pair takes its frames ``gap_s`` apart: every
    inverse range is off by ``rate gap / (2 b)`` (the outer pair's disparity shift), the pose always right."""
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(**params), dt_s=0.1, scenes=TOY_CAMPUS)  # type: ignore[arg-type]
    rng = np.random.default_rng(5)
    pf.reset(rng, PoseEstimate(5.0, 25.0, 0.0))
    out, heading = [], 0.0
    for n in range(10 + frames):
        turn = 0.0 if n < 10 else rate_rps * 0.1
        heading += turn
        pf.predict(OdometryDelta(0.0, 0.0, turn))
        seen = seen_from((5.0, 25.0, heading), rng)
        shift = (turn / 0.1) * gap_s / (2.0 * 0.19)
        pf.update(EdgeMeasurement(seen.types, seen.inverse_range_m + shift, seen.bearings_rad))
        out.append(pf.estimate)
    return out


def test_a_turn_on_free_running_cameras_is_no_contradiction_when_the_filter_knows_their_frame_gap() -> None:
    """A turn shifts the disparity between free-running webcams' frames (here 6 sds of the inverse range);
    the lost test counts that shift in its sds when the rig's frame gap is known (``gym.make`` passes the camera's),
    and a filter that assumes synchronised cameras (``frame_gap_s`` 0) calls the same right pose lost."""
    knowing = turning_run(frame_gap_s=1.0 / 30.0, baseline_m=0.19)
    assert all(e.valid for e in knowing)
    assert all(abs(e.theta_rad - 0.04 * max(0, n - 9)) < 0.02 for n, e in enumerate(knowing))  # and it stays right
    assuming_synchronised = turning_run(frame_gap_s=0.0)
    assert not any(e.valid for e in assuming_synchronised[15:])  # lost after 0.5 s of contradiction, and stays so


def test_a_search_that_finds_the_position_but_another_heading_redraws_the_set() -> None:
    """The search confirms the estimate only when its best pose agrees in heading too: a robot turned by 0.2 rad where
    it stands (unseen by odometry) is found with its new heading, not confirmed with the old one and lost again."""
    pf = FarLandmarkPF(SQUARE, FarLandmarkParams(), dt_s=0.1, scenes=TOY_CAMPUS)
    rng = np.random.default_rng(5)
    pf.reset(rng, PoseEstimate(5.0, 25.0, 0.0))
    estimates = []
    for n in range(40):
        pf.predict(OdometryDelta(0.0, 0.0, 0.0))
        pf.update(seen_from((5.0, 25.0, 0.0 if n < 10 else 0.2), rng))
        estimates.append(pf.estimate)
    assert pf.searches >= 1
    assert all(e.valid and abs(e.theta_rad - 0.2) < 0.02 and math.hypot(e.x_m - 5.0, e.y_m - 25.0) < 0.3 for e in estimates[20:])


# ------------------------------------------------------------------ on the campus


@pytest.fixture(scope="module")
def campus_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Run 1 without people, the poses from the LIDAR reference, with synchronised cameras of equal gains
    (:data:`SYNCED`: these tests check the filter itself; the webcams' effect is the reproduction's to measure)."""
    return build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0), env_kwargs=SYNCED).save(
        tmp_path_factory.mktemp("maps") / "campus.npz"
    )


#: the campus's cameras synchronised and of equal gains (the campus's default: the paper's free-running webcams)
SYNCED = {"stereo": {"synchronised": True, "exposure_range": (1.0, 1.0), "white_balance_k": (0.0, 0.0)}}


def drive(scene_map: Path, seed: int, steps: int = 2000, **params: object) -> tuple[np.ndarray, np.ndarray, bool]:
    env = gym.make(CAMPUS, crowd_size=0, localizer="far_landmark_pf", localizer_params={"scene_map": str(scene_map), **params},
                   **SYNCED)  # fmt: skip
    obs, info = env.reset(seed=seed)
    policy = make_policy("route_follower", env, seed=0)
    est, truth = [], []
    done = False
    for _ in range(steps):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        e = info["estimate"]
        est.append(e.as_array() if e.valid else np.full(3, np.nan))
        truth.append(info["true_pose"])
        if terminated or truncated:
            done = terminated
            break
    env.close()
    return np.array(est), np.array(truth), done


def test_it_tracks_the_crowd_free_route_from_a_known_start(campus_map: Path) -> None:
    est, truth, done = drive(campus_map, seed=1)
    assert done  # it drove the route on its own estimate and stopped at the goal
    err = np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1])
    assert np.isfinite(err).all()
    assert np.median(err) < 0.25 and err.max() < 0.7, (np.median(err), err.max())


def test_on_the_papers_free_running_webcams_it_drives_the_crowd_free_route_round_its_corner() -> None:
    """With the default map (its drive slows in the corner and records no scene mid-turn) and the camera's frame gap
    known to the lost test, the filter keeps its pose through the corner on free-running webcams; without those two it
    declares itself lost in the turn at 57 m and route_follower stands there for the rest of the episode."""
    env = gym.make(CAMPUS, crowd_size=0, localizer="far_landmark_pf")
    obs, info = env.reset(seed=1)
    policy = make_policy("route_follower", env, seed=0)
    valid, err, terminated = [], [], False
    for _ in range(2000):
        action, _ = policy.predict(obs)
        obs, _, terminated, truncated, info = env.step(action)
        e, truth = info["estimate"], info["true_pose"]
        valid.append(e.valid)
        err.append(math.hypot(e.x_m - truth[0], e.y_m - truth[1]))
        if terminated or truncated:
            break
    env.close()
    assert terminated and policy.progress_m > 95.0  # the goal, at the end of the route
    assert np.mean(valid) > 0.95 and np.median(err) < 0.3, (np.mean(valid), np.median(err))


def test_the_map_drive_takes_the_corner_slowly_on_webcams_and_at_speed_on_synchronised_cameras() -> None:
    """On free-running webcams the mapping drive turns no faster than a 1 px shift between the cameras'
    frames allows (0.054 rad/s on the campus) and records no scene mid-turn, so the corner's views are mapped a few
    degrees apart and true; synchronised cameras drive the corner at speed and record it about 18 deg per scene."""

    def corner_steps_deg(scene_map: SceneMap) -> np.ndarray:
        headings = np.degrees(scene_map.poses[:, 2]) % 360.0
        steps = np.abs((np.diff(headings) + 180.0) % 360.0 - 180.0)
        return steps[(headings[:-1] > 95.0) & (headings[:-1] < 175.0)]  # leaving the first straight (180 deg) for the second (90)

    webcams = corner_steps_deg(build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0)))
    synchronised = corner_steps_deg(build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0), env_kwargs=SYNCED))
    assert webcams.size >= 15 and webcams.max() < 8.0, webcams
    assert synchronised.size <= 6 and synchronised.max() > 10.0, synchronised


@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, True, "1"])
def test_a_bad_map_drive_shift_is_refused_naming_it(value: object) -> None:
    with pytest.raises(ConfigError, match=r"max_shift_px must be a number > 0.*got"):
        MappingDrive(max_shift_px=value)  # type: ignore[arg-type]


def test_same_seed_same_estimates(campus_map: Path) -> None:
    a, _, _ = drive(campus_map, seed=2, steps=150)
    b, _, _ = drive(campus_map, seed=2, steps=150)
    np.testing.assert_array_equal(a, b)


def test_a_map_from_the_reference_keeps_its_pose_covariances_and_one_from_the_truth_none() -> None:
    reference = build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0, max_steps=60))
    variances = np.diagonal(reference.pose_covariances, axis1=1, axis2=2)
    assert reference.scene_count >= 2 and (variances > 0).all()  # the LIDAR reference's own uncertainty
    truth = build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0, max_steps=60, pose="truth"))
    np.testing.assert_array_equal(truth.pose_covariances, np.zeros((truth.scene_count, 3, 3)))


def test_a_seeded_crowded_campus_run_keeps_the_estimates_pinned_before_the_kernels_savings() -> None:
    """200 steps of random actions in a crowd of 100 on the default map: the estimates and the searches (lost, the
    filter searches the scene map), pinned; :func:`particle_log_weights` and :func:`position_votes` skip work and must
    give them bit for bit (a speed-up changes no number: never re-record for one). The pin records the default map's
    drive taking the corner slowly and recording no scene mid-turn, the lost test knowing the webcams' frame gap and
    a search confirming the estimate only in its heading too: 5 searches, a pose on 92 % of the steps."""
    pinned = json.loads((PINNED_DIR / "far_landmark_pf_campus.json").read_text())
    env = gym.make(CAMPUS, crowd_size=100, localizer="far_landmark_pf")
    env.reset(seed=3)
    estimates = []
    for action in np.random.default_rng(3).uniform(-1.0, 1.0, size=(200, 2)).astype(np.float32):
        _, _, terminated, truncated, info = env.step(action)
        e = info["estimate"]
        estimates.append([e.x_m, e.y_m, e.theta_rad, e.valid])
    run = {"searches": env.get_wrapper_attr("localizer").searches, "estimates": estimates}
    env.close()
    assert pinned["searches"] >= 3  # the re-localization ran: position_votes and the refinement are covered
    assert_same_numbers(pinned, run, "far_landmark_pf_campus")


def test_gym_make_builds_and_caches_the_default_map() -> None:
    env = gym.make(CAMPUS, crowd_size=0, localizer="far_landmark_pf")
    path = default_map_path(env.unwrapped)
    assert path.is_file()  # made on first use, in the session's cache (tests/localizers/conftest.py)
    made = path.stat().st_mtime_ns
    env.close()
    again = gym.make(CAMPUS, crowd_size=5, localizer="far_landmark_pf")  # another crowd, the same world: the same map
    assert default_map_path(again.unwrapped) == path and path.stat().st_mtime_ns == made
    obs, _ = again.reset(seed=0)
    assert obs["estimate_valid"][0] == 1.0
    again.close()


def test_gym_make_gives_the_filter_its_cameras_frame_gap_and_baseline_unless_given() -> None:
    def rig(**kwargs: object) -> tuple[float, float]:
        env = gym.make(CAMPUS, crowd_size=0, localizer="far_landmark_pf", **kwargs)  # type: ignore[arg-type]
        params = env.get_wrapper_attr("localizer")._params
        env.close()
        return params.frame_gap_s, params.baseline_m

    assert rig() == (pytest.approx(1.0 / 30.0), 0.19)  # the campus's free-running webcams
    assert rig(**SYNCED)[0] == 0.0
    assert rig(localizer_params={"frame_gap_s": 0.01, "baseline_m": 0.2}) == (0.01, 0.2)
