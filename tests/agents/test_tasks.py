"""Task ids hold the whole active-localization task: their reward is not 0 under a random policy."""

from __future__ import annotations

import json
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.monitor import Monitor

from agents.rl import task_ids
from agents.rl.config import load_train_config
from core.schema import ConfigError

SOCCER_TASKS = {"crowdloc/ActiveCandidateSets-v0": "ppo_candidate_sets", "crowdloc/ActiveMCLBearing-v0": "ppo_mcl_bearing"}


@pytest.mark.parametrize(("env_id", "config"), sorted(SOCCER_TASKS.items()))
def test_a_task_id_is_its_training_config_with_the_reward(env_id: str, config: str) -> None:
    """The soccer tasks; the other worlds' tasks: tests/agents/test_world_tasks.py."""
    trained = load_train_config(config)
    env = Monitor(gym.make(env_id))
    assert env.spec is not None and env.spec.max_episode_steps == trained.ppo.n_steps == task_ids.task_episode_steps(config)
    obs, info = env.reset(seed=0)
    assert {"estimate", "estimate_valid", "sonar"} <= set(obs) and "true_pose" not in obs
    assert env.unwrapped.config.sensors["camera"].fov_rad == pytest.approx(trained.env_kwargs["camera"]["fov_rad"])
    rng = np.random.default_rng(0)
    total, steps, done = 0.0, 0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        total, steps, done = total + reward, steps + 1, terminated or truncated
    assert steps == trained.ppo.n_steps
    assert total != 0.0 and "reward_terms" in info
    assert env.get_episode_rewards() == [pytest.approx(total)]  # Monitor outside sees the task's reward


@pytest.mark.parametrize("env_id", sorted(task_ids.TASK_CONFIGS))
def test_a_task_id_names_the_task_in_its_spec_and_monitor_files(env_id: str, tmp_path: Path) -> None:
    """env.spec.id was the bare world's (its wrappers inside the task cached it): rl-zoo3's monitor
    files named the world. The spec also re-makes the task, and one time limit ends its episodes."""
    env = gym.make(env_id)
    assert env.spec is not None and env.spec.id == env_id
    Monitor(env, str(tmp_path / "run")).close()
    header = json.loads((tmp_path / "run.monitor.csv").read_text().splitlines()[0].lstrip("#"))
    assert header["env_id"] == env_id
    again = gym.make(env.spec)
    assert again.spec is not None and again.spec.id == env_id
    assert str(again) == str(env)
    assert str(env).count("TimeLimit") == 1
    again.close()


def test_a_bare_world_id_returns_reward_zero() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    env.reset(seed=0)
    assert env.step(env.action_space.sample())[1] == 0.0


def test_a_task_id_keeps_its_localizer_and_merges_parameter_overrides() -> None:
    """gym.make(task, localizer=...) was gymnasium's 'multiple values for keyword argument' TypeError."""
    with pytest.raises(
        ConfigError, match=r"localizer 'candidate_sets' is the task .* localizer='dead_reckoning' cannot replace it"
    ):
        gym.make("crowdloc/ActiveCandidateSets-v0", localizer="dead_reckoning")
    env = gym.make("crowdloc/ActiveCandidateSets-v0", localizer_params={"max_sets": 3})
    assert env.get_wrapper_attr("localizer")._params.max_sets == 3
    env.close()
    with pytest.raises(ConfigError, match="localizer_params must be a mapping, got int 0"):
        gym.make("crowdloc/ActiveCandidateSets-v0", localizer_params=0)
