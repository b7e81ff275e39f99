"""The bearing camera's occlusion and range limits, and the LIDAR against closed-form ranges."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from envs.config import load_world

STILL = np.zeros(2, dtype=np.float32)
START = [2.5, 8.0, 0.0]  # robocup_static's start pose; L5 (5, 10), L6 (3.5, 10), L7 (1.5, 10)
NAMES = ("L5", "L6", "L7")
#: the crowded room without its door, bevel and furniture: four walls, analytic ranges
BARE_ROOM = dataclasses.replace(load_world("crowded_room"), walls=(), furniture=())


def slots(obs: dict) -> np.ndarray:
    return np.asarray(obs["landmarks"]).reshape(-1, 3)


def static_env(**kwargs: object) -> gym.Env:
    """Exp 1's field without its distractors (tests of what the camera sees of the landmarks)."""
    camera = {"distractors": [], **kwargs.pop("camera", {})}  # type: ignore[dict-item]
    return gym.make("crowdloc/RoboCupStatic-v0", camera=camera, **kwargs)


def test_static_world_landmark_order() -> None:
    env = static_env()
    assert env.unwrapped.world.landmark_names == NAMES
    env.close()


@pytest.mark.parametrize("landmark", [0, 1, 2], ids=NAMES)
def test_crowd_member_on_the_sight_line_hides_the_landmark(landmark: int) -> None:
    env = static_env(crowd_size=1)
    obs, info = env.reset(seed=0, options={"robot_pose": START})
    world = env.unwrapped.world
    world.place_crowd_member(0, (0.5, 1.0))  # far from every sight line
    obs, _, _, _, info = env.step(STILL)
    assert slots(obs)[:, 0].tolist() == [1.0, 1.0, 1.0]
    assert np.flatnonzero(info["visible_landmarks"]).tolist() == [0, 1, 2]

    # halfway along the sight line from the robot to the landmark
    midpoint = 0.5 * (np.array(START[:2]) + world.landmark_xy[landmark])
    world.place_crowd_member(0, tuple(midpoint))
    for _ in range(3):  # held in place: it stays hidden
        obs, _, _, _, info = env.step(STILL)
        assert slots(obs)[landmark, 0] == 0.0
        assert slots(obs)[landmark, 1:].tolist() == [0.0, 0.0]
        assert landmark not in np.flatnonzero(info["visible_landmarks"]).tolist()
        np.testing.assert_allclose(world.positions[1], midpoint, atol=1e-9)
    others = [j for j in range(3) if j != landmark]
    # the other landmarks stay in sight, unless the blocker also covers one (L6 and L7 are 2 m apart,
    # a 0.23 m person at 1.2 m covers about +-11 deg)
    assert set(np.flatnonzero(info["visible_landmarks"]).tolist()) <= set(others)

    world.place_crowd_member(0, (0.5, 1.0))
    obs, _, _, _, info = env.step(STILL)
    assert slots(obs)[landmark, 0] == 1.0
    assert landmark in np.flatnonzero(info["visible_landmarks"]).tolist()
    env.close()


def test_crowd_member_beside_the_sight_line_does_not_hide_it() -> None:
    env = static_env(crowd_size=1)
    env.reset(seed=0, options={"robot_pose": START})
    world = env.unwrapped.world
    # L6 from (2.5, 8) is along (1, 2)/sqrt(5); step 0.4 m sideways from the midpoint (radius 0.23 m)
    side = np.array([2.0, -1.0]) / math.sqrt(5.0)
    world.place_crowd_member(0, tuple(np.array([3.0, 9.0]) + 0.4 * side))
    obs, _, _, _, info = env.step(STILL)
    assert slots(obs)[1, 0] == 1.0 and 1 in np.flatnonzero(info["visible_landmarks"]).tolist()
    env.close()


