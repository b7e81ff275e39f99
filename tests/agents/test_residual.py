"""Residual actions (``action.residual_to``): the policy's action corrects a fixed policy's command.

A zero correction drives exactly as the fixed policy does on the plain task; a correction is added,
scaled and clipped; the policy observes the base's command; ``crowdloc eval`` gives the residual to
trained policies only, and refuses a residual model where no base adds its command."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import yaml

from agents.cli import build_parser
from agents.evaluate import EvalSpec, run_cli
from agents.evaluate.spec import task_conditions
from agents.policies.fixed import make_policy, task_route_kwargs
from agents.rl.config import EXPERIMENT_DIR, load_train_config
from agents.rl.observation import ObservationConfig
from agents.rl.residual import BASE_KEY, MODEL_ACTION_ATTR, ActionConfig, ResidualAction, check_trained_action
from agents.rl.train import make_task_env
from core.schema import ConfigError

#: training config -> the fixed policy a residual corrects there
BASES = {"ppo_room_lidar": "route_follower", "ppo_corridor_targets": "corridor_follower"}


def _plain(name: str) -> Any:
    """The training config with the world's whole observation and plain commands (what a fixed policy drives)."""
    return dataclasses.replace(load_train_config(name), observation=ObservationConfig(), action=ActionConfig())


class _Sent(gym.Wrapper):  # type: ignore[type-arg]
    """Records the commands that reach the task."""

    def __init__(self, env: gym.Env[Any, Any]) -> None:
        super().__init__(env)
        self.sent: list[np.ndarray] = []

    def step(self, action: Any) -> Any:
        self.sent.append(np.asarray(action, dtype=np.float64).copy())
        return self.env.step(action)


@pytest.mark.parametrize("name", sorted(BASES))
def test_a_zero_correction_drives_exactly_as_the_base_policy_on_the_plain_task(name: str) -> None:
    config = _plain(name)
    base = BASES[name]
    plain = make_task_env(config, None)
    residual = make_task_env(dataclasses.replace(config, action=ActionConfig(residual_to=base)), None)
    assert isinstance(residual, ResidualAction) and set(residual.observation_space.spaces) == {  # type: ignore[union-attr]
        *plain.observation_space.spaces, BASE_KEY}  # type: ignore[union-attr]  # fmt: skip
    driver = make_policy(base, plain, seed=0, **task_route_kwargs(base, config.route.points_m))
    obs_p, _ = plain.reset(seed=4)
    obs_r, _ = residual.reset(seed=4)
    commands = []
    for step in range(80):
        command, _ = driver.predict(obs_p, deterministic=True)
        np.testing.assert_array_equal(obs_r[BASE_KEY], command, err_msg=f"step {step}")
        assert residual.observation_space.contains(obs_r)
        obs_p, reward_p, *_ = plain.step(command)
        obs_r, reward_r, *_ = residual.step(np.zeros(2, dtype=np.float32))
        assert reward_r == reward_p, f"step {step}"
        np.testing.assert_array_equal(obs_r["estimate"], obs_p["estimate"])
        commands.append(tuple(command))
    assert len(set(commands)) > 3, "the base drove (the comparison is not of standing still)"
    plain.close(), residual.close()


#: an action number -> the correction it makes with a deadband of 0.25 (0 within it, then linear to 1 at 1)
DEADBAND = {0.0: 0.0, 0.2: 0.0, -0.25: 0.0, 0.3: 0.05 / 0.75, -0.7: -0.45 / 0.75, 1.0: 1.0, -1.0: -1.0, 5.0: 1.0}


@pytest.mark.parametrize("band", [0.0, 0.25])
def test_the_command_sent_is_the_base_plus_the_scaled_correction_clipped(band: float) -> None:
    config = _plain("ppo_room_lidar")
    action = ActionConfig(residual_to="route_follower", residual_scale=0.5, deadband=band)
    env = ResidualAction(_Sent(make_task_env(config, None)), action, config.route)
    obs, _ = env.reset(seed=1)
    numbers = sorted(DEADBAND)
    for i in range(40):
        correction = (numbers[i % len(numbers)], numbers[(3 * i + 1) % len(numbers)])
        made = [DEADBAND[c] if band else float(np.clip(c, -1, 1)) for c in correction]  # outside [-1, 1]: clipped first
        base = np.asarray(obs[BASE_KEY], dtype=np.float64)
        obs, *_ = env.step(np.asarray(correction, dtype=np.float32))
        expected = np.clip(base + 0.5 * np.asarray(made), -1, 1)
        np.testing.assert_allclose(env.env.sent[-1], expected, atol=1e-6)  # type: ignore[attr-defined]
        np.testing.assert_allclose(env.command, expected, atol=1e-7)
    with pytest.raises(ValueError, match=r"2 finite numbers, got .*nan"):
        env.step(np.array([np.nan, 0.0], dtype=np.float32))
    env.close()


