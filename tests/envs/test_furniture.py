"""Furniture and walls with heights (envs.config.FurnitureConfig): what sensors at each height
see of them, what collides, and the localizers' map where the furniture has moved."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from core.schema import ConfigError
from envs.config import FurnitureConfig, load_world
from envs.world import World
from localizers.base import LandmarkMap

STILL = np.zeros(2, dtype=np.float32)


def ahead_range(pose: list[float], height_m: float) -> float:
    """The empty room's LIDAR beam straight ahead from ``pose`` with the scan plane at ``height_m``."""
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=0, lidar={"range_std_m": 0.0, "height_m": height_m})
    obs, _ = env.reset(seed=0, options={"robot_pose": pose})
    lidar = env.unwrapped.config.sensors["lidar"]
    ahead = int(np.argmin(np.abs(np.linspace(*lidar.relative_angles_rad, lidar.beams))))
    env.close()
    return float(obs["lidar"][ahead])


@pytest.mark.parametrize(("height_m", "expected"), [(0.2, 2.0 - 0.42), (1.0, 2.0 - 0.42), (1.9, 2.0)])
def test_the_shelf_is_seen_below_its_top_and_not_above(height_m: float, expected: float) -> None:
    # from (1.6, 2.0) facing -y: the 1.8 m shelf's front at y = 0.22 + 0.2, the wall at y = 0
    assert ahead_range([1.6, 2.0, -math.pi / 2], height_m) == pytest.approx(expected, abs=1e-5)


@pytest.mark.parametrize(("height_m", "expected"), [(0.2, 3.0), (0.705, 3.0 - 1.55), (1.9, 3.0)])
def test_a_table_shows_its_legs_low_its_top_at_its_height_and_nothing_above(height_m: float, expected: float) -> None:
    # from (5.4, 3.0) facing -y: between the legs (0.575 m to either side) to the wall; the top's
    # edge at y = 1.2 + 0.35 between 0.69 and 0.72 m
    assert ahead_range([5.4, 3.0, -math.pi / 2], height_m) == pytest.approx(expected, abs=1e-5)


def test_a_table_leg_is_seen_at_leg_height() -> None:
    # from (4.825, 3.0) facing -y, straight at a leg: centre (5.4 - 0.575, 1.2 + 0.325), front face y = 1.525 + 0.025
    assert ahead_range([4.825, 3.0, -math.pi / 2], 0.2) == pytest.approx(3.0 - 1.55, abs=1e-5)


def test_the_table_segments_have_their_heights() -> None:
    table = next(f for f in load_world("crowded_room").furniture if f.kind == "table")
    rows = np.array(table.segments())
    assert rows.shape == (4 + 16, 6)
    np.testing.assert_allclose(rows[:4, 4:], [[0.69, 0.72]] * 4)  # the top
    np.testing.assert_allclose(rows[4:, 4:], [[0.0, 0.69]] * 16)  # four legs of four sides


def test_the_map_has_the_table_where_it_stood_and_a_lidar_localizer_gets_the_map_at_its_height() -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", localizer="mcl_lidar")
    world_segments = env.unwrapped.config.static_segments()
    full = env.unwrapped.landmark_map
    moved = np.flatnonzero(np.any(np.abs(full.walls_m - world_segments[:, :4]) > 1e-12, axis=1))
    table = next(f for f in env.unwrapped.config.furniture if f.kind == "table")
    assert moved.size == 20  # the table's top and legs, nothing else
    np.testing.assert_allclose(full.walls_m[moved][:, [0, 2]] - world_segments[moved][:, [0, 2]], table.map_offset_m[0])
    cut = env.get_wrapper_attr("landmark_map")
    assert cut.walls_m.shape[0] == full.walls_m.shape[0] - 4  # at 0.2 m the table's top is not in the map
    assert np.all(cut.heights[:, 0] <= 0.2) and np.all(cut.heights[:, 1] > 0.2)
    env.close()


