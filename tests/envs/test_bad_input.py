"""Every bad input raises the exact error type with the bad key or value in its message."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from typing import ClassVar

import gymnasium as gym
import numpy as np
import pytest
import yaml

import envs
from core.schema import ConfigError
from envs.config import load_world, non_finite_numbers, world_path
from envs.localization_env import LocalizationEnv


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


# ---------------------------------------------------------------------------- values that reach pymunk or the sensors

INF, NAN = float("inf"), float("nan")


@pytest.mark.parametrize(
    ("env_id", "kwargs", "fragments"),
    [
        # a non-finite mass or friction aborted the process inside Chipmunk (exit 134)
        ("RoboCupCrowded", {"robot": {"mass_kg": INF}}, ["robot.mass_kg must be finite, got inf"]),
        ("RoboCupCrowded", {"crowd": {"soccer": {"mass_kg": INF}}}, ["crowds.soccer.mass_kg must be finite, got inf"]),
        ("RoboCupCrowded", {"robot": {"friction": NAN}}, ["robot.friction must be finite and >= 0, got nan"]),
        ("RoboCupCrowded", {"robot": {"friction": -0.5}}, ["robot.friction must be finite and >= 0, got -0.5"]),
        ("RoboCupCrowded", {"crowd": {"soccer": {"ball_mass_kg": 0}}}, ["soccer.ball_mass_kg must be finite and > 0, got 0.0"]),
        (
            "CrowdedRoom",
            {"crowd": {"walkers": {"repulsion_strength_mps2": NAN}}},
            ["crowds.walkers.repulsion_strength_mps2", "nan"],
        ),
        # sensors: NaN in the observation, infinite bounds, ranges of 0 or the maximum
        ("RoboCupCrowded", {"camera": {"noise_std_rad": INF}}, ["sensors.camera.noise_std_rad must be finite, got inf"]),
        ("RoboCupCrowded", {"lidar": {"max_range_m": INF}}, ["sensors.lidar.max_range_m must be finite, got inf"]),
        ("RoboCupCrowded", {"sonar": {"max_range_m": INF}}, ["sensors.sonar.max_range_m must be finite, got inf"]),
        ("RoboCupCrowded", {"lidar": {"range_std_m": INF}}, ["sensors.lidar.range_std_m must be finite, got inf"]),
        ("RoboCupCrowded", {"odometry": {"alpha1": INF}}, ["odometry.alpha1 must be finite and >= 0, got inf"]),
        ("CrowdedRoom", {"lidar": {"fov_rad": NAN}}, ["lidar.fov_rad", "got nan"]),
        # errors that blamed the crowd, or came from deep inside
        ("RoboCupCrowded", {"robot": {"radius_m": INF}}, ["robot.radius_m must be finite, got inf"]),
        ("RoboCupCrowded", {"robot": {"radius_m": 100}}, ["robot.start_region_m", "radius 100 m", "200 m across, is larger"]),
        ("RoboCupStatic", {"robot": {"start_pose": [NAN, 2.0, 0.0]}}, ["robot.start_pose[0] must be finite, got nan"]),
        ("RoboCupCrowded", {"robot": {"max_turn_rate_rps": INF}}, ["robot.max_turn_rate_rps must be finite, got inf"]),
        (
            "RoboCupCrowded",
            {"robot": {"start_region_m": [4.0, 1.0, 1.0, 4.0]}},
            ["robot.start_region_m must be (xmin, ymin, xmax, ymax) with xmin <= xmax", "[4.0, 1.0, 1.0, 4.0]"],
        ),
        (
            "RoboCupCrowded",
            {"crowd": {"soccer": {"radius_m": 5}}},
            ["crowd 'soccer'", "robots of radius 5 m (10 m across) cannot fit in the 5 m x 5 m field"],
        ),
        # sizes: bounded by what a real sensor resolves and what memory holds
        ("RoboCupCrowded", {"lidar": {"beams": 10**8}}, ["lidar.beams must be in 1..7200", "0.05 deg", "got 100000000"]),
        ("RoboCupCrowded", {"sonar": {"sensors": 10**6}}, ["sonar.sensors x sonar.rays_per_cone (1000000 x 5)", "1..7200"]),
        ("CeilingCorridor", {"camera": {"texel_m": 1e-5}}, ["texel_m 1e-05", "320000 x 2500000 texels", "more than 1 GiB"]),
    ],
)
def test_values_that_killed_hung_or_misled_are_config_errors(env_id: str, kwargs: dict, fragments: list[str]) -> None:
    with pytest.raises(ConfigError) as exc:
        gym.make(f"crowdloc/{env_id}-v0", **kwargs)
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_numpy_integers_are_integers() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=np.int64(5), lidar={"beams": np.int32(91)})
    assert env.unwrapped.config.crowd.count == 5 and type(env.unwrapped.config.crowd.count) is int
    assert env.unwrapped.config.sensors["lidar"].beams == 91
    env.close()
    with pytest.raises(ConfigError, match="expected an integer, got bool np.True_"):
        gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=np.bool_(True))


def test_an_unbounded_field_still_takes_inf() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", camera={"max_range_m": INF}, crowd={"soccer": {"height_m": INF}})
    assert env.unwrapped.config.sensors["camera"].max_range_m == INF
    env.close()


def test_non_finite_numbers_names_each_by_its_path() -> None:
    @dataclasses.dataclass
    class Inner:
        unbounded_fields: ClassVar[frozenset[str]] = frozenset({"reach_m"})
        reach_m: float = INF
        size_m: tuple[float, float] = (1.0, NAN)

    found = list(non_finite_numbers({"a": Inner(), "b": Inner(reach_m=NAN, size_m=(1.0, 2.0)), "n": [3, 10**400, -INF]}))
    assert [(p, str(v), inf_ok) for p, v, inf_ok in found] == [
        ("a.size_m[1]", "nan", False),
        ("b.reach_m", "nan", True),
        ("n[2]", "-inf", False),
    ]


@pytest.mark.parametrize("pose", [[100.0, 100.0, 0.0], [-0.4, 5.0, 0.0], [2.5, 10.4, 1.0]])
def test_a_start_pose_follows_the_reset_option_rule(pose: list[float]) -> None:
    env = LocalizationEnv("robocup_static")
    with pytest.raises(ValueError, match="robot_pose") as refused:
        env.reset(seed=0, options={"robot_pose": pose})
    problem = str(refused.value).split(": ", 1)[1]
    with pytest.raises(ConfigError) as exc:
        gym.make("crowdloc/RoboCupStatic-v0", robot={"start_pose": pose})
    assert f"robot.start_pose = {pose}: {problem}" in str(exc.value)


def test_a_start_region_must_lie_where_the_robot_fits() -> None:
    with pytest.raises(ConfigError, match=r"robot.start_region_m = \[5.0, 5.0, 6.0, 6.0\].*x \[-0.27, 5.27\]"):
        gym.make("crowdloc/RoboCupStatic-v0", robot={"start_pose": None, "start_region_m": [5.0, 5.0, 6.0, 6.0]})
    # inside a building on the campus: the same rule, the same words as a reset option
    with pytest.raises(ConfigError, match=r"robot.start_pose = \[.*\]: the robot's centre .* would be inside"):
        config = load_world("stereo_campus")
        building = next(s for f in config.features.values() for s in f.solids() if s.bottom_m <= 0.0)
        x, y = building.corners.mean(axis=0)
        gym.make("crowdloc/StereoCampus-v0", robot={"start_pose": [float(x), float(y), 0.0]})
    # a region that just fits is accepted
    gym.make("crowdloc/RoboCupStatic-v0", robot={"start_pose": None, "start_region_m": [-0.27, -0.27, 5.27, 10.27]}).close()


def test_a_pose_behind_a_wall_is_off_the_floor_for_a_reset_and_a_start() -> None:
    """(1.31, 2.87) clears every wall of the corridor but lies between its wall and the field's
    edge, a pocket closed on every side: a kidnap once left the robot there for a whole window."""
    env = LocalizationEnv("ceiling_corridor")
    with pytest.raises(ValueError, match=r"robot_pose.*\(1.31, 2.87\).*close off from its main floor"):
        env.reset(seed=0, options={"robot_pose": [1.31, 2.87, 1.57]})
    with pytest.raises(ConfigError, match=r"robot.start_pose = \[1.31, 2.87, 1.57\]: .* close off from its main floor"):
        gym.make("crowdloc/CeilingCorridor-v0", robot={"start_pose": [1.31, 2.87, 1.57]})
    # the alcove beside it and the door recess are floor the robot can reach
    assert env.world.config.robot_placement_problem(1.3, 10.5) is None
    assert env.world.config.robot_placement_problem(0.0, 2.87) is None
    env.close()


def test_a_crowd_region_too_small_for_its_radius_says_so() -> None:
    env = LocalizationEnv("robocup_crowded")
    crowd = env.world.crowd_named("soccer")
    with pytest.raises(ConfigError, match=r"crowd 'soccer': members of radius 0.6 m do not fit .* x \[1.6, 1.4\], y \[0, 2\]"):
        crowd.free_positions(np.random.default_rng(0), 2, 0.6, [], box=(1.6, 0.0, 1.4, 2.0))
