"""Task ids: the whole active-localization task behind one ``gym.make`` id.

A bare world id (``crowdloc/RoboCupCrowded-v0``) returns reward 0: it is the world and its
sensors. A task id adds what a shipped training config (``configs/experiments/NAME.yaml``)
trains on: the localizer wrapper, the training conditions (camera, prior, sonar, belief
spread), the active-localization reward inside the env, what its policy observes and the
training episode length. So off-the-shelf tools (stable-baselines3's ``Monitor``, rl-zoo3) see
the real reward, and ``env.spec.id`` names the task (:func:`agents.rl.train.make_world`)::

    env = gym.make("crowdloc/ActiveCandidateSets-v0")   # == configs/experiments/ppo_candidate_sets.yaml

The ids are registered by ``import agents`` (:mod:`agents.rl.task_ids`, by name only: this module is
imported when one is made).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from agents.rl.config import load_train_config
from agents.rl.train import make_task_env


def make_task(config: str, crowd_size: int | None = None, render_mode: str | None = None, **overrides: Any) -> gym.Env[Any, Any]:
    """The task of training config ``config``: its env, localizer and conditions, with its reward.

    Args:
        config: a shipped training config name (or a YAML path).
        crowd_size: the crowd density (default: the world's own); training cycles the config's
            ``crowd_sizes`` over its parallel envs.
        render_mode: as for any crowdloc id.
        **overrides: further ``gym.make`` keywords, on top of the config's conditions.
    """
    return make_task_env(load_train_config(config), crowd_size, render_mode=render_mode, **overrides)
