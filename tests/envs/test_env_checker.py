"""Gymnasium's and stable-baselines3's environment checkers on every registered id, warnings as errors."""

from __future__ import annotations

import warnings
from collections.abc import Callable

import gymnasium as gym
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import envs

ENV_IDS = sorted(envs.ENV_WORLDS)


def run_without_warnings(check: Callable[[gym.Env], object], env: gym.Env) -> None:
    """Run ``check(env)`` turning every warning into an error, and record none."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("error")
        check(env)
    assert caught == []


def test_every_shipped_world_is_registered() -> None:
    assert sorted(envs.ENV_WORLDS.values()) == envs.available_worlds()
    for env_id in ENV_IDS:
        assert env_id in gym.registry
        assert env_id.startswith("crowdloc/")


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env_on_the_unwrapped_env(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        # rendering is covered by tests/envs/test_render.py
        run_without_warnings(lambda e: gym_check_env(e, skip_render_check=True), env.unwrapped)
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env_on_the_made_env(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            gym_check_env(env, skip_render_check=True)
        # check_env announces that it was given a wrapped env (TimeLimit, OrderEnforcing,
        # PassiveEnvChecker around ours) whatever the env; that notice is about the checker's
        # input and must be the only warning
        messages = [str(w.message) for w in caught]
        assert len(messages) == 1, messages
        assert "is different from the unwrapped version" in messages[0]
        # and the made env runs its passive checker through reset and steps without a warning
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("error")
            env.reset(seed=0)
            for _ in range(5):
                env.step(env.action_space.sample())
        assert caught == []
    finally:
        env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_stable_baselines3_check_env(env_id: str) -> None:
    env = gym.make(env_id)
    try:
        run_without_warnings(lambda e: sb3_check_env(e, warn=True, skip_render_check=True), env)
    finally:
        env.close()


def test_checkers_pass_with_an_added_sonar_ring() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", sonar={})
    try:
        run_without_warnings(lambda e: gym_check_env(e, skip_render_check=True), env.unwrapped)
        run_without_warnings(lambda e: sb3_check_env(e, warn=True, skip_render_check=True), env)
    finally:
        env.close()
