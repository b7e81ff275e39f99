"""rl-zoo3 out of the box: the shipped hyperparameter file (configs/rl_zoo3/ppo.yaml) covers every
task id with its training config's PPO settings, and the recipe in docs/tasks.md trains, enjoys and
records a task id (slow: the [zoo] extra, installed by make)."""

from __future__ import annotations

import dataclasses
import subprocess
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest
import yaml

import crowdloc_configs
from agents.rl import task_ids
from agents.rl.config import load_train_config

ROOT = Path(__file__).resolve().parents[2]
HYPERPARAMS = crowdloc_configs.path("rl_zoo3", "ppo.yaml")
#: the record_video line of docs/tasks.md's recipe: rl_zoo3.record_video has no --gym-packages
RECORD_VIDEO = "import agents, runpy; runpy.run_module('rl_zoo3.record_video', run_name='__main__', alter_sys=True)"


def _hyperparams() -> dict[str, dict[str, Any]]:
    loaded = yaml.safe_load(HYPERPARAMS.read_text())
    assert isinstance(loaded, dict)
    return loaded


def test_the_hyperparameter_file_covers_every_task_id_with_a_dict_policy() -> None:
    hyperparams = _hyperparams()
    assert sorted(hyperparams) == sorted(task_ids.TASK_CONFIGS), "one entry per task id, and only task ids"
    for env_id, params in hyperparams.items():
        assert env_id in gym.registry
        assert params["policy"] == "MultiInputPolicy", f"{env_id}: the observation is a dict"


@pytest.mark.parametrize(("env_id", "config"), sorted(task_ids.TASK_CONFIGS.items()))
def test_the_hyperparameters_are_the_training_configs(env_id: str, config: str) -> None:
    trained = load_train_config(config)
    params = _hyperparams()[env_id]
    in_policy = ("net_arch", "log_std_init")  # SB3 takes these in policy_kwargs
    ppo = {f.name: getattr(trained.ppo, f.name) for f in dataclasses.fields(trained.ppo) if f.name not in in_policy}
    expected = {
        "policy": "MultiInputPolicy",
        "n_envs": trained.n_envs,
        "n_timesteps": trained.total_timesteps,
        **ppo,
        "policy_kwargs": {"net_arch": list(trained.ppo.net_arch), "log_std_init": trained.ppo.log_std_init},
    }
    assert params == expected


def _zoo(*argv: str) -> str:
    """``python ARGV`` from the checkout (as docs/tasks.md's recipe runs), asserting it succeeds."""
    done = subprocess.run([sys.executable, *argv], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{argv}: exit {done.returncode}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


@pytest.mark.slow
def test_rl_zoo3_trains_enjoys_and_records_a_task_id(tmp_path: Path) -> None:
    env_id, logs, episode = (
        "crowdloc/ActiveCandidateSets-v0",
        str(tmp_path / "logs"),
        task_ids.task_episode_steps("ppo_candidate_sets"),
    )
    task = ("--algo", "ppo", "--env", env_id)
    # 2048 steps: two rollouts of 4 envs x 450 steps
    _zoo("-m", "rl_zoo3.train", *task, "--gym-packages", "agents", "--conf-file", str(HYPERPARAMS), "-n", "2048",
         "--eval-freq", "-1", "--seed", "0", "--log-folder", logs)  # fmt: skip
    run = tmp_path / "logs" / "ppo" / "crowdloc-ActiveCandidateSets-v0_1"
    assert (run / "crowdloc-ActiveCandidateSets-v0.zip").is_file()
    out = _zoo("-m", "rl_zoo3.enjoy", *task, "--gym-packages", "agents", "-f", logs, "-n", str(episode), "--no-render")
    assert f"Episode Length {episode}" in out and "1 Episodes" in out
    assert RECORD_VIDEO in (ROOT / "docs" / "tasks.md").read_text()
    _zoo("-c", RECORD_VIDEO, *task, "-f", logs, "-n", "30")
    assert len(list((run / "videos").glob("*.mp4"))) == 1
