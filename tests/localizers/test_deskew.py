"""``deskew`` of the LIDAR localizers: a swept scan moved to the pose at its end.

Analytic: a scan swept in a box by :func:`core.raycast.cast_rays_from` from the poses of
:func:`core.geometry.poses_along_step`, deskewed with the step's exact increment, puts every
hit back on the walls as seen from the end pose; taken as instantaneous it does not.
"""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from core.geometry import between, deskewed_scan, poses_along_step
from core.raycast import cast_rays_from
from core.schema import ConfigError
from envs.config import load_world
from envs.wrappers import LocalizationObservation
from localizers.base import MeasurementError, OdometryDelta, ScanMeasurement
from localizers.mcl_lidar import LidarMCL, deskewed
from localizers.registry import load_params, make_localizer

BOX = (7.0, 7.0)
CORNERS = np.array([[0.0, 0.0], [BOX[0], 0.0], [BOX[0], BOX[1]], [0.0, BOX[1]]])
SEG_A, SEG_B = CORNERS, np.roll(CORNERS, -1, axis=0)
NONE2, NONE = np.zeros((0, 2)), np.zeros(0)
ANGLES = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)
SWEEP_S, DT_S, MAX_RANGE = 0.025, 0.025, 30.0
LAGS = SWEEP_S * (ANGLES[-1] - ANGLES) / (2 * math.pi)  # envs.sensors.lidar.beam_lags_s


def wall_gap(points: np.ndarray) -> np.ndarray:
    """Distance of each world point ``(n, 2)`` to the nearest wall of the box."""
    return np.minimum.reduce([points[:, 0], BOX[0] - points[:, 0], points[:, 1], BOX[1] - points[:, 1]]).__abs__()


