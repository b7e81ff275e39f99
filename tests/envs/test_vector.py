"""``gym.make_vec`` works on every id, with and without a localizer, in both vectorization modes,
over episodes that end and restart: every ``info`` entry a vector env stacks has a fixed shape."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)

CASES = [
    ("crowdloc/RoboCupCrowded-v0", {}),
    ("crowdloc/RoboCupCrowded-v0", {"localizer": "candidate_sets", "camera": {"false_detection_probability": 0.1}}),
    ("crowdloc/CrowdedRoom-v0", {"lidar": {"beams": 91}}),
]


@pytest.mark.parametrize("mode", ["sync", "async"])
@pytest.mark.parametrize(("env_id", "kwargs"), CASES, ids=["crowded", "crowded+localizer", "room"])
def test_make_vec_steps_through_episode_ends(env_id: str, kwargs: dict, mode: str) -> None:
    vec = gym.make_vec(env_id, num_envs=3, vectorization_mode=mode, max_episode_steps=7, **kwargs)
    try:
        obs, info = vec.reset(seed=[0, 1, 2])
        assert vec.observation_space.contains(obs)
        ended = 0
        for _ in range(16):  # two and a bit episodes per env
            obs, reward, terminated, truncated, info = vec.step(vec.action_space.sample())
            assert vec.observation_space.contains(obs) and reward.shape == (3,)
            ended += int(np.sum(terminated | truncated))
        assert ended >= 6
        assert info["true_pose"].shape == (3, 3)
        if "visible_landmarks" in info:
            assert info["visible_landmarks"].shape == (3, 8) and info["visible_landmarks"].dtype == bool
            assert info["false_detections"].shape == (3, 8)
    finally:
        vec.close()


def test_spawned_workers_find_the_ids_through_the_module_prefix() -> None:
    # a worker started by spawn or forkserver has not imported envs: "envs:" imports it first
    from stable_baselines3.common.vec_env import SubprocVecEnv

    vec = SubprocVecEnv([lambda: gym.make("envs:crowdloc/RoboCupStatic-v0")] * 2, start_method="spawn")
    try:
        obs = vec.reset()
        assert obs["odometry"].shape == (2, 3)
        vec.step(np.zeros((2, 2), dtype=np.float32))
    finally:
        vec.close()


def test_an_env_says_it_cannot_be_pickled() -> None:
    import copy
    import pickle

    env = gym.make("crowdloc/RoboCupStatic-v0")
    for attempt in (lambda: copy.deepcopy(env), lambda: pickle.dumps(env.unwrapped)):
        with pytest.raises(TypeError, match="cannot be pickled or deep-copied .* gym.make"):
            attempt()