def test_at_height_keeps_the_walls_spanning_the_height() -> None:
    walls = np.array([[0, 0, 1, 0], [0, 1, 1, 1], [0, 2, 1, 2]], dtype=float)
    lmap = LandmarkMap(np.zeros((0, 2)), (), (0, 0, 5, 5), walls, wall_heights_m=np.array([[0, 2.5], [0, 1.8], [0.7, 0.72]]))
    assert lmap.at_height(0.2).walls_m.tolist() == walls[:2].tolist()
    assert lmap.at_height(1.9).walls_m.tolist() == walls[:1].tolist()
    assert lmap.at_height(0.71).walls_m.shape == (3, 4)
    assert LandmarkMap(np.zeros((0, 2)), (), (0, 0, 5, 5), walls).at_height(100.0).walls_m.shape == (3, 4)
    with pytest.raises(ValueError, match="height_m must be finite, got nan"):
        lmap.at_height(math.nan)
    with pytest.raises(ValueError, match="bottom < top"):
        LandmarkMap(np.zeros((0, 2)), (), (0, 0, 5, 5), walls, wall_heights_m=np.array([[0, 2.5], [2, 1.8], [0, 1]]))


def test_the_robot_cannot_be_placed_inside_a_box_and_stops_at_it() -> None:
    room = load_world("crowded_room")
    crate = FurnitureConfig("crate", "box", 3.5, 3.5, (1.0, 1.0), 1.0, angle_rad=0.3)
    world = World(dataclasses.replace(room, furniture=(*room.furniture, crate)))
    assert "inside furniture 'crate'" in str(world.robot_placement_problem(3.6, 3.4))
    assert "would overlap wall" in str(world.robot_placement_problem(3.5, 4.05))  # across its edge
    assert world.robot_placement_problem(3.5, 4.5) is None
    assert world.robot_placement_problem(5.4, 1.2) is None  # under the table, between its legs
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=0)
    env.reset(seed=0, options={"robot_pose": [1.6, 1.0, -math.pi / 2]})
    for _ in range(200):  # drive into the shelf's front at y = 0.42
        _, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
    assert info["true_pose"][1] == pytest.approx(0.42 + 0.25, abs=0.03)
    env.close()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"size_m": (0.0, 1.0)}, "size_m must be positive"),
        ({"height_m": math.nan}, "every number must be finite"),
        ({"leg_radius_m": 0.3}, "the legs must fit under the top"),
        ({"top_thickness_m": 0.8}, "top_thickness_m must be in"),
        ({"x_m": 6.9}, "must lie inside the boundary walls"),
        ({"map_offset_m": (2.0, 0.0)}, "must lie inside the boundary walls"),
    ],
)
def test_bad_furniture_is_refused(change: dict, message: str) -> None:
    room = load_world("crowded_room")
    table = next(f for f in room.furniture if f.kind == "table")
    with pytest.raises(ConfigError, match=message):
        dataclasses.replace(room, furniture=(dataclasses.replace(table, **change),))


def test_repeated_furniture_names_are_refused() -> None:
    room = load_world("crowded_room")
    piece = FurnitureConfig("box", "box", 3.0, 3.0, (0.5, 0.5), 1.0)
    with pytest.raises(ConfigError, match="furniture names repeat"):
        dataclasses.replace(room, furniture=(piece, piece))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"lidar": {"height_m": -0.1}}, "lidar.height_m must be finite and >= 0, got -0.1"),
        ({"lidar": {"height_m": math.inf}}, "lidar.height_m must be finite and >= 0, got inf"),
        ({"sonar": {"height_m": math.nan}}, "sonar.height_m must be finite and >= 0, got nan"),
    ],
)
def test_a_sensor_height_must_be_a_height(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        gym.make("crowdloc/CrowdedRoom-v0", **kwargs)


def test_a_camera_height_must_be_a_height() -> None:
    with pytest.raises(ConfigError, match="camera.height_m must be finite and >= 0, got -1"):
        gym.make("crowdloc/RoboCupStatic-v0", camera={"height_m": -1.0})


def test_a_wall_height_must_be_positive() -> None:
    with pytest.raises(ConfigError, match="wall_height_m must be > 0, got 0"):
        dataclasses.replace(load_world("crowded_room"), wall_height_m=0.0)