@pytest.mark.parametrize(
    ("robot_xy", "l5_visible"),
    [
        ((5.0, 5.5), True),  # 4.5 m from L5 (max_range_m 4.6)
        ((5.0, 5.45), True),  # 4.55 m
        ((5.0, 5.35), False),  # 4.65 m
        ((5.0, 5.3), False),  # 4.7 m
        ((2.5, 5.0), False),  # 5.59 m
    ],
)
def test_small_pole_is_lost_beyond_its_max_range(robot_xy: tuple[float, float], l5_visible: bool) -> None:
    env = static_env(crowd_size=0)
    obs, info = env.reset(seed=0, options={"robot_pose": [*robot_xy, 0.0]})
    for current in (obs, env.step(STILL)[0]):
        assert slots(current)[0, 0] == float(l5_visible)
        assert slots(current)[1:, 0].tolist() == [1.0, 1.0]  # the goal posts have no range limit
    info = env.unwrapped.last_info
    assert (0 in np.flatnonzero(info["visible_landmarks"]).tolist()) == l5_visible
    env.close()


def test_camera_range_limit_applies_to_every_landmark() -> None:
    env = static_env(crowd_size=0, camera={"max_range_m": 2.2})
    obs, info = env.reset(seed=0, options={"robot_pose": [2.5, 8.0, 0.0]})
    # distances: L5 3.2 m, L6 2.24 m, L7 2.24 m
    assert slots(obs)[:, 0].tolist() == [0.0, 0.0, 0.0]
    obs, info = env.reset(seed=0, options={"robot_pose": [3.5, 8.0, 0.0]})
    # L5 2.83 m, L6 2.0 m, L7 2.83 m
    assert slots(obs)[:, 0].tolist() == [0.0, 1.0, 0.0]
    assert np.flatnonzero(info["visible_landmarks"]).tolist() == [1]
    env.close()


@pytest.mark.parametrize(
    ("theta_deg", "fov_deg", "expected"),
    [
        # from (2.5, 8): L5 (5, 10) at 38.7 deg, L6 (3.5, 10) at 63.4 deg, L7 (1.5, 10) at 116.6 deg
        (90.0, 90.0, [0.0, 1.0, 1.0]),  # L5 is 51.3 deg off the heading
        (90.0, 110.0, [1.0, 1.0, 1.0]),
        (0.0, 90.0, [1.0, 0.0, 0.0]),
        (-90.0, 90.0, [0.0, 0.0, 0.0]),  # facing away
        (-90.0, 360.0, [1.0, 1.0, 1.0]),  # the omnidirectional default sees behind
        (63.4, 1.0, [0.0, 1.0, 0.0]),
    ],
)
def test_field_of_view_hides_landmarks_off_the_heading(theta_deg: float, fov_deg: float, expected: list[float]) -> None:
    env = static_env(crowd_size=0, camera={"fov_rad": math.radians(fov_deg)})
    obs, info = env.reset(seed=0, options={"robot_pose": [2.5, 8.0, math.radians(theta_deg)]})
    assert slots(obs)[:, 0].tolist() == expected
    assert np.flatnonzero(info["visible_landmarks"]).tolist() == np.flatnonzero(expected).tolist()
    env.close()


@pytest.mark.parametrize("fov", [0.0, -1.0, 7.0, math.nan])
def test_bad_field_of_view_is_named(fov: float) -> None:
    with pytest.raises(ValueError, match="camera.fov_rad"):
        static_env(camera={"fov_rad": fov})


@pytest.mark.parametrize("theta", [0.0, 1.0, -2.5, math.pi - 0.01])
def test_noise_free_bearings_match_the_geometry(theta: float) -> None:
    env = static_env(crowd_size=0, camera={"noise_std_rad": 0.0})
    pose = [2.5, 7.0, theta]
    obs, info = env.reset(seed=3, options={"robot_pose": pose})
    landmark_xy = env.unwrapped.world.landmark_xy
    bearing = np.arctan2(landmark_xy[:, 1] - pose[1], landmark_xy[:, 0] - pose[0]) - theta
    expected = np.column_stack([np.ones(3), np.cos(bearing), np.sin(bearing)]).astype(np.float32)
    np.testing.assert_allclose(slots(obs), expected, atol=1e-6)
    np.testing.assert_array_equal(info["true_pose"], pose)
    env.close()


