"""Per-update time of every bearing localizer with 8 landmarks in view (RoboCupCrowded-v0's map).

A synthetic drive supplies exact poses; bearings get 1 deg noise and odometry the world's
alpha noise. After a warm-up, each frame's ``predict`` + ``update`` is timed (the figure the
issue targets), and separately the ``estimate`` read that the wrapper does every step.
``candidate_sets`` is first driven into its heaviest state, K = 10 live sets of 360 arc
candidates each (generated from two-landmark frames with pruning switched off), and kept
there while timing with all 8 landmarks.
"""

from __future__ import annotations

import time

import numpy as np

import envs
from benchmarks.common import Result
from core.geometry import bearings_to, between
from core.motion import sample_odometry
from localizers.base import BearingMeasurement, LandmarkMap, OdometryDelta, PoseEstimate
from localizers.registry import LOCALIZERS, make_localizer

TARGETS_MS = {"candidate_sets": 0.3, "mcl_bearing": 0.3}
_BEARING_STD = np.radians(1.0)


def _drive(steps: int, rng: np.random.Generator) -> np.ndarray:
    """``(steps + 1, 3)`` true poses: a smooth loop inside the 5 m x 5 m field."""
    t = np.arange(steps + 1) / 30.0
    x = 2.5 + 1.5 * np.cos(0.3 * t)
    y = 2.5 + 1.2 * np.sin(0.6 * t)
    heading = np.arctan2(np.gradient(y), np.gradient(x))
    return np.stack([x, y, heading], axis=1)


def _frames(landmarks: LandmarkMap, poses: np.ndarray, alphas: np.ndarray, rng: np.random.Generator, ids: np.ndarray):
    for k in range(1, poses.shape[0]):
        odo = sample_odometry(rng, between(poses[k - 1], poses[k]), alphas)
        bearings = bearings_to(poses[k], landmarks.positions_xy_m[ids]) + rng.normal(0.0, _BEARING_STD, ids.size)
        bearings = (bearings + np.pi) % (2 * np.pi) - np.pi
        yield OdometryDelta(*odo), BearingMeasurement(ids, bearings)


def _time_localizer(name: str, landmarks: LandmarkMap, poses: np.ndarray, alphas: np.ndarray, warm: int) -> tuple[list, list]:
    rng = np.random.default_rng(0)
    params: dict[str, object] | None = None
    all_ids = np.arange(landmarks.count)
    if name == "candidate_sets":
        # every set determines at once and nothing is pruned: ten 360-candidate arc sets stay live
        params = {"prune_error_rad": 1e9, "abort_error_rad": 1e9, "determine_below": 100000, "max_live_candidates": 3600}
    loc = make_localizer(name, landmarks, dt_s=1 / 30, params=params)
    prior = PoseEstimate(*poses[0], np.diag([1e-4, 1e-4, 1e-4]), True)
    loc.reset(np.random.default_rng(1), prior if LOCALIZERS[name].needs_prior else None)
    warm_ids = np.array([1, 2]) if name == "candidate_sets" else all_ids
    frames = _frames(landmarks, poses, alphas, rng, warm_ids)
    for _ in range(warm):
        odo, meas = next(frames)
        loc.predict(odo)
        loc.update(meas)
    if name == "candidate_sets":
        sizes = loc.set_sizes  # type: ignore[attr-defined]
        assert len(sizes) == 10 and all(s == 360 for s in sizes), f"benchmark set-up failed: set sizes {sizes}"
    frames = _frames(landmarks, poses[warm:], alphas, rng, all_ids)
    update_s, estimate_s = [], []
    for odo, meas in frames:
        start = time.perf_counter()
        loc.predict(odo)
        loc.update(meas)
        mid = time.perf_counter()
        _ = loc.estimate
        update_s.append(mid - start)
        estimate_s.append(time.perf_counter() - mid)
    return update_s, estimate_s


def run_all(quick: bool = False) -> list[Result]:
    landmarks = envs.LocalizationEnv("robocup_crowded").landmark_map
    alphas = np.asarray(envs.load_world("robocup_crowded").sensors["odometry"].alphas)
    steps = 600 if quick else 3000
    warm = 30
    poses = _drive(steps + warm, np.random.default_rng(0))
    results = []
    for name, spec in LOCALIZERS.items():
        if spec.measurement != "bearings":
            continue
        update_s, estimate_s = _time_localizer(name, landmarks, poses, alphas, warm)
        med = float(np.median(update_s) * 1e3)
        p99 = float(np.percentile(update_s, 99) * 1e3)
        target = TARGETS_MS.get(name)
        label = f"{name}: predict + update" + (" (K = 10 sets x 360 candidates)" if name == "candidate_sets" else "")
        results.append(
            Result(
                "localizers (8 landmarks)",
                label,
                med,
                "ms",
                f"p99 {p99:.3f}",
                f"<= {target} ms" if target else "",
                (med <= target) if target else None,
            )
        )
        est_med = float(np.median(estimate_s) * 1e3)
        results.append(
            Result(
                "localizers (8 landmarks)",
                f"{name}: estimate read",
                est_med,
                "ms",
                f"p99 {np.percentile(estimate_s, 99) * 1e3:.3f}",
            )
        )
    return results
