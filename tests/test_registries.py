"""The plug-in registries and the world's control API refuse bad input with a message naming it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml

import envs  # noqa: F401  (registers crowdloc/*)
from core.schema import ConfigError
from envs.config import load_world, world_path
from envs.crowds import CrowdConfig, QueueCrowd, register_crowd
from envs.sensors import Lidar, LidarConfig, SensorConfig, register_sensor
from localizers.base import ScanMeasurement
from localizers.measurements import MeasurementKind, find_sensor, register_measurement, scan_measurement
from localizers.registry import LocalizerSpec, register_localizer


def test_a_taken_sensor_type_name_is_refused() -> None:
    with pytest.raises(ValueError, match="sensor type 'lidar' is already registered by envs.sensors.lidar.Lidar"):
        register_sensor("lidar", LidarConfig)(type("OtherLidar", (Lidar,), {}))
    register_sensor("lidar", LidarConfig)(Lidar)  # the same pair again is fine


def test_a_sensor_config_needs_a_key_field() -> None:
    @dataclass(frozen=True)
    class Keyless(SensorConfig):
        beams: int = 3

    with pytest.raises(ValueError, match="Keyless needs a 'key' field"):
        register_sensor("keyless", Keyless)


def test_a_taken_crowd_type_name_is_refused() -> None:
    @dataclass(frozen=True)
    class Other(CrowdConfig):
        pass

    with pytest.raises(ValueError, match="crowd type 'queues' is already registered by envs.crowds.queues.QueueCrowd"):
        register_crowd("queues", Other)(QueueCrowd)


def test_measurement_kinds_and_localizers_refuse_a_second_meaning() -> None:
    with pytest.raises(ValueError, match="measurement kind 'scan' is already registered"):
        register_measurement(MeasurementKind("scan", "sonar", scan_measurement))
    with pytest.raises(ConfigError, match="unknown measurement kind 'sonar_scan'"):
        register_localizer("x", LocalizerSpec("localizers.mcl_lidar", "LidarMCL", "LidarMCLParams", "sonar_scan", True, ""))
    taken = LocalizerSpec("localizers.mcl_lidar", "LidarMCL", "LidarMCLParams", "bearings", True, "")
    with pytest.raises(ConfigError, match="localizer 'mcl_lidar' is already registered"):
        register_localizer("mcl_lidar", taken)


def test_a_kind_with_two_sensors_to_read_is_ambiguous() -> None:
    sensors = {"front": {"type": "lidar", "key": "front"}, "rear": {"type": "lidar", "key": "rear"}}
    with pytest.raises(ConfigError, match="has several: front, rear"):
        find_sensor("scan", sensors, "localizer 'mcl_lidar'")
    # an added sensor may not take another's observation key
    with pytest.raises(ConfigError, match="sensors 'lidar' and 'sonar' both write observation key 'lidar'"):
        gym.make("crowdloc/CrowdedRoom-v0", sonar={"key": "lidar"})


def test_a_decoded_scan_carries_the_sensor_metadata() -> None:
    scan = scan_measurement(np.ones(3, dtype=np.float32), {"beam_angles_rad": np.array([-1.0, 0.0, 1.0]), "max_range_m": 4.0})
    assert isinstance(scan, ScanMeasurement) and scan.max_range_m == 4.0 and scan.ranges_m.dtype == np.float64


def test_crowd_size_needs_a_crowd(tmp_path: Path) -> None:
    data = yaml.safe_load(world_path("crowded_room").read_text())
    data.pop("crowds")
    path = tmp_path / "empty_room.yaml"
    path.write_text(yaml.safe_dump(data))
    assert load_world(path).crowd is None
    with pytest.raises(ConfigError, match="crowd_size=3: world 'crowded_room' has no crowd"):
        gym.make("crowdloc/CrowdedRoom-v0", world=str(path), crowd_size=3)
    env = gym.make("crowdloc/CrowdedRoom-v0", world=str(path))  # no crowd at all is a valid world
    obs, _ = env.reset(seed=0)
    assert env.unwrapped.world.body_count == 1 and env.observation_space.contains(obs)


def test_the_control_api_names_what_does_not_exist() -> None:
    world = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=2).unwrapped.world
    with pytest.raises(IndexError, match="body row 9 does not exist"):
        world.place_body(9, (1.0, 1.0))
    with pytest.raises(IndexError, match="crowd member 2 does not exist"):
        world.place_crowd_member(2, (1.0, 1.0))
    with pytest.raises(KeyError, match="has no crowd 'walkers'"):
        world.crowd_named("walkers")
    with pytest.raises(IndexError, match="member 5 does not exist"):
        world.crowd_named("soccer").send(5, np.zeros(2))