def swept(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    poses = poses_along_step(start, end, LAGS / DT_S)
    return cast_rays_from(np.ascontiguousarray(poses[:, :2]), ANGLES + poses[:, 2], MAX_RANGE, SEG_A, SEG_B, NONE2, NONE)


def to_world(pose: np.ndarray, ranges: np.ndarray, angles: np.ndarray) -> np.ndarray:
    a = pose[2] + angles
    return pose[:2] + ranges[:, None] * np.stack([np.cos(a), np.sin(a)], axis=1)


@pytest.mark.parametrize(
    "end",
    [(2.0, 3.0, 0.3 + 1.5 * DT_S), (2.0 + 0.5 * DT_S, 3.0, 0.3), (2.0 + 0.4 * DT_S, 3.0 + 0.3 * DT_S, 0.3 - 1.2 * DT_S)],
    ids=["turning", "driving", "both"],
)
def test_deskew_puts_a_swept_scan_back_on_the_walls(end: tuple[float, float, float]) -> None:
    start, stop = np.array([2.0, 3.0, 0.3]), np.array(end)
    ranges = swept(start, stop)
    assert wall_gap(to_world(stop, ranges, ANGLES)).max() > 1e-3  # taken as instantaneous: skewed by mm
    r, a = deskewed_scan(ranges, ANGLES, MAX_RANGE, between(start, stop), LAGS / DT_S)
    assert wall_gap(to_world(stop, r, a)).max() < 1e-9


def test_deskew_keeps_a_blank_beam_blank_and_turns_it() -> None:
    r, a = deskewed_scan(
        np.array([MAX_RANGE, 2.0]), np.array([0.0, 1.0]), MAX_RANGE, np.array([0.0, 0.0, 0.1]), np.array([0.5, 0.0])
    )
    assert r[0] == MAX_RANGE and a[0] == pytest.approx(-0.05)
    assert r[1] == pytest.approx(2.0) and a[1] == pytest.approx(1.0)


def test_deskewed_checks_the_lags_and_leaves_an_instantaneous_scan_alone() -> None:
    ranges = np.full(3, 2.0)
    angles = np.array([-1.0, 0.0, 1.0])
    step = np.array([0.01, 0.0, 0.02])
    for lags in (None, np.zeros(3)):
        r, a = deskewed(ranges, angles, 4.0, lags, step, DT_S, "test")
        assert r is ranges and a is angles
    with pytest.raises(MeasurementError, match="one lag per beam"):
        deskewed(ranges, angles, 4.0, np.zeros(2), step, DT_S, "test")
    with pytest.raises(MeasurementError, match=r"beam lag -0\.1 s at index 1"):
        deskewed(ranges, angles, 4.0, np.array([0.0, -0.1, 0.0]), step, DT_S, "test")


def test_lidar_mcl_weighs_the_deskewed_scan(monkeypatch: pytest.MonkeyPatch) -> None:
    """With ``deskew`` the likelihood gets :func:`deskewed_scan` of the scan by the last increment; without, the scan."""
    start, stop = np.array([2.0, 3.0, 0.3]), np.array([2.0 + 0.5 * DT_S, 3.0, 0.3 + 1.5 * DT_S])
    ranges = swept(start, stop)
    increment = between(start, stop)
    scan = ScanMeasurement(ranges, ANGLES, MAX_RANGE, LAGS)
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=0)
    landmarks = env.unwrapped.landmark_map
    env.close()
    seen = {}
    for deskew in (False, True):
        params = dataclasses.replace(load_params("mcl_lidar", {"model": "likelihood_field"}), deskew=deskew)
        mcl = LidarMCL(landmarks, params, dt_s=DT_S)
        mcl.reset(np.random.default_rng(0))
        mcl.predict(OdometryDelta(*increment))
        captured = []
        monkeypatch.setattr(mcl, "_log_likelihood", lambda particles, r, a, m, out, c=captured: (c.append((r, a)), out.fill(0.0)))
        mcl.update(scan)
        seen[deskew] = captured[0]
    np.testing.assert_array_equal(seen[False][0], ranges)
    want = deskewed_scan(ranges, ANGLES, MAX_RANGE, increment, LAGS / DT_S)
    np.testing.assert_allclose(seen[True][0], want[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(seen[True][1], want[1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("deskew", [False, True])
def test_far_point_mcl_accumulates_deskewed_points_from_a_swept_lidar(deskew: bool) -> None:
    """End to end: the bare room's swept UTM-30LX (noiseless ranges and odometry) on a turning,
    driving robot; the window's points, placed by the true pose, lie on the walls with ``deskew``
    (to the float32 ranges) and centimetres off without."""
    world = dataclasses.replace(load_world("crowded_room"), walls=(), furniture=())
    odometry = {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, "wheel_diameter_ratio": 1.0, "wheelbase_ratio": 1.0}
    no_slip = {"slip_per_accel_s2": 0.0, "slip_per_angular_accel_s2": 0.0, "slip_in_contact": 0.0}
    env = gym.make("crowdloc/CrowdedRoom-v0", world=world, crowd_size=0, robot=no_slip, odometry=odometry,
                   lidar={"range_std_m": 0.0, "sweep_s": SWEEP_S})  # fmt: skip
    params = {"deskew": deskew, "mcl": {"model": "likelihood_field"}}
    wrapped = LocalizationObservation(env, "far_point_mcl", localizer_params=params)
    wrapped.reset(seed=0, options={"robot_pose": [2.0, 3.0, 0.3]})
    for _ in range(8):
        wrapped.step(np.array([1.0, 1.0], dtype=np.float32))
    loc = wrapped.localizer
    points = loc.filter.to_world(loc.filter.points_xy, env.unwrapped.state.robot_pose)
    gap = wall_gap(points).max()
    assert (gap < 1e-4) if deskew else (gap > 0.01)
    wrapped.close()


def test_deskew_options_are_checked() -> None:
    with pytest.raises(ConfigError, match="mcl.deskew must be false: far_point_mcl deskews the raw scans"):
        load_params("far_point_mcl", {"mcl": {"deskew": True}})
    for name in ("mcl_lidar", "far_point_mcl"):
        assert load_params(name).deskew is False  # off in the papers' reproductions
        with pytest.raises(ConfigError, match="deskew"):
            load_params(name, {"deskew": "yes"})
    make_localizer(
        "far_point_mcl", gym.make("crowdloc/CrowdedRoom-v0").unwrapped.landmark_map, dt_s=DT_S, params={"deskew": True}
    )