def test_bad_action_settings_name_the_field_and_the_value() -> None:
    with pytest.raises(ConfigError, match=r"action.residual_to must be a fixed policy .*route_follower.*got 'nope'"):
        load_train_config("ppo_campus_stereo", {"action.residual_to": "nope"})
    for bad in (0, -1.0, float("nan"), float("inf"), "2", True):
        with pytest.raises(ConfigError, match=r"action.residual_scale must be finite and > 0, got"):
            ActionConfig(residual_to="route_follower", residual_scale=bad)  # type: ignore[arg-type]
    for bad in (-0.1, 1.0, float("nan"), "0.1", False):
        with pytest.raises(ConfigError, match=r"action.deadband must be in \[0, 1\), got"):
            ActionConfig(residual_to="route_follower", deadband=bad)  # type: ignore[arg-type]
    room = make_task_env(_plain("ppo_room_lidar"), None)
    with pytest.raises(ConfigError, match=r"needs action.residual_to"):
        ResidualAction(room, ActionConfig())
    with pytest.raises(ConfigError, match=r"action.residual_to 'corridor_follower' cannot drive this task: .*ceiling"):
        ResidualAction(room, ActionConfig(residual_to="corridor_follower"))
    room.close()


def test_eval_gives_the_residual_to_trained_policies_only_and_refuses_a_residual_model_without_it(tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    data = yaml.safe_load((EXPERIMENT_DIR / "ppo_room_lidar.yaml").read_text())
    data["action"] = {"residual_to": "route_follower"}
    conditions = tmp_path / "room_residual.yaml"
    conditions.write_text(yaml.safe_dump(data))
    config = load_train_config(conditions)
    env = make_task_env(config, 8)
    assert BASE_KEY in env.observation_space.spaces  # type: ignore[attr-defined]  # the task's observation keeps it
    model = tmp_path / "model.zip"
    PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu").save(model)
    env.close()

    def args(conditions_: str, out: str) -> Any:
        return build_parser(["eval"]).parse_args(
            ["eval", "--conditions", conditions_, "--crowd-sizes", "8", "--seeds", "2", "--episode-steps", "12", "--workers",
             "1", "--no-gif", "--no-progress", "--out", str(tmp_path / out), "--policies", f"ppo:{model}", "route_follower"]
        )  # fmt: skip

    result = run_cli(args(str(conditions), "residual"))
    spec = result.spec
    assert spec.action == config.action == ActionConfig(residual_to="route_follower")
    trained, fixed = (spec.make_env(p, "mcl_lidar", 8) for p in (f"ppo:{model}", "route_follower"))
    assert BASE_KEY in trained.observation_space.spaces and BASE_KEY not in fixed.observation_space.spaces  # type: ignore[attr-defined]
    wrappers = []
    env_: Any = trained
    while isinstance(env_, gym.Wrapper):
        wrappers.append(type(env_))
        env_ = env_.env
    assert ResidualAction in wrappers
    trained.close(), fixed.close()
    assert len(result.episodes) == 4
    assert '"residual_to": "route_follower"' in (tmp_path / "residual" / "run.json").read_text()  # the record says so
    # the model on the plain task's conditions: no base adds its command, and eval says so
    with pytest.raises(ConfigError, match=BASE_KEY):
        run_cli(args("ppo_room_lidar", "plain"))
    assert not (tmp_path / "plain").exists() or not any((tmp_path / "plain").iterdir())


def test_crowdloc_train_trains_a_residual_policy_and_records_its_action(tmp_path: Path) -> None:
    import json

    from stable_baselines3 import PPO

    from agents.rl.train import train

    overrides = {"n_envs": 2, "vec_env": "dummy", "ppo.n_steps": 64, "ppo.batch_size": 64, "total_timesteps": 128,
                 "checkpoint_every": 10**9, "action.residual_to": "route_follower", "action.deadband": 0.1}  # fmt: skip
    config = load_train_config("ppo_room_lidar", overrides)
    path = train(config, tmp_path, progress_bar=False)
    model = PPO.load(path, device="cpu")
    assert BASE_KEY in model.observation_space.spaces  # type: ignore[attr-defined]
    trained = {"residual_to": "route_follower", "residual_scale": 2.0, "deadband": 0.1}
    (record,) = tmp_path.rglob("run.json")
    assert json.loads(record.read_text())["config"]["action"] == trained
    # the model itself records its action, and eval refuses it under another one (which nothing else would tell)
    assert getattr(model, MODEL_ACTION_ATTR) == trained
    other = dataclasses.replace(config, action=ActionConfig(residual_to="route_follower", deadband=0.2))
    grid = {"policies": (f"ppo:{path}",), "crowd_sizes": (8,), "seeds": 1, "episode_steps": 5}
    with pytest.raises(
        ConfigError, match=r"was trained with action .*'deadband': 0.1.* and these conditions give .*'deadband': 0.2"
    ):
        EvalSpec(**grid, **task_conditions(other))
    assert EvalSpec(**grid, **task_conditions(config)).action == config.action
    check_trained_action("ppo:old", object(), ActionConfig())  # a model without the record (trained before it): no check
