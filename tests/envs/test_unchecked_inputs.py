"""Inputs that must be checked: reset poses outside the field, a dt_s the physics cannot
resolve, and a contact list that grew with the episode."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

from core.schema import ConfigError
from envs.config import available_worlds, load_world, world_path
from envs.localization_env import LocalizationEnv

# ---------------------------------------------------------------- reset(options={"robot_pose": ...})


@pytest.mark.parametrize(
    ("pose", "fragments"),
    [
        ([100.0, 100.0, 0.0], ["[100.0, 100.0, 0.0]", "x in [0, 5]", "y in [0, 10]", "0.5 m margin", "x in [-0.5, 5.5]"]),
        ([-1.0, 5.0, 0.0], ["[-1.0, 5.0, 0.0]", "x in [-0.5, 5.5]"]),
        ([2.5, 10.6, 0.0], ["[2.5, 10.6, 0.0]", "y in [-0.5, 10.5]"]),
        # inside the boundary walls, but the robot's disc (radius 0.23 m) would cross them
        ([-0.4, 5.0, 0.0], ["[-0.4, 5.0, 0.0]", "radius 0.23 m", "x [-0.27, 5.27]"]),
        ([2.5, 10.4, 1.0], ["[2.5, 10.4, 1.0]", "radius 0.23 m", "y [-0.27, 10.27]"]),
    ],
    ids=["far-outside", "left", "above", "disc-over-left-edge", "disc-over-top-edge"],
)
def test_reset_refuses_a_robot_pose_off_the_field(pose: list[float], fragments: list[str]) -> None:
    env = LocalizationEnv("robocup_static")
    with pytest.raises(ValueError, match=r"robot_pose") as exc:
        env.reset(seed=0, options={"robot_pose": pose})
    for fragment in [*fragments, "robocup_static"]:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_reset_refuses_a_bad_pose_through_gym_make_and_keeps_refusing_unknown_keys() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0")
    with pytest.raises(ValueError, match=r"robot_pose.*\[100, 100, 0\].*field"):
        env.reset(seed=0, options={"robot_pose": [100, 100, 0]})
    with pytest.raises(ValueError, match="unknown reset option 'robot_xy'"):
        env.reset(seed=0, options={"robot_xy": [1.0, 1.0]})
    env.close()


def test_reset_accepts_a_disc_that_just_fits() -> None:
    env = LocalizationEnv("robocup_static")  # boundary walls 0.5 m outside the field
    r = env.config.robot.radius_m
    for pose in ([-0.5 + r, -0.5 + r, 0.0], [5.5 - r, 10.5 - r, 3.0], [5.0, 5.5, 0.0]):
        _, info = env.reset(seed=0, options={"robot_pose": pose})
        np.testing.assert_allclose(info["true_pose"][:2], pose[:2], atol=1e-12)


def test_reset_bounds_are_the_field_where_there_is_no_margin() -> None:
    env = LocalizationEnv("crowded_room", crowd_size=0)  # 7 m x 7 m, no margin
    with pytest.raises(ValueError, match=r"x \[0\.25, 6\.75\]") as exc:
        env.reset(seed=0, options={"robot_pose": [6.9, 3.0, 0.0]})
    assert "margin" not in str(exc.value)


def test_reset_refuses_a_robot_disc_over_an_interior_wall() -> None:
    env = LocalizationEnv("ceiling_corridor")  # corridor walls at x = +-1
    with pytest.raises(ValueError, match=r"robot_pose.*overlap wall") as exc:
        env.reset(seed=0, options={"robot_pose": [1.0, 0.0, 0.0]})
    assert "radius 0.275 m" in str(exc.value) and "at least 0.295 m" in str(exc.value)
    with pytest.raises(ValueError, match="overlap wall"):
        env.reset(seed=0, options={"robot_pose": [0.8, 0.0, 0.0]})  # the disc reaches x = 1.075
    _, info = env.reset(seed=0, options={"robot_pose": [0.6, 0.0, 0.0]})  # clear of the wall
    np.testing.assert_allclose(info["true_pose"], [0.6, 0.0, 0.0], atol=1e-12)


# ---------------------------------------------------------------- dt_s


@pytest.mark.parametrize("name", available_worlds())
def test_every_shipped_world_keeps_its_dt_within_the_bound(name: str) -> None:
    config = load_world(name)
    assert config.robot.max_speed_mps * config.dt_s <= config.robot.radius_m
    for crowd in config.crowds.values():
        for _, speed, radius in crowd.top_speeds():
            assert speed * config.dt_s <= radius


def test_infinite_dt_is_a_config_error_naming_dt_s_and_the_file(tmp_path: Path) -> None:
    data = yaml.safe_load(world_path("robocup_static").read_text())
    data["dt_s"] = math.inf
    path = tmp_path / "fast.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"dt_s must be finite, got inf") as exc:
        load_world(path)
    assert "fast.yaml" in str(exc.value)


@pytest.mark.parametrize(
    ("name", "dt", "fragments"),
    [
        # the robot: 1.75 m/s x 0.25 s = 0.44 m, its radius 0.23 m
        ("robocup_static", 0.25, ["dt_s = 0.25", "the robot", "0.438 m", "radius 0.23 m", "<= 0.1314 s"]),
        # the ball: kicked at 3 m/s, radius 0.11 m
        ("robocup_crowded", 0.05, ["dt_s = 0.05", "crowd 'soccer': ball", "radius 0.11 m", "<= 0.03667 s"]),
        # the corridor walkers: capped at 1.3 x 1.4 m/s, radius 0.2 m
        ("ceiling_corridor", 0.2, ["dt_s = 0.2", "crowd 'corridor': walkers", "1.82 m/s", "<= 0.1099 s"]),
    ],
)
def test_dt_too_long_for_the_fastest_body_is_a_config_error(name: str, dt: float, fragments: list[str]) -> None:
    config = load_world(name)
    with pytest.raises(ConfigError) as exc:
        dataclasses.replace(config, dt_s=dt)
    for fragment in [*fragments, repr(name)]:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_dt_bound_comes_through_gym_make_overrides() -> None:
    # dt_s itself is not an env keyword; the speeds it is bounded by are
    with pytest.raises(ConfigError, match=r"dt_s = 0\.0333.*the robot.*radius 0\.23 m"):
        gym.make("crowdloc/RoboCupStatic-v0", robot={"max_speed_mps": 10.0})
    with pytest.raises(ConfigError, match=r"dt_s = 0\.0333.*crowd 'soccer': ball"):
        gym.make("crowdloc/RoboCupCrowded-v0", crowd={"soccer": {"kick_speed_mps": 6.0}})
    gym.make("crowdloc/RoboCupCrowded-v0", crowd={"soccer": {"kick_speed_mps": 6.0, "ball": False}}).close()


# ---------------------------------------------------------------- world.contacts


def test_contacts_stay_bounded_over_a_long_episode_and_info_reports_each_step() -> None:
    env = LocalizationEnv("robocup_static")
    env.reset(seed=0, options={"robot_pose": [2.5, 0.4, -math.pi / 2]})  # facing the bottom edge
    world = env.world
    events, steps_with_events = 0, 0
    for k in range(1, 5001):
        forward = (k // 16) % 2 == 0  # bump into the wall (0.5 m outside the field), back off, bump again
        _, _, _, _, info = env.step(np.array([1.0 if forward else -1.0, 0.0], dtype=np.float32))
        assert len(world.contacts) <= 4, f"step {k}: the world holds {len(world.contacts)} contact events"
        assert info["contacts"] == world.contacts and info["contacts"] is not world.contacts
        assert all(c.step == k for c in info["contacts"]), (k, info["contacts"])
        events += len(info["contacts"])
        steps_with_events += bool(info["contacts"])
    assert steps_with_events >= 100, steps_with_events  # a bump every 32 steps
    assert world.contact_count == events
    assert {c.other for c in info["contacts"]} <= {"wall"}
    env.reset(seed=0)
    assert world.contacts == [] and world.contact_count == 0
