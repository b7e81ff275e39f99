"""World geometry and contacts: the arena's walls hold the robot, contacts are reported."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import envs
from envs.config import load_world
from envs.world import World

ENV_IDS = sorted(envs.ENV_WORLDS)


@pytest.mark.parametrize("world_name", sorted(envs.ENV_WORLDS.values()))
def test_world_exports_its_static_geometry(world_name: str) -> None:
    config = load_world(world_name)
    world = World(config)
    xmin, ymin, xmax, ymax = config.arena_m
    furniture = sum(len(piece.segments()) for piece in config.furniture)
    scenery = sum(len(feature.segments()) for feature in config.features.values())  # buildings, poles, trees
    assert world.seg_a.shape == world.seg_b.shape == (4 + len(config.walls) + furniture + scenery, 2)
    corners = {tuple(p) for p in world.seg_a[:4]}
    assert corners == {(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)}
    assert world.landmark_xy.shape == (len(config.landmarks), 2)
    np.testing.assert_array_equal(world.landmark_xy, np.reshape([(lm.x_m, lm.y_m) for lm in config.landmarks], (-1, 2)))
    np.testing.assert_array_equal(world.landmark_max_range_m, [lm.max_range_m for lm in config.landmarks])
    assert world.positions.shape == (world.body_count, 2)
    assert world.radii_m.shape == (world.body_count,)


@pytest.mark.parametrize("env_id", ENV_IDS)
@pytest.mark.parametrize("heading", [-math.pi / 2, 3 * math.pi / 4], ids=["into-a-wall", "into-a-corner"])
def test_walls_stop_the_robot_at_full_throttle(env_id: str, heading: float) -> None:
    env = gym.make(env_id, crowd_size=0)
    config = env.unwrapped.config
    xmin, ymin, xmax, ymax = config.arena_m
    start = [0.5 * (xmin + xmax), 0.5 * (ymin + ymax), heading]
    if env.unwrapped.world.robot_placement_problem(start[0], start[1]):  # the campus's centre is inside a building
        start[:2] = config.robot.start_pose[:2]
    env.reset(seed=0, options={"robot_pose": start})
    r = config.robot.radius_m
    kinds: list[str] = []
    # long enough to cross the whole arena twice
    steps = int(2 * max(xmax - xmin, ymax - ymin) / (config.robot.max_speed_mps * config.dt_s))
    for _ in range(steps):
        _, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        x, y, _ = info["true_pose"]
        kinds += [c.other for c in info["contacts"]]
        # the robot's centre stays at least most of a radius inside the boundary walls
        assert xmin + 0.5 * r < x < xmax - 0.5 * r and ymin + 0.5 * r < y < ymax - 0.5 * r, info["true_pose"]
    assert "wall" in kinds or "landmark" in kinds
    env.close()


def test_contact_events_name_the_other_body() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0", crowd_size=0)
    # L6 (3.5, 10) straight ahead, 1 m away: drive into the goal post
    env.reset(seed=0, options={"robot_pose": [2.5, 10.0, 0.0]})
    seen = []
    for _ in range(30):
        _, _, _, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
        seen += info["contacts"]
    assert [c.other for c in seen][:1] == ["landmark"]
    assert seen[0].other_index == -1
    assert seen[0].position_xy_m[0] == pytest.approx(3.5 - 0.06, abs=0.05)
    env.close()
