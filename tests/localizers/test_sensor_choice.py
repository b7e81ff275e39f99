"""A second sensor of a kind (the LIDAR paper's reference LIDAR at 1.9 m): added through the
``sensors`` env keyword, picked by ``localizer_sensor`` online and ``sensor`` in replays, and the
localizer's map cut at the chosen sensor's height."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents.experiments.replay import record, replay
from agents.experiments.scenarios import square_driver
from core.schema import ConfigError

TOP = {"lidar_top": {"type": "lidar", "key": "lidar_top", "height_m": 1.9, "beams": 271}}


def test_a_second_lidar_sees_over_the_people_and_the_furniture() -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=30, sensors=TOP, lidar={"beams": 271})
    obs, _ = env.reset(seed=0)
    assert obs["lidar_top"].shape == (271,)
    section = env.unwrapped.world.snapshot().section(1.9)
    assert section.rows.size < 30 * 0.5  # only the tallest heads reach 1.9 m
    # legs and furniture cut the low scan short where the high one reaches the walls, rarely the reverse
    low, high = obs["lidar"], obs["lidar_top"]
    assert (low < high - 0.1).sum() > 10 * max(1, (high < low - 0.1).sum())
    env.close()


def test_two_lidars_need_the_localizer_to_name_one() -> None:
    with pytest.raises(ConfigError, match="several: lidar, lidar_top; name one"):
        gym.make("crowdloc/CrowdedRoom-v0", sensors=TOP, localizer="mcl_lidar")
    with pytest.raises(ConfigError, match="sensor 'odometry' is not a lidar sensor"):
        gym.make("crowdloc/CrowdedRoom-v0", sensors=TOP, localizer="mcl_lidar", localizer_sensor="odometry")
    low = gym.make("crowdloc/CrowdedRoom-v0", sensors=TOP, localizer="mcl_lidar", localizer_sensor="lidar")
    high = gym.make("crowdloc/CrowdedRoom-v0", sensors=TOP, localizer="mcl_lidar", localizer_sensor="lidar_top")
    full = low.unwrapped.landmark_map
    assert low.get_wrapper_attr("landmark_map").walls_m.shape[0] == full.walls_m.shape[0] - 4  # not the table's top
    # at 1.9 m: the room's walls, the bevel, the door and the pillar; not the 1.8 m shelf nor the table
    assert high.get_wrapper_attr("landmark_map").walls_m.shape[0] == 4 + 2 + 4
    high.reset(seed=0)
    _, _, _, _, info = high.step(np.zeros(2, dtype=np.float32))
    assert info["estimate"].valid
    low.close()
    high.close()


def test_a_replay_reads_the_sensor_it_is_told_to() -> None:
    env_kwargs = {"sensors": TOP, "lidar": {"beams": 271}, "crowd_size": 8}

    def drive(env: object) -> object:
        return square_driver(env, center_xy=(3.5, 3.5), side_m=2.0, laps=1, speed_mps=0.5, turn_rate_rps=1.0)

    rec = record(
        "crowdloc/CrowdedRoom-v0", drive, 0, max_steps=40, env_kwargs=env_kwargs, reset_options={"robot_pose": [2.5, 2.5, 0.0]}
    )
    with pytest.raises(ConfigError, match="several"):
        replay(rec, "mcl_lidar", rng_seed=0)
    low = replay(rec, "mcl_lidar", rng_seed=0, sensor="lidar")
    high = replay(rec, "mcl_lidar", rng_seed=0, sensor="lidar_top")
    assert low.estimates.shape == high.estimates.shape == (41, 3)  # the reset and 40 steps
    assert not np.array_equal(low.estimates, high.estimates)
    assert rec.localizer_map("scan", "lidar_top").walls_m.shape[0] == 10


def test_the_sensors_keyword_is_checked() -> None:
    with pytest.raises(ConfigError, match="a new one needs a 'type'"):
        gym.make("crowdloc/CrowdedRoom-v0", sensors={"top": {"height_m": 1.9}})
    with pytest.raises(ConfigError, match="must map sensor names to mappings"):
        gym.make("crowdloc/CrowdedRoom-v0", sensors=["lidar"])
    env = gym.make("crowdloc/CrowdedRoom-v0", sensors={"lidar": {"height_m": 1.0}})  # an existing one: overrides
    assert env.unwrapped.config.sensors["lidar"].height_m == 1.0
    env.close()
