"""Every bad input raises the exact error type with the bad key or value in its message."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import envs
from envs.config import load_world, world_path
from envs.localization_env import LocalizationEnv
from localizers.schema import ConfigError


def write_world(tmp_path: Path, name: str, edit: Callable[[dict], object]) -> Path:
    """A copy of a shipped world YAML with ``edit(data)`` applied."""
    data = yaml.safe_load(world_path(name).read_text())
    edit(data)
    path = tmp_path / f"edited_{name}.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.mark.parametrize("name", sorted(envs.ENV_WORLDS.values()))
def test_shipped_worlds_load_and_round_trip_through_a_yaml_copy(tmp_path: Path, name: str) -> None:
    config = load_world(name)
    assert config.name == name
    assert load_world(write_world(tmp_path, name, lambda d: None)) == config
    assert load_world(world_path(name)) == config


def test_unknown_world_name() -> None:
    with pytest.raises(ConfigError, match="unknown world 'robocup_crowdd'") as exc:
        load_world("robocup_crowdd")
    assert "robocup_crowded" in str(exc.value)  # lists what exists


def edit_top(key: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        d[key] = value

    return edit


def edit_nested(section: str, key: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        d[section][key] = value

    return edit


def edit_sensor(sensor: str, key: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        d["sensors"][sensor][key] = value

    return edit


def edit_crowd(crowd: str, key: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        d["crowds"][crowd][key] = value

    return edit


def edit_landmark(key: str, value: object) -> Callable[[dict], None]:
    def edit(d: dict) -> None:
        d["landmarks"][1][key] = value

    return edit


@pytest.mark.parametrize(
    ("name", "edit", "fragments"),
    [
        ("robocup_crowded", edit_top("bogus_key", 1), ["'bogus_key'"]),
        ("robocup_static", edit_nested("robot", "raduis_m", 0.2), ["'raduis_m'", "RobotConfig"]),
        ("crowded_room", edit_sensor("lidar", "beems", 10), ["'beems'"]),
        ("robocup_crowded", edit_landmark("colour", "red"), ["'colour'", "landmarks[1]"]),
        ("robocup_crowded", edit_top("dt_s", "fast"), ["'fast'", "dt_s", "expected a number"]),
        ("crowded_room", edit_sensor("lidar", "beams", 10.5), ["10.5", "beams", "expected an integer"]),
        ("robocup_static", edit_sensor("camera", "noise_std_rad", True), ["True", "noise_std_rad"]),
        ("robocup_crowded", edit_top("size_m", [5.0]), ["size_m", "[5.0]", "expected 2 values"]),
        ("robocup_crowded", edit_crowd("soccer", "type", "zombies"), ["'zombies'", "unknown crowd type", "soccer"]),
        ("robocup_crowded", edit_crowd("soccer", "count", 20), ["20", "crowd.count", "[0, 14]"]),
        ("robocup_crowded", edit_crowd("soccer", "count", -1), ["-1", "crowd.count"]),
        ("robocup_crowded", edit_crowd("soccer", "kind", "soccer"), ["'kind'", "SoccerConfig", "crowds.soccer"]),
        ("crowded_room", lambda d: d["crowds"].update(lidar={"type": "walkers"}), ["'lidar'", "both a sensor and a crowd"]),
        ("robocup_static", lambda d: d["landmarks"][0].update(collides="no"), ["'no'", "collides"]),
        ("robocup_crowded", edit_top("dt_s", 0.0), ["dt_s must be > 0, got 0.0"]),
        ("robocup_static", edit_landmark("max_range_m", -4.6), ["-4.6", "max_range_m"]),
        ("robocup_static", edit_sensor("odometry", "alpha3", -0.1), ["-0.1", "odometry.alpha3"]),
        ("crowded_room", edit_sensor("lidar", "fov_rad", 7.0), ["7.0", "lidar.fov_rad"]),
        ("robocup_static", edit_sensor("camera", "dropout_probability", 1.5), ["1.5", "dropout_probability"]),
        ("robocup_crowded", edit_top("name", None), ["None", "name"]),
        ("robocup_crowded", lambda d: d.pop("dt_s"), ["missing required key 'dt_s'"]),
        ("robocup_static", lambda d: d.pop("sensors"), ["needs at least one sensor"]),
        ("robocup_static", edit_sensor("camera", "type", "telescope"), ["'telescope'", "sensors.camera", "bearing_camera"]),
        ("robocup_static", lambda d: d["sensors"]["camera"].pop("type"), ["sensors.camera", "needs a 'type'"]),
        ("crowded_room", edit_sensor("lidar", "type", "bearing_camera"), ["'beams'", "BearingCameraConfig"]),
        ("crowded_room", lambda d: d["sensors"].update(camera={"type": "bearing_camera"}), ["'camera'", "needs landmarks"]),
        (
            "crowded_room",
            lambda d: d["sensors"].update(rear={"type": "lidar", "beams": 9}),
            ["sensors 'lidar' and 'rear' both write observation key 'lidar'"],
        ),
        (
            "robocup_static",
            lambda d: d["landmarks"].append(dict(d["landmarks"][0])),
            ["landmark names repeat", "L5"],
        ),
    ],
)
def test_bad_world_file_names_the_problem_and_the_file(
    tmp_path: Path, name: str, edit: Callable[[dict], object], fragments: list[str]
) -> None:
    path = write_world(tmp_path, name, edit)
    with pytest.raises(ConfigError) as exc:
        load_world(path)
    message = str(exc.value)
    assert path.name in message
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_missing_world_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="nowhere.yaml"):
        load_world(tmp_path / "nowhere.yaml")


# ---------------------------------------------------------------------------- actions


@pytest.mark.parametrize(
    ("action", "fragment"),
    [
        (np.array([2.0, 0.0], dtype=np.float32), "2.0"),
        (np.array([0.0, -1.5], dtype=np.float32), "-1.5"),
        (np.array([np.nan, 0.0], dtype=np.float32), "nan"),
        (np.array([0.0, np.inf]), "inf"),
        ([1.0001, 0.0], "1.0001"),
    ],
    ids=["speed-2", "turn-minus-1.5", "nan", "inf", "list-just-over"],
)
def test_out_of_range_action_raises_value_error_naming_it(action: object, fragment: str) -> None:
    env = LocalizationEnv("robocup_crowded")
    env.reset(seed=0)
    pose = env.world.robot_pose
    with pytest.raises(ValueError, match="outside the action space") as exc:
        env.step(action)  # type: ignore[arg-type]
    assert fragment in str(exc.value)
    np.testing.assert_array_equal(env.world.robot_pose, pose)  # nothing moved
    assert env.world.step_count == 0


@pytest.mark.parametrize(
    ("action", "fragment"),
    [
        (np.zeros(3, dtype=np.float32), "array([0., 0., 0.]"),
        (np.zeros((1, 2), dtype=np.float32), "array([[0., 0.]]"),
        (np.float32(0.5), "0.5"),
        (np.array(["0", "1"]), "'0'"),
        ([0.1, 0.2, 0.3], "[0.1, 0.2, 0.3]"),
    ],
    ids=["three", "row", "scalar", "strings", "list-of-three"],
)
def test_wrong_shape_or_type_action_raises_value_error(action: object, fragment: str) -> None:
    env = LocalizationEnv("robocup_crowded")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(2,\)") as exc:
        env.step(action)  # type: ignore[arg-type]
    assert fragment in str(exc.value)


def test_bad_action_through_gym_make() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"\[2\.0, 0\.0\]"):
        env.step(np.array([2.0, 0.0], dtype=np.float32))
    env.close()


@pytest.mark.parametrize("corner", [(-1.0, -1.0), (1.0, 1.0), (-1.0, 1.0), (0.0, 0.0)])
def test_boundary_actions_are_accepted(corner: tuple[float, float]) -> None:
    env = LocalizationEnv("robocup_static", crowd_size=0)
    env.reset(seed=0)
    env.step(np.array(corner, dtype=np.float32))
    env.step(np.array(corner, dtype=np.float64))
    env.step(np.array([int(c) for c in corner]))  # integers are numbers too
    assert env.world.step_count == 3


# ---------------------------------------------------------------------------- env kwargs


@pytest.mark.parametrize(
    ("kwargs", "fragments"),
    [
        ({"bogus": 1}, ["'bogus'", "1"]),
        ({"camera": {"nosie_std_rad": 0}}, ["'nosie_std_rad'", "camera"]),
        ({"crowd": {"soccer": {"bal": False}}}, ["'bal'", "soccer"]),
        ({"crowd": {"robots": {"count": 2}}}, ["no crowd 'robots'", "crowds: soccer"]),
        ({"crowd": {"count": 2}}, ["no crowd 'count'"]),
        ({"crowd_size": "many"}, ["'many'", "count", "expected an integer"]),
        ({"crowd_size": 20}, ["20", "crowd.count must be in [0, 14]"]),
        ({"crowd_size": -3}, ["-3"]),
        ({"crowd_size": 2.5}, ["2.5", "expected an integer"]),
        ({"crowd_size": True}, ["True", "expected an integer"]),
        ({"camera": {"noise_std_rad": "small"}}, ["'small'", "noise_std_rad"]),
        ({"camera": {"noise_std_rad": -0.1}}, ["-0.1", "noise_std_rad"]),
        ({"odometry": {"alpha1": None}}, ["None", "alpha1"]),
        ({"robot": {"max_speed_mps": 0}}, ["max_speed_mps must be > 0, got 0"]),
        ({"camera": 0.0}, ["'camera'", "mapping", "0.0"]),
        # a sensor the world lacks is added (its defaults, then the overrides), checked the same way
        ({"lidar": {"beams": 0}}, ["lidar.beams must be >= 1, got 0", "robocup_crowded"]),
        ({"sonar": {"sensors": 0}}, ["sonar.sensors must be >= 1, got 0", "robocup_crowded"]),
        ({"sonar": [12]}, ["'sonar'", "mapping", "[12]"]),
        ({"render_mode": "ascii"}, ["'ascii'", "render_mode"]),
    ],
)
def test_bad_env_kwargs_raise_config_error_naming_them(kwargs: dict, fragments: list[str]) -> None:
    with pytest.raises(ConfigError) as exc:
        gym.make("crowdloc/RoboCupCrowded-v0", **kwargs)
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_good_env_kwargs_reach_the_config() -> None:
    env = gym.make(
        "crowdloc/RoboCupCrowded-v0",
        crowd_size=3,
        camera={"noise_std_rad": 0},
        odometry={"alpha1": 0.1},
        crowd={"soccer": {"ball": False}},
    )
    config = env.unwrapped.config
    assert config.crowd.count == 3
    assert config.sensors["camera"].noise_std_rad == 0.0 and isinstance(config.sensors["camera"].noise_std_rad, float)
    assert (
        config.sensors["odometry"].alpha1 == 0.1
        and config.sensors["odometry"].alpha2 == load_world("robocup_crowded").sensors["odometry"].alpha2
    )
    assert config.crowds["soccer"].ball is False and config.crowds["soccer"].goalkeeper is True
    assert env.unwrapped.world.ball_row == -1 and env.unwrapped.world.ball_rows.size == 0
    env.close()


def test_reset_option_robot_pose_is_applied() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0")
    _, info = env.reset(seed=0, options={"robot_pose": [1.0, 2.0, -0.5]})
    np.testing.assert_allclose(info["true_pose"], [1.0, 2.0, -0.5], atol=1e-12)
    assert math.isfinite(info["time_s"]) and info["time_s"] == 0.0
    env.close()


@pytest.mark.parametrize(
    ("pose", "fragment"),
    [
        ([1.0, 2.0], "[1.0, 2.0]"),
        ([1.0, 2.0, 0.0, 4.0], "[1.0, 2.0, 0.0, 4.0]"),
        ([float("nan"), 2.0, 0.0], "nan"),
        ([1.0, float("inf"), 0.0], "inf"),
        ("here", "'here'"),
    ],
    ids=["two", "four", "nan", "inf", "string"],
)
def test_bad_robot_pose_option_raises_value_error_naming_it(pose: object, fragment: str) -> None:
    env = LocalizationEnv("robocup_static")
    with pytest.raises(ValueError, match=r"robot_pose") as exc:
        env.reset(seed=0, options={"robot_pose": pose})
    assert fragment in str(exc.value)


def test_place_crowd_member_checks_the_index() -> None:
    env = LocalizationEnv("robocup_static", crowd_size=1)
    env.reset(seed=0)
    with pytest.raises(IndexError, match="crowd member 1 does not exist"):
        env.world.place_crowd_member(1, (1.0, 1.0))
