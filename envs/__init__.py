"""crowdloc worlds: Pymunk scenarios with crowds, sensors and the Gymnasium environments.

Importing this package registers the world ids in the ``crowdloc`` namespace (``import agents``
adds the task ids, :mod:`agents.rl.task_ids`)::

    import gymnasium as gym
    import envs  # noqa: F401  (registers crowdloc/*)

    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=10)
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

from envs.config import WorldConfig, available_worlds, load_world
from envs.localization_env import LocalizationEnv

#: env id -> shipped world config name
ENV_WORLDS = {
    "crowdloc/RoboCupStatic-v0": "robocup_static",
    "crowdloc/RoboCupCrowded-v0": "robocup_crowded",
    "crowdloc/CrowdedRoom-v0": "crowded_room",
    "crowdloc/CeilingCorridor-v0": "ceiling_corridor",
    "crowdloc/StereoCampus-v0": "stereo_campus",
}


def _register() -> None:
    for env_id, world in ENV_WORLDS.items():
        if env_id in registry:
            continue
        register(
            id=env_id,
            entry_point="envs.registration:make_env",
            kwargs={"world": world},
            max_episode_steps=load_world(world).max_episode_steps,
        )


_register()

__all__ = ["ENV_WORLDS", "LocalizationEnv", "WorldConfig", "available_worlds", "load_world"]
