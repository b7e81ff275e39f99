"""A tiny PPO run trains, saves, loads and resumes exactly; bad configs are refused."""

from __future__ import annotations

import inspect
import re
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

from agents.cli import main
from agents.rl.config import TrainConfig, load_train_config, parse_overrides
from agents.rl.train import check_train_config, latest_checkpoint, run_dir, train
from core.schema import ConfigError


def tiny(total: int, **kw: object) -> TrainConfig:
    overrides = {
        "total_timesteps": total,
        "n_envs": 2,
        "vec_env": "dummy",
        "checkpoint_every": 64,
        "crowd_sizes": [3],
        "ppo.n_steps": 32,
        "ppo.batch_size": 32,
        "ppo.n_epochs": 2,
        "ppo.net_arch": [16],
    }
    overrides.update(kw)
    return load_train_config("ppo_candidate_sets", overrides)


def weights(path: Path) -> list[torch.Tensor]:
    from stable_baselines3 import PPO

    return [p.detach().clone() for p in PPO.load(path, device="cpu").policy.parameters()]


def test_tiny_run_trains_saves_loads_and_resumes_exactly(tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    straight = train(tiny(192), tmp_path / "straight", progress_bar=False)
    first = train(tiny(64), tmp_path / "pieces", progress_bar=False)
    config = tiny(192)
    checkpoint = latest_checkpoint(config, tmp_path / "pieces")
    assert checkpoint is not None and checkpoint.name == "step_64.zip"
    resumed = train(config, tmp_path / "pieces", resume=checkpoint, progress_bar=False)
    assert first != straight
    a, b = weights(straight), weights(resumed)
    assert len(a) == len(b)
    for x, y in zip(a, b):
        torch.testing.assert_close(x, y, rtol=0, atol=0)
    # the policy did change from its initialization
    init = weights(train(tiny(1), tmp_path / "init", progress_bar=False))
    assert any(not torch.equal(x, y) for x, y in zip(a, init))
    # the saved model loads and acts on a real observation
    from agents.rl.train import make_training_env

    env = make_training_env(config, 0)
    obs, _ = env.reset()
    action, _ = PPO.load(resumed, device="cpu").predict(obs, deterministic=True)
    assert env.action_space.contains(action)
    run = tmp_path / "straight" / config.name / f"seed_{config.seed}"
    assert f'"seed": {config.seed}' in (run / "run.json").read_text() and "stable_baselines3" in (run / "run.json").read_text()
    assert any((run / "tb").rglob("events.out.tfevents*"))


@pytest.mark.parametrize(
    ("overrides", "needle"),
    [
        ({"ppo.lr": 1.0}, "lr"),
        ({"n_envs": 0}, "n_envs"),
        ({"vec_env": "threads"}, "threads"),
        ({"env_kwargs": {"max_episode_steps": 10}}, "max_episode_steps"),
        ({"ppo.net_arch": [0]}, "net_arch"),
        ({"ppo.log_std_init": float("nan")}, "log_std_init"),
    ],
)
def test_bad_training_configs_name_the_problem(overrides: dict, needle: str) -> None:
    with pytest.raises(ConfigError, match=needle):
        load_train_config("ppo_candidate_sets", overrides)


def test_the_initial_action_sd_is_the_configs(tmp_path: Path) -> None:
    """``ppo.log_std_init`` sets the Gaussian actions' starting log sd; its default is SB3's own (sd 1), so a
    config without it trains with SB3's starting sd."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.policies import ActorCriticPolicy

    from agents.rl.config import PPOConfig

    default = train(tiny(1), tmp_path / "default", progress_bar=False)
    narrow = train(tiny(1, **{"ppo.log_std_init": -1.5}), tmp_path / "narrow", progress_bar=False)
    # one rollout's update (4 Adam steps of 3e-4) moves them by at most about 1e-3
    assert PPO.load(default, device="cpu").policy.log_std.tolist() == pytest.approx([0.0, 0.0], abs=0.01)
    assert PPO.load(narrow, device="cpu").policy.log_std.tolist() == pytest.approx([-1.5, -1.5], abs=0.01)
    sb3_default = inspect.signature(ActorCriticPolicy.__init__).parameters["log_std_init"].default
    assert PPOConfig().log_std_init == sb3_default


def test_multi_seed_training_equals_the_single_runs(tmp_path: Path) -> None:
    from agents.rl.train import train_seeds

    config = tiny(64)
    models = train_seeds(config, tmp_path / "sweep", [3, 4], workers=2, progress=False)
    assert [m.parent.name for m in models] == ["seed_3", "seed_4"]
    alone = train(tiny(64, seed=4), tmp_path / "alone", progress_bar=False)
    for x, y in zip(weights(models[1]), weights(alone)):  # a run in the pool is the same run
        torch.testing.assert_close(x, y, rtol=0, atol=0)
    assert any(not torch.equal(x, y) for x, y in zip(weights(models[0]), weights(models[1])))
    with pytest.raises(ConfigError, match="seeds repeat"):
        train_seeds(config, tmp_path, [1, 1])


def test_train_cli_refuses_options_that_do_not_fit(capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import main

    for argv, needle in (
        (["train", "ppo_candidate_sets", "--seeds", "1", "2", "--resume", "latest"], "--resume continues one run"),
        (["train", "ppo_candidate_sets", "--workers", "2"], "give --seeds"),
        (["train", "ppo_candidate_sets", "--seed", "1", "--seeds", "2"], "not allowed with argument"),
    ):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 2
        assert needle in capsys.readouterr().err


def test_overrides_parse_as_yaml_values() -> None:
    assert parse_overrides(["ppo.learning_rate=1e-3", "crowd_sizes=[2, 4]"]) == {"ppo.learning_rate": 1e-3, "crowd_sizes": [2, 4]}
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_overrides(["learning_rate"])


def test_a_dotted_override_of_env_kwargs_keeps_the_other_conditions() -> None:
    shipped = load_train_config("ppo_mcl_bearing")
    config = load_train_config("ppo_mcl_bearing", {"env_kwargs.belief_spread": True, "env_kwargs.camera.fov_rad": 1.0})
    assert config.env_kwargs == {
        **shipped.env_kwargs,
        "camera": {**shipped.env_kwargs["camera"], "fov_rad": 1.0},
        "belief_spread": True,
    }


def test_a_replacement_sets_a_field_whole_and_overrides_merge_on_top() -> None:
    """--set env_kwargs={} merges nothing; --replace env_kwargs={} drops the file's conditions (the camera,
    which another world's env refuses), and --set then merges on top of the replacement."""
    shipped = load_train_config("ppo_mcl_bearing")
    assert load_train_config("ppo_mcl_bearing", {"env_kwargs": {}}).env_kwargs == shipped.env_kwargs
    room = {"env_id": "crowdloc/CrowdedRoom-v0", "localizer": "mcl_lidar", "crowd_sizes": [4]}
    config = load_train_config("ppo_mcl_bearing", {**room, "env_kwargs.prior": "none"}, {"env_kwargs": {}})
    assert config.env_kwargs == {"prior": "none"} and config.reward == shipped.reward
    check_train_config(config)  # the room builds: no camera key left
    with pytest.raises(ConfigError, match="unknown env keyword 'camera'"):
        check_train_config(load_train_config("ppo_mcl_bearing", room))
    replaced = load_train_config("ppo_mcl_bearing", None, {"env_kwargs.camera": {"fov_rad": 1.0}})
    assert replaced.env_kwargs["camera"] == {"fov_rad": 1.0}  # the camera's distractors: [] went with it
    with pytest.raises(ConfigError, match=r"replacement 'name.x' of .*ppo_mcl_bearing.yaml: 'name' is 'ppo_mcl_bearing', not a"):
        load_train_config("ppo_mcl_bearing", None, {"name.x": 1})
    with pytest.raises(ConfigError, match="unknown key 'env_kwarg'"):
        load_train_config("ppo_mcl_bearing", None, {"env_kwarg": {}})


def test_the_train_command_replaces_env_kwargs(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    argv = ["train", "ppo_mcl_bearing", "--set", "env_id=crowdloc/CrowdedRoom-v0", "--set", "localizer=mcl_lidar",
            "--set", "crowd_sizes=[4]", "--total-timesteps", "1", "--out", str(tmp_path), "--no-progress",
            "--set", "n_envs=1", "--set", "ppo.n_steps=8", "--set", "ppo.batch_size=8"]  # fmt: skip
    with pytest.raises(SystemExit):
        main([*argv, "--set", "env_kwargs={}"])
    assert "unknown env keyword 'camera'" in capsys.readouterr().err
    assert main([*argv, "--replace", "env_kwargs={}"]) == 0
    assert (tmp_path / "ppo_mcl_bearing" / "seed_0" / "model.zip").is_file()
    with pytest.raises(SystemExit):
        main([*argv, "--replace", "env_kwargs"])
    assert "--replace 'env_kwargs' is not KEY=VALUE" in capsys.readouterr().err


@pytest.mark.parametrize("name", ["ppo_candidate_sets", "ppo_mcl_bearing"])
def test_shipped_experiment_configs_load(name: str) -> None:
    config = load_train_config(name)
    assert config.ppo.n_steps >= 100 and np.all(np.asarray(config.crowd_sizes) <= 14)


def test_the_step_total_is_rounded_up_to_whole_rollouts(tmp_path: Path) -> None:
    from stable_baselines3.common.callbacks import BaseCallback

    seen: list[int] = []

    class Total(BaseCallback):
        def _on_training_start(self) -> None:
            seen.append(self.model._total_timesteps)  # what the progress bar counts to

        def _on_step(self) -> bool:
            return True

    config = tiny(100)  # rollouts of 2 envs x 32 steps = 64: two of them
    path = train(config, tmp_path, progress_bar=False, extra_callbacks=[Total()])
    from stable_baselines3 import PPO

    assert seen == [128] and PPO.load(path, device="cpu").num_timesteps == 128


class EndsEarly(gym.Wrapper):
    """Terminates each episode after 3 to 20 steps, drawn from its reset seed: episodes end inside the
    32-step rollouts of :func:`tiny`, as the corridor's and the campus's do when the robot stops at the goal."""

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        assert seed is not None  # EpisodeSeeds gives every episode its seed
        self.left = 3 + seed % 18
        return self.env.reset(seed=seed, options=options)

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.left -= 1
        return obs, float(reward), terminated or self.left == 0, truncated, info


@pytest.fixture
def early_ending_tasks(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every training task ends its episodes early (:class:`EndsEarly`); subproc envs fork, so that they see it too."""
    import stable_baselines3.common.vec_env as vec_env

    import agents.rl.train as train_module

    real = train_module.make_task_env
    monkeypatch.setattr(train_module, "make_task_env", lambda *args, **kwargs: EndsEarly(real(*args, **kwargs)))

    class ForkedSubprocVecEnv(vec_env.SubprocVecEnv):
        def __init__(self, env_fns: list[Any], start_method: str | None = None) -> None:
            super().__init__(env_fns, start_method="fork")

    monkeypatch.setattr(vec_env, "SubprocVecEnv", ForkedSubprocVecEnv)


def episodes(path: Path) -> list[tuple[float, int]]:
    """The (return, length) of the episodes ``model.zip`` logged last (its ``ep_info_buffer``: ep_rew_mean)."""
    from stable_baselines3 import PPO

    return [(info["r"], info["l"]) for info in PPO.load(path, device="cpu").ep_info_buffer]


@pytest.mark.parametrize("vec_env", ["dummy", "subproc"])
@pytest.mark.usefixtures("early_ending_tasks")
def test_resume_is_exact_when_episodes_end_inside_rollouts(tmp_path: Path, vec_env: str) -> None:
    """Envs are mid-episode at every checkpoint, having played more episodes than rollouts: the resumed runs
    (from a checkpoint written during a run, and from a run's last one) equal the straight run bit for bit."""
    straight = train(tiny(192, vec_env=vec_env), tmp_path / "straight", progress_bar=False)
    lengths = [length for _, length in episodes(straight)]
    assert len(lengths) > 2 * 192 // 32 and len(set(lengths)) > 3  # many episodes, of varied lengths
    config = tiny(192, vec_env=vec_env)
    during = run_dir(config, tmp_path / "straight") / "checkpoints" / "step_128.zip"
    train(tiny(64, vec_env=vec_env), tmp_path / "pieces", progress_bar=False)
    last = latest_checkpoint(config, tmp_path / "pieces")
    assert last is not None and last.name == "step_64.zip"
    for checkpoint, out in ((during, "from_128"), (last, "pieces")):
        resumed = train(config, tmp_path / out, resume=checkpoint, progress_bar=False)
        for x, y in zip(weights(straight), weights(resumed), strict=True):
            torch.testing.assert_close(x, y, rtol=0, atol=0)
        assert episodes(resumed) == episodes(straight)


@pytest.mark.usefixtures("early_ending_tasks")
def test_a_checkpoint_that_does_not_replay_or_predates_replay_is_refused(tmp_path: Path) -> None:
    """A checkpoint of another env count or without env positions (written before exact resume) is refused
    before anything is written; one whose envs do not replay to where the run had them, naming the env."""
    import dataclasses
    import pickle

    train(tiny(64), tmp_path, progress_bar=False)
    checkpoint = latest_checkpoint(tiny(128), tmp_path)
    assert checkpoint is not None
    run_json = run_dir(tiny(128), tmp_path) / "run.json"
    written = run_json.read_text()
    state_path = checkpoint.with_suffix(".state.pkl")
    state = pickle.loads(state_path.read_bytes())
    first = state["envs"][0]
    assert len(first.actions)  # mid-episode
    for changed, needle, before_writing in (
        ({"envs": state["envs"][:1]}, "has 1 envs, the config n_envs=2", True),
        ({"envs": None}, "predates exact resume", True),
        (
            {"envs": [dataclasses.replace(first, actions=np.repeat(first.actions, 20, axis=0)), *state["envs"][1:]]},
            "ended after",
            False,
        ),
        (
            {"envs": [dataclasses.replace(first, actions=first.actions[:-1]), *state["envs"][1:]]},
            "env 0, .*observation after",
            False,
        ),
    ):
        changed_state = {key: value for key, value in {**state, **changed}.items() if value is not None}
        state_path.write_bytes(pickle.dumps(changed_state))
        with pytest.raises(ConfigError, match=f"checkpoint {re.escape(str(checkpoint))}.*{needle}"):
            train(tiny(128), tmp_path, resume=checkpoint, progress_bar=False)
        if before_writing:
            assert run_json.read_text() == written