def test_bearing_noise_has_the_configured_spread() -> None:
    env = static_env(crowd_size=0)
    std = env.unwrapped.config.sensors["camera"].noise_std_rad
    obs, _ = env.reset(seed=5, options={"robot_pose": [2.5, 7.0, 0.0]})
    landmark_xy = env.unwrapped.world.landmark_xy
    truth = np.arctan2(landmark_xy[:, 1] - 7.0, landmark_xy[:, 0] - 2.5)
    errors = []
    for _ in range(2_000):
        obs, *_ = env.step(STILL)
        s = slots(obs).astype(np.float64)
        errors.append((np.arctan2(s[:, 2], s[:, 1]) - truth + np.pi) % (2 * np.pi) - np.pi)
    errors = np.asarray(errors).reshape(-1)
    n = errors.size
    assert abs(errors.mean()) < 5 * std / math.sqrt(n)
    assert abs(errors.var(ddof=1) - std**2) < 5 * std**2 * math.sqrt(2 / (n - 1))
    env.close()


def test_dropout_and_false_detections() -> None:
    env = static_env(crowd_size=0, camera={"dropout_probability": 1.0})
    obs, info = env.reset(seed=0, options={"robot_pose": START})
    assert slots(obs)[:, 0].tolist() == [0.0, 0.0, 0.0]
    assert np.flatnonzero(info["visible_landmarks"]).tolist() == [0, 1, 2]  # ground truth ignores dropout
    env.close()

    env = static_env(crowd_size=0, camera={"false_detection_probability": 1.0, "noise_std_rad": 0.0})
    obs, info = env.reset(seed=0, options={"robot_pose": [2.5, 2.0, 0.0]})  # too far for L5
    assert slots(obs)[:, 0].tolist() == [1.0, 1.0, 1.0]
    assert np.flatnonzero(info["false_detections"]).tolist() == [0, 1, 2]
    assert np.flatnonzero(info["visible_landmarks"]).tolist() == [1, 2]
    env.close()

    env = static_env(crowd_size=0)
    _, info = env.reset(seed=0)
    assert np.flatnonzero(info["false_detections"]).tolist() == []
    env.close()


def box_ranges(x: float, y: float, angles: np.ndarray, size: tuple[float, float]) -> np.ndarray:
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (size[0] - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (size[1] - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)


@pytest.mark.parametrize("pose", [(2.0, 3.0, 0.3), (5.5, 1.2, -2.8), (3.5, 3.5, math.pi / 2)])
def test_lidar_in_the_empty_room_reads_the_wall_distances(pose: tuple[float, float, float]) -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", world=BARE_ROOM, crowd_size=0, lidar={"range_std_m": 0.0})
    obs, _ = env.reset(seed=0, options={"robot_pose": list(pose)})
    lidar = env.unwrapped.config.sensors["lidar"]
    lo, hi = lidar.relative_angles_rad
    assert hi - lo == pytest.approx(lidar.fov_rad)
    angles = pose[2] + np.linspace(lo, hi, lidar.beams)
    expected = box_ranges(pose[0], pose[1], angles, env.unwrapped.config.size_m)
    np.testing.assert_allclose(obs["lidar"], expected, atol=1e-5)  # float32 metres
    env.close()


def test_lidar_sees_a_column_in_front() -> None:
    """People as columns of their footprint (legs, torso and head: tests/envs/test_bodies.py)."""
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=2, lidar={"range_std_m": 0.0}, crowd={"queues": {"shape": "column"}})
    obs, _ = env.reset(seed=0, options={"robot_pose": [2.0, 3.0, 0.0]})
    world = env.unwrapped.world
    world.place_crowd_member(0, (4.0, 3.0))
    world.place_crowd_member(1, (2.0, 0.8))  # to the right, at -90 deg (inside the 270 deg scan)
    obs, *_ = env.step(STILL)
    lidar = env.unwrapped.config.sensors["lidar"]
    angles = np.linspace(*lidar.relative_angles_rad, lidar.beams)
    ahead = int(np.argmin(np.abs(angles)))
    below = int(np.argmin(np.abs(angles + math.pi / 2)))
    r = env.unwrapped.config.crowd.radius_m
    assert obs["lidar"][ahead] == pytest.approx(2.0 - r, abs=1e-5)
    assert obs["lidar"][below] == pytest.approx(2.2 - r, abs=1e-5)
    env.close()


