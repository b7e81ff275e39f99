"""Same seed, same rollout; a different seed, a different one."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)

STEPS = 500

# (id, kwargs): the crowded field with its full crowd and ball, the room with queues and walkers
ROLLOUTS = [
    ("crowdloc/RoboCupCrowded-v0", {"crowd_size": 14}),
    ("crowdloc/CrowdedRoom-v0", {"crowd": {"walkers": {"count": 6}}}),
]


def rollout(env_id: str, kwargs: dict, seed: int, action_seed: int) -> list[tuple]:
    """``STEPS`` steps of seeded random actions; returns (obs, true_pose, reward, contacts) per step."""
    env = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(action_seed).uniform(-1, 1, size=(STEPS, 2)).astype(np.float32)
    obs, info = env.reset(seed=seed)
    out = [(obs, info["true_pose"], 0.0, [])]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        assert not terminated and not truncated
        out.append((obs, info["true_pose"], reward, info["contacts"]))
    env.close()
    return out


def assert_same_step(a: tuple, b: tuple, step: int) -> None:
    obs_a, pose_a, reward_a, contacts_a = a
    obs_b, pose_b, reward_b, contacts_b = b
    assert obs_a.keys() == obs_b.keys()
    for key in obs_a:
        np.testing.assert_array_equal(obs_a[key], obs_b[key], err_msg=f"step {step}: observation {key!r}")
    np.testing.assert_array_equal(pose_a, pose_b, err_msg=f"step {step}: true_pose")
    assert reward_a == reward_b, step
    assert contacts_a == contacts_b, step


@pytest.mark.parametrize(("env_id", "kwargs"), ROLLOUTS, ids=[r[0] for r in ROLLOUTS])
def test_same_seed_gives_the_identical_rollout(env_id: str, kwargs: dict) -> None:
    # two envs stepped side by side in one process, so shared state between instances would show
    env_a = gym.make(env_id, **kwargs)
    env_b = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(99).uniform(-1, 1, size=(STEPS, 2)).astype(np.float32)
    obs_a, info_a = env_a.reset(seed=123)
    obs_b, info_b = env_b.reset(seed=123)
    assert_same_step((obs_a, info_a["true_pose"], 0.0, []), (obs_b, info_b["true_pose"], 0.0, []), 0)
    crowd_a = env_a.unwrapped.world.positions.copy()
    moved = False
    for step, action in enumerate(actions, start=1):
        obs_a, r_a, _, _, info_a = env_a.step(action)
        obs_b, r_b, _, _, info_b = env_b.step(action.copy())
        assert_same_step(
            (obs_a, info_a["true_pose"], r_a, info_a["contacts"]),
            (obs_b, info_b["true_pose"], r_b, info_b["contacts"]),
            step,
        )
        np.testing.assert_array_equal(env_a.unwrapped.world.positions, env_b.unwrapped.world.positions)
        moved |= not np.array_equal(env_a.unwrapped.world.positions[1:], crowd_a[1:])
    assert moved  # the crowd really moved, so the comparison covered its randomness
    env_a.close()
    env_b.close()


@pytest.mark.parametrize(("env_id", "kwargs"), ROLLOUTS, ids=[r[0] for r in ROLLOUTS])
def test_reset_with_the_same_seed_replays_the_episode(env_id: str, kwargs: dict) -> None:
    env = gym.make(env_id, **kwargs)
    actions = np.random.default_rng(5).uniform(-1, 1, size=(60, 2)).astype(np.float32)
    runs = []
    for _ in range(2):
        obs, info = env.reset(seed=7)
        steps = [(obs, info["true_pose"], 0.0, [])]
        for a in actions:
            obs, r, _, _, info = env.step(a)
            steps.append((obs, info["true_pose"], r, info["contacts"]))
        runs.append(steps)
    for step, (a, b) in enumerate(zip(*runs)):
        assert_same_step(a, b, step)
    env.close()


@pytest.mark.parametrize(("env_id", "kwargs"), ROLLOUTS, ids=[r[0] for r in ROLLOUTS])
def test_a_different_seed_gives_a_different_rollout(env_id: str, kwargs: dict) -> None:
    a = rollout(env_id, kwargs, seed=1, action_seed=0)
    b = rollout(env_id, kwargs, seed=2, action_seed=0)
    # the same actions: only the env's randomness differs
    differs = [not np.array_equal(x[1], y[1]) for x, y in zip(a, b)]
    assert all(differs[len(differs) // 2 :])
    obs_differs = [any(not np.array_equal(x[0][k], y[0][k]) for k in x[0]) for x, y in zip(a, b)]
    assert all(obs_differs[1:])


@pytest.mark.parametrize(
    ("env_id", "sensor_kwargs"),
    [
        ("crowdloc/CrowdedRoom-v0", {"lidar": {"range_std_m": 0.0}, "odometry": {"alpha1": 0.0, "alpha3": 0.2}}),
        ("crowdloc/RoboCupCrowded-v0", {"camera": {"noise_std_rad": 0.0, "dropout_probability": 0.3}}),
    ],
)
def test_sensor_settings_do_not_change_how_the_world_moves(env_id: str, sensor_kwargs: dict) -> None:
    plain = gym.make(env_id, crowd_size=8)
    changed = gym.make(env_id, crowd_size=8, **sensor_kwargs)
    actions = np.random.default_rng(3).uniform(-1, 1, size=(150, 2)).astype(np.float32)
    plain.reset(seed=11)
    changed.reset(seed=11)
    for a in actions:
        _, _, _, _, info_p = plain.step(a)
        _, _, _, _, info_c = changed.step(a)
        np.testing.assert_array_equal(info_p["true_pose"], info_c["true_pose"])
        np.testing.assert_array_equal(plain.unwrapped.world.positions, changed.unwrapped.world.positions)
