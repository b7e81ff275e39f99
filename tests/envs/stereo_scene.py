"""A small street scene for the stereo camera's tests: one building's façade ahead of the robot, a pole, a person.

The robot stands at (10, 30) facing +x; the building's west façade (x = 30, y from 15 to 45,
14 m tall, windows and pilasters) lies 20 m ahead and fills the cameras' view; a street lamp
stands at (22, 33); a crowd of one standing person can be placed anywhere.
"""

from __future__ import annotations

from typing import Any

from envs.config import RobotConfig, WorldConfig
from envs.crowds import WalkersConfig
from envs.features import BuildingConfig, BuildingsConfig, FacadeConfig, PoleConfig, PolesConfig
from envs.localization_env import LocalizationEnv
from envs.sensors import OdometryConfig
from envs.sensors.stereo_camera import IDEAL, StereoCameraConfig

ROBOT_POSE = (10.0, 30.0, 0.0)
FACADE_X_M = 30.0


def scene(people: int = 0, **camera: Any) -> WorldConfig:
    """The scene's world with ``people`` standing walkers and a stereo camera (ideal unless overridden)."""
    facade = FacadeConfig(column_pitch_m=6.0, window_pitch_m=2.0, wall_rgb=(200, 190, 170), column_rgb=(230, 228, 220))
    return WorldConfig(
        name="stereo_scene",
        description="a façade ahead, a pole, maybe a person",
        size_m=(60.0, 60.0),
        dt_s=0.1,
        max_episode_steps=100,
        robot=RobotConfig(start_pose=ROBOT_POSE, max_speed_mps=1.0, max_turn_rate_rps=1.0),
        wall_height_m=1.0,
        sensors={"odometry": OdometryConfig(), "stereo": StereoCameraConfig(**{**IDEAL, **camera})},
        crowds={"people": WalkersConfig(count=people, max_count=4)} if people else {},
        features={
            "buildings": BuildingsConfig(
                items=(BuildingConfig("hall", ((FACADE_X_M, 45.0), (FACADE_X_M, 15.0), (45.0, 15.0), (45.0, 45.0)), 14.0),),
                facade=facade,
            ),
            "poles": PolesConfig(items=(PoleConfig(22.0, 33.0, radius_m=0.12, height_m=8.0),)),
        },
    )


def scene_env(people: int = 0, **camera: Any) -> LocalizationEnv:
    """The scene as an env, reset with seed 0 (people held where they were placed: see :func:`place`)."""
    env = LocalizationEnv(scene(people, **camera))
    env.reset(seed=0)
    return env


def place(env: LocalizationEnv, index: int, x: float, y: float) -> None:
    """Stand person ``index`` at ``(x, y)``, held there, and observe again."""
    env.world.place_crowd_member(index, (x, y), hold=True)
