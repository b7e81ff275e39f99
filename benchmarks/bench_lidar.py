"""LIDAR localization speed: mcl_lidar at the paper's size and far-point extraction.

- ``mcl_lidar``: 1000 particles x 1081 beams (beam_stride 1), beam model and likelihood
  field, one predict + update per scan (updates forced every scan, not every 0.5 m), in a
  7 m x 7 m room with 16 people along the walls; synthetic scans from ``cast_rays``.
- Far-point extraction of 100,000 accumulated points into 1440 bins (the paper: 60 ms).
The ray-cast table is built into a temporary cache first (its build time is reported).
"""

from __future__ import annotations

import math
import os
import tempfile
import time

import numpy as np

from benchmarks.common import Result
from core.geometry import between
from core.motion import sample_odometry
from core.raycast import cast_rays
from localizers.base import LandmarkMap, OdometryDelta, PoseEstimate, ScanMeasurement

ROOM = np.array([[0, 0, 7, 0], [7, 0, 7, 7], [7, 7, 0, 7], [0, 7, 0, 0]], float)
ANGLES = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)


def _scans(poses: np.ndarray, rng: np.random.Generator) -> list[ScanMeasurement]:
    people = np.stack([np.r_[np.full(8, 0.5), np.full(8, 6.5)], np.r_[np.linspace(1, 6, 8), np.linspace(1, 6, 8)]], 1)
    out = []
    for pose in poses:
        r = cast_rays(pose[:2], ANGLES + pose[2], 30.0, ROOM[:, :2].copy(), ROOM[:, 2:].copy(), people, np.full(16, 0.18))
        r = np.where(r < 30.0, np.clip(r + 0.01 * rng.standard_normal(r.size), 0.0, 30.0), r)
        out.append(ScanMeasurement(r, ANGLES, 30.0))
    return out


def run_all(quick: bool = False) -> list[Result]:
    with tempfile.TemporaryDirectory() as cache:
        os.environ["CROWDLOC_CACHE"] = cache
        return _run(quick)


def _run(quick: bool) -> list[Result]:
    from localizers.mcl_lidar import LidarMCL, LidarMCLParams
    from localizers.scan_filter import far_points

    rng = np.random.default_rng(0)
    steps = 120 if quick else 400
    t = np.linspace(0, 4 * math.pi, steps)
    poses = np.stack([3.5 + 1.5 * np.cos(t), 3.5 + 1.5 * np.sin(t), t + math.pi / 2], 1)
    scans = _scans(poses, rng)
    odometry = [
        OdometryDelta(*sample_odometry(rng, between(poses[k - 1], poses[k]), [0.01, 0.005, 0.005, 0.005]))
        for k in range(1, steps)
    ]
    landmarks = LandmarkMap(np.zeros((0, 2)), (), (0, 0, 7, 7), ROOM)
    results = []
    for model in ("beam", "likelihood_field"):
        params = LidarMCLParams(model=model, update_min_travel_m=0.0, update_min_rotation_rad=0.0)
        start = time.perf_counter()
        loc = LidarMCL(landmarks, params, dt_s=0.025)
        loc.reset(np.random.default_rng(1), PoseEstimate(*poses[0], np.diag([1e-3, 1e-3, 1e-3])))
        loc.update(scans[0])
        build_s = time.perf_counter() - start
        times = []
        for k in range(1, steps):
            s0 = time.perf_counter()
            loc.predict(odometry[k - 1])
            loc.update(scans[k])
            times.append(time.perf_counter() - s0)
        ms = np.asarray(times[10:]) * 1e3
        target = model == "beam"
        results.append(
            Result(
                "lidar",
                f"mcl_lidar {model}: 1000 particles x 1081 beams, predict + update",
                float(np.median(ms)),
                "ms",
                f"p99 {np.percentile(ms, 99):.1f}",
                "<= 10 ms" if target else "",
                (float(np.median(ms)) <= 10.0) if target else None,
            )
        )
        if model == "beam":
            results.append(
                Result("lidar", "ray-cast table build (7 m room, 0.05 m x 720 directions) + first update", build_s, "s", "")
            )
    x = rng.uniform(-6, 6, 100_000)
    y = rng.uniform(-6, 6, 100_000)
    scratch = (np.empty(100_000), np.empty(100_000), np.empty(100_000))
    far_points(x, y, (0.1, 0.2), 0.3, 1440, scratch=scratch)
    times = []
    for _ in range(50 if quick else 300):
        s0 = time.perf_counter()
        far_points(x, y, (0.1, 0.2), 0.3, 1440, scratch=scratch)
        times.append(time.perf_counter() - s0)
    ms = np.asarray(times) * 1e3
    results.append(
        Result(
            "lidar",
            "far-point extraction, 100,000 points, 1440 bins",
            float(np.median(ms)),
            "ms",
            f"p99 {np.percentile(ms, 99):.2f}",
            "<= 3 ms",
            float(np.median(ms)) <= 3.0,
        )
    )
    return results
