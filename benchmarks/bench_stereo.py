"""The outdoor campus with its stereo camera (paper D's world): env steps in the fast mode, one
frame of the image mode (three 640 x 480 images rendered, their edges found and matched), the
far-landmark particle filter's update, and the mapping drive that makes its default map."""

from __future__ import annotations

import time

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the ids)
from agents.experiments.scene_maps import MappingDrive, build_scene_map
from benchmarks.common import Result, per_call_ms, rate
from envs.sensors.stereo_camera import StereoCamera
from localizers.base import EdgeMeasurement, PoseEstimate
from localizers.far_landmark_pf import FarLandmarkParams, FarLandmarkPF
from localizers.measurements import edge_measurement, sensor_map

ENV_ID = "crowdloc/StereoCampus-v0"
#: 100 pedestrians and 10 cars: crowd_size 110 with a car share of 10 / 110
BUSY = {"crowd_size": 110, "crowd": {"campus": {"car_share": 10 / 110}}}


def _route_actions(steps: int) -> np.ndarray:
    """Forward at 0.5-1 of full speed with a wandering turn: the robot moves through the campus."""
    rng = np.random.default_rng(0)
    actions = np.empty((steps, 2), dtype=np.float32)
    actions[:, 0] = rng.uniform(0.5, 1.0, steps)
    actions[:, 1] = np.clip(np.cumsum(rng.normal(0.0, 0.1, steps)), -0.6, 0.6)
    return actions


def _env_rate(steps: int, **kwargs: object) -> tuple[float, float, float]:
    env = gym.make(ENV_ID, **kwargs)
    env.reset(seed=0)
    actions = _route_actions(steps)
    env.step(actions[0])  # compile kernels outside the timing

    def run(n: int) -> None:
        for a in actions[:n]:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()

    out = rate(run, steps)
    env.close()
    return out


def _image_frame_ms(calls: int) -> tuple[float, float]:
    """One image-mode observation of the stereo camera at crowd 30 along the route."""
    env = gym.make(ENV_ID, crowd_size=30, stereo={"mode": "image"})
    env.reset(seed=0)
    actions = _route_actions(calls + 40)
    for a in actions[:40]:
        env.step(a)
    camera = env.unwrapped.sensors["stereo"]
    assert isinstance(camera, StereoCamera)
    rng = np.random.default_rng(0)
    state = env.unwrapped.state
    camera.observe(state, rng)  # compile
    return per_call_ms(lambda: camera.observe(state, rng), calls)


def _pf_update_ms(calls: int, selection: str) -> tuple[float, float]:
    """``far_landmark_pf``'s update with 500 particles and 30 detections, against the scenes near
    a pose on the route (a map made on the crowd-free route)."""
    scenes = build_scene_map("stereo_campus", MappingDrive(seed=0, crowd_size=0))
    env = gym.make(ENV_ID, crowd_size=30)
    obs, _ = env.reset(seed=1)
    for _ in range(60):  # 6 s along the sidewalk
        obs, *_ = env.step(np.array([0.8, 0.0], dtype=np.float32))
    base = env.unwrapped
    landmarks = sensor_map(base.landmark_map, base.sensor_metadata["stereo"])
    seen = edge_measurement(obs["stereo"])
    keep = np.argsort(seen.inverse_range_m)[:30]  # 30 detections (the frame has more)
    meas = EdgeMeasurement(seen.types[keep], seen.inverse_range_m[keep], seen.bearings_rad[keep])
    pf = FarLandmarkPF(landmarks, FarLandmarkParams(selection=selection), dt_s=base.config.dt_s, scenes=scenes)
    x, y, th = base.state.robot_pose
    pf.reset(np.random.default_rng(0), PoseEstimate(float(x), float(y), float(th)))
    pf.update(meas)  # compile, and the scenes near the pose
    return per_call_ms(lambda: pf.update(meas), calls)


def run_all(quick: bool = False) -> list[Result]:
    n = 300 if quick else 3000
    results = []
    med, lo, hi = _env_rate(n, **BUSY)
    results.append(
        Result(
            "campus",
            "StereoCampus-v0, fast mode, 100 pedestrians + 10 cars (and 8 parked), odometry + stereo + 720-beam LIDAR",
            med,
            "steps/s",
            f"{lo:,.0f}-{hi:,.0f}",
            ">= 2,000",
            med >= 2_000,
        )  # fmt: skip
    )
    med, lo, hi = _env_rate(n, **BUSY, lidar={"beams": 1})
    results.append(
        Result("campus", "the same, the LIDAR cut to one beam (the cost of the rest)", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}")
    )
    med, lo, hi = _env_rate(n)
    results.append(Result("campus", "StereoCampus-v0, default crowd (30)", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}"))
    med, p99 = _image_frame_ms(20 if quick else 100)
    results.append(
        Result(
            "campus",
            "image mode: three 640 x 480 images rendered, edges found and matched (crowd 30)",
            med,
            "ms",
            f"p99 {p99:.3g}",
            "<= 20 ms",
            med <= 20.0,
        )  # fmt: skip
    )
    for selection, target in (("farthest", "<= 1 ms"), ("all", "")):
        med, p99 = _pf_update_ms(50 if quick else 500, selection)
        results.append(
            Result(
                "campus",
                f"far_landmark_pf update, 500 particles x 30 detections, selection {selection}",
                med,
                "ms",
                f"p99 {p99:.3g}",
                target,
                (med <= 1.0) if target else None,
            )  # fmt: skip
        )
    start = time.perf_counter()
    build_scene_map("stereo_campus", MappingDrive(seed=0))
    wall = time.perf_counter() - start
    results.append(Result("campus", "the default scene map: the route driven once (run 1, crowd 30), one process", wall, "s",
                          "one run", "<= 60 s", wall <= 60.0))  # fmt: skip
    return results
