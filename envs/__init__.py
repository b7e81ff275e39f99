"""crowdloc worlds: Pymunk scenarios with crowds, sensors and the Gymnasium environments.

Importing this package registers the environment ids in the ``crowdloc`` namespace::

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


#: task id -> shipped training config (``configs/experiments/``): a world with its localizer,
#: conditions and the active-localization reward (``agents.rl.tasks``); the ids above return reward 0
TASK_CONFIGS = {
    "crowdloc/ActiveCandidateSets-v0": "ppo_candidate_sets",
    "crowdloc/ActiveMCLBearing-v0": "ppo_mcl_bearing",
    "crowdloc/ActiveRoomLidar-v0": "ppo_room_lidar",
    "crowdloc/ActiveCorridorTargets-v0": "ppo_corridor_targets",
    "crowdloc/ActiveCampusStereo-v0": "ppo_campus_stereo",
}


def task_episode_steps(config: str) -> int:
    """A task's episode length: its training config's ``ppo.n_steps`` (one episode per env per rollout)."""
    import crowdloc_configs
    from localizers.schema import load_yaml

    return int(load_yaml(crowdloc_configs.path("experiments", f"{config}.yaml"))["ppo"]["n_steps"])


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
    for env_id, config in TASK_CONFIGS.items():
        if env_id not in registry:
            # by name only: envs does not import agents; the task module loads when one is made
            register(
                id=env_id,
                entry_point="agents.rl.tasks:make_task",
                kwargs={"config": config},
                max_episode_steps=task_episode_steps(config),
            )


_register()

__all__ = ["ENV_WORLDS", "TASK_CONFIGS", "task_episode_steps", "LocalizationEnv", "WorldConfig", "available_worlds", "load_world"]