def cone_rays(sensors: int, cone: float, per_cone: int) -> np.ndarray:
    """``(sensors, per_cone)`` ray angles of a sonar ring, as SonarConfig documents them."""
    centres = np.arange(sensors) * 2 * math.pi / sensors
    return centres[:, None] + ((np.arange(per_cone) + 0.5) / per_cone - 0.5) * cone


@pytest.mark.parametrize(("pose", "per_cone"), [((2.0, 3.0, 0.3), 1), ((5.5, 1.2, -2.8), 5), ((3.5, 3.5, math.pi / 2), 9)])
def test_sonar_reads_the_nearest_wall_in_each_cone(pose: tuple[float, float, float], per_cone: int) -> None:
    sonar = {"range_std_m": 0.0, "max_range_m": 20.0, "rays_per_cone": per_cone, "sensors": 8, "cone_rad": 0.6}
    env = gym.make("crowdloc/CrowdedRoom-v0", world=BARE_ROOM, crowd_size=0, sonar=sonar)
    obs, _ = env.reset(seed=0, options={"robot_pose": list(pose)})
    rays = cone_rays(8, 0.6, per_cone) + pose[2]
    expected = box_ranges(pose[0], pose[1], rays.reshape(-1), env.unwrapped.config.size_m).reshape(8, per_cone).min(axis=1)
    assert obs["sonar"].shape == (8,)
    np.testing.assert_allclose(obs["sonar"], expected, atol=1e-5)
    env.close()


def test_sonar_cone_sees_a_robot_off_its_centre_line() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=1, sonar={"range_std_m": 0.0, "max_range_m": 1.5})
    env.reset(seed=0, options={"robot_pose": [2.5, 2.5, 0.0]})
    world = env.unwrapped.world
    world.place_crowd_member(0, (2.5 + 1.0 * math.cos(0.2), 2.5 + 1.0 * math.sin(0.2)))  # 11 deg left, 1 m
    obs, *_ = env.step(STILL)
    r = env.unwrapped.config.crowd.radius_m
    ranges = obs["sonar"]
    assert ranges.shape == (12,)
    # sensor 0 (cone -15..15 deg) sees the robot's near side along its nearest ray; its
    # centre ray alone (1 m * cos 11 deg passes 0.2 m from the centre, inside the radius) reads more
    assert 1.0 - r - 0.01 < ranges[0] < 1.0 - r + 0.03
    # the robot subtends 11 +- 13 deg: sensor 1 (15..45 deg) sees its edge, the rest nothing
    assert ranges[1] < 1.5
    assert np.all(ranges[2:] == pytest.approx(1.5))
    env.close()


def test_sonar_is_added_to_a_world_without_one_and_bad_values_are_named() -> None:
    from core.schema import ConfigError

    plain = gym.make("crowdloc/RoboCupCrowded-v0")
    assert "sonar" not in plain.observation_space.spaces
    env = gym.make("crowdloc/RoboCupCrowded-v0", sonar={})
    assert env.observation_space["sonar"].shape == (12,)
    assert env.observation_space["sonar"].high.max() == pytest.approx(2.0)
    obs, _ = env.reset(seed=3)
    assert env.observation_space.contains(obs)
    env.close()
    plain.close()
    with pytest.raises(ConfigError, match=r"sonar.cone_rad must be in \(0, 2 pi / sensors = 0.5236\].*got 1.0"):
        gym.make("crowdloc/RoboCupCrowded-v0", sonar={"cone_rad": 1.0})
    with pytest.raises(ConfigError, match="unknown key 'beams' for SonarConfig"):
        gym.make("crowdloc/RoboCupCrowded-v0", sonar={"beams": 16})
