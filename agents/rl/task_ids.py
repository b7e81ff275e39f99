"""The task ids: ``crowdloc/Active*-v0``, each a shipped training config's whole task (a world,
its localizer, the conditions and the active-localization reward; :mod:`agents.rl.tasks`).

``import agents`` registers them with Gymnasium (beside the world ids that ``import envs``
registers, which return reward 0)::

    import gymnasium as gym
    import agents  # noqa: F401  (registers the task ids)

    env = gym.make("crowdloc/ActiveCandidateSets-v0")

This module stays light (no torch, no stable-baselines3): the entry point is named, and its
module loads when a task is made.
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

import crowdloc_configs
import envs  # registers the world ids a task is made of
from core.schema import load_yaml

#: task id -> shipped training config (``configs/experiments/``)
TASK_CONFIGS = {
    "crowdloc/ActiveCandidateSets-v0": "ppo_candidate_sets",
    "crowdloc/ActiveMCLBearing-v0": "ppo_mcl_bearing",
    "crowdloc/ActiveRoomLidar-v0": "ppo_room_lidar",
    "crowdloc/ActiveCorridorTargets-v0": "ppo_corridor_targets",
    "crowdloc/ActiveCampusStereo-v0": "ppo_campus_stereo",
}


def task_episode_steps(config: str) -> int:
    """A task's episode length: its training config's ``ppo.n_steps`` (one episode per env per rollout)."""
    return int(load_yaml(crowdloc_configs.path("experiments", f"{config}.yaml"))["ppo"]["n_steps"])


def register_task_ids() -> None:
    """Register every task id of :data:`TASK_CONFIGS` not yet registered (idempotent)."""
    assert envs.ENV_WORLDS  # the worlds first: a task id names one
    for env_id, config in TASK_CONFIGS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point="agents.rl.tasks:make_task",
                kwargs={"config": config},
                max_episode_steps=task_episode_steps(config),
            )
