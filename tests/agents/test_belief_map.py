"""The belief map: the localizer's own hypotheses bin by bin, its Gaussian for a one-pose
localizer, no ground truth, its config checks, and the CNN that reads it in training."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import torch as th

import envs  # noqa: F401  (registers the ids)
from agents.rl.belief_map import BeliefMapConfig, belief_map
from agents.rl.extractor import BeliefMapExtractor
from agents.rl.observation import ObservationConfig, TaskObservation
from core.schema import ConfigError, from_mapping
from core.types import Overlay, PoseEstimate


def _env(localizer: str, config: BeliefMapConfig, env_id: str = "crowdloc/RoboCupCrowded-v0") -> TaskObservation:
    return TaskObservation(gym.make(env_id, localizer=localizer), ObservationConfig(belief_map=config))


def _run(env: TaskObservation, steps: int, seed: int = 3) -> dict:
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, *_ = env.step(rng.uniform(-1, 1, env.action_space.shape).astype(np.float32))
    return obs


def reference(config: BeliefMapConfig, poses: np.ndarray, w: np.ndarray, centre: tuple[float, float, float]) -> np.ndarray:
    """The same map by another road: turn into the estimate's frame, clamp into the window, and
    count with ``np.histogramdd`` over explicit edges."""
    x0, y0, t0 = centre
    dx, dy = poses[:, 0] - x0, poses[:, 1] - y0
    u = math.cos(t0) * dx + math.sin(t0) * dy
    v = -math.sin(t0) * dx + math.cos(t0) * dy
    half = config.extent_m / 2
    inside = np.nextafter(half, 0.0)
    u, v = np.clip(u, -half, inside), np.clip(v, -half, inside)
    rel = np.angle(np.exp(1j * (poses[:, 2] - t0)))
    rel = np.where(rel >= math.pi, -math.pi, rel)
    edges_xy = np.linspace(-half, half, config.cells + 1)
    edges_h = np.linspace(-math.pi, math.pi, config.heading_bins + 1)
    counts, _ = np.histogramdd(np.stack([rel, v, u], axis=1), bins=[edges_h, edges_xy, edges_xy], weights=w / w.sum())
    return counts


@pytest.mark.parametrize(("localizer", "steps"), [("mcl_bearing", 40), ("candidate_sets", 90), ("mcl_bearing_paper", 40)])
def test_the_map_is_the_localizers_own_hypotheses_bin_by_bin(localizer: str, steps: int) -> None:
    config = BeliefMapConfig(cells=16, heading_bins=4, extent_m=3.0)
    env = _env(localizer, config)
    obs = _run(env, steps)
    loc = env.get_wrapper_attr("localizer")
    est = env.get_wrapper_attr("estimate")
    overlay = loc.overlay()
    if localizer.startswith("mcl"):
        np.testing.assert_array_equal(overlay.poses, loc.particles)  # the overlay is the particle set itself
    assert est.valid and len(overlay.poses) > 1
    expected = reference(config, overlay.poses, overlay.weights, (est.x_m, est.y_m, est.theta_rad))
    assert obs["belief_map"].shape == config.shape and obs["belief_map"].dtype == np.float32
    np.testing.assert_allclose(obs["belief_map"], expected, atol=1e-6)
    assert obs["belief_map"].sum() == pytest.approx(1.0, abs=1e-5)
    assert env.observation_space.contains(obs)


def test_the_world_frame_covers_the_world_and_keeps_world_headings() -> None:
    config = BeliefMapConfig(cells=10, heading_bins=2, frame="world")
    bounds = (0.0, 0.0, 10.0, 5.0)
    poses = np.array([[0.5, 0.25, 0.1], [9.99, 4.99, -0.1], [5.0, 2.5, 3.0]])
    got = belief_map(config, Overlay(poses=poses, weights=np.array([1.0, 1.0, 2.0])), PoseEstimate.invalid(), bounds)
    assert got[1, 0, 0] == pytest.approx(0.25)  # heading 0.1 in [0, pi): channel 1; the cell of (0.5, 0.25)
    assert got[0, 9, 9] == pytest.approx(0.25)  # heading -0.1: channel 0; the far corner's cell
    assert got[1, 5, 5] == pytest.approx(0.5)  # the centre, twice the weight
    assert got.sum() == pytest.approx(1.0)


def test_far_hypotheses_count_in_the_border_cell_nearest_them() -> None:
    config = BeliefMapConfig(cells=4, heading_bins=1, extent_m=2.0)
    est = PoseEstimate(0.0, 0.0, 0.0)
    poses = np.array([[100.0, 0.1, 0.0], [-100.0, -100.0, 0.0]])
    got = belief_map(config, Overlay(poses=poses, weights=np.ones(2)), est, (0, 0, 1, 1))
    assert got[0, 2, 3] == pytest.approx(0.5) and got[0, 0, 0] == pytest.approx(0.5)


def test_the_window_turns_with_the_estimate() -> None:
    config = BeliefMapConfig(cells=4, heading_bins=4, extent_m=4.0)
    est = PoseEstimate(1.0, 1.0, math.pi / 2)  # facing +y
    ahead = np.array([[1.0, 2.5, math.pi / 2]])  # 1.5 m ahead, facing the same way
    got = belief_map(config, Overlay(poses=ahead, weights=np.ones(1)), est, (0, 0, 5, 5))
    # ahead is +u (column 3), on the centre line v = 0 (row 2), relative heading 0 (channel 2 of 4)
    assert got[2, 2, 3] == pytest.approx(1.0)


def test_no_hypothesis_gives_zeros() -> None:
    config = BeliefMapConfig(cells=8)
    for overlay in (Overlay(), Overlay(poses=np.zeros((2, 3)), weights=np.zeros(2))):
        got = belief_map(config, overlay, PoseEstimate.invalid(), (0, 0, 1, 1))
        assert got.shape == config.shape and not got.any()


def test_without_a_valid_estimate_the_window_centres_on_the_hypotheses() -> None:
    config = BeliefMapConfig(cells=4, heading_bins=1, extent_m=2.0)
    poses = np.array([[10.2, 20.2, 0.0], [9.8, 19.8, 0.0]])
    got = belief_map(config, Overlay(poses=poses, weights=np.ones(2)), PoseEstimate.invalid(), (0, 0, 30, 30))
    assert got[0, 2, 2] == pytest.approx(0.5) and got[0, 1, 1] == pytest.approx(0.5)


def test_a_one_pose_localizer_renders_its_gaussian() -> None:
    config = BeliefMapConfig(cells=21, heading_bins=4, extent_m=4.0)
    cov = np.diag([0.2**2, 0.5**2, 0.3**2])
    est = PoseEstimate(2.0, 3.0, 0.4, cov)
    got = belief_map(config, Overlay(poses=est.as_array()[None, :], weights=np.ones(1)), est, (0, 0, 5, 5)).astype(float)
    assert got.sum() == pytest.approx(1.0, abs=1e-5)
    # the heading channels: the normal's mass in each quarter turn around 0 (relative to the estimate)
    edges = np.linspace(-math.pi, math.pi, 5)
    cdf = np.array([0.5 * (1 + math.erf(e / (0.3 * math.sqrt(2)))) for e in edges])
    np.testing.assert_allclose(got.sum(axis=(1, 2)), np.diff(cdf), atol=1e-5)
    # the position: the peak at the centre cell; x (columns, the estimate's heading; no turn here as
    # theta is turned away) spreads less than y
    plane = got.sum(axis=0)
    assert np.unravel_index(plane.argmax(), plane.shape) == (10, 10)
    centres = (np.arange(21) + 0.5) / 21 * 4.0 - 2.0
    sd_col = math.sqrt(float(plane.sum(axis=0) @ centres**2))
    sd_row = math.sqrt(float(plane.sum(axis=1) @ centres**2))
    # turned by the estimate's heading 0.4 rad: the window's axes mix the world's sds
    c, s = math.cos(0.4), math.sin(0.4)
    assert sd_col == pytest.approx(math.sqrt(c * c * 0.04 + s * s * 0.25), rel=0.02)
    assert sd_row == pytest.approx(math.sqrt(s * s * 0.04 + c * c * 0.25), rel=0.02)


def test_kalman_in_the_env_gives_a_normalised_map() -> None:
    env = _env("kalman", BeliefMapConfig(cells=12, heading_bins=3, extent_m=3.0))
    obs = _run(env, 60)
    assert env.get_wrapper_attr("estimate").valid
    assert obs["belief_map"].sum() == pytest.approx(1.0, abs=1e-5)
    assert (obs["belief_map"] > 0).sum() > 3  # a spread, not one cell


def test_the_map_does_not_read_the_truth() -> None:
    """Move the robot (and so everything the truth could tell) without stepping the localizer:
    the map stays the same, bit for bit."""
    env = _env("mcl_bearing", BeliefMapConfig(cells=16, extent_m=3.0))
    obs = _run(env, 30)
    raw = env.env.observation_space.sample()  # the wrapper reads no sensor entry for the map
    base = env.unwrapped
    body = base.world.robot_body
    body.position = (body.position[0] + 1.3, body.position[1] - 0.7)
    body.angle += 2.0
    again = env.observation({**raw, **{k: v for k, v in obs.items() if k in raw}})
    np.testing.assert_array_equal(again["belief_map"], obs["belief_map"])


@pytest.mark.parametrize(
    ("mapping", "message"),
    [
        ({"cells": -1}, "cells must be in"),
        ({"cells": 8, "heading_bins": 0}, "heading_bins must be in"),
        ({"cells": 8, "frame": "robot"}, "frame must be one of estimate, world, got 'robot'"),
        ({"cells": 8, "extent_m": float("nan")}, "extent_m must be finite"),
    ],
)
def test_bad_settings_are_refused_with_their_value(mapping: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        from_mapping(ObservationConfig, {"belief_map": mapping}, "test")


def test_a_world_without_a_localizer_is_refused() -> None:
    with pytest.raises(ConfigError, match="belief_map is the localizer's belief"):
        TaskObservation(gym.make("crowdloc/RoboCupCrowded-v0"), ObservationConfig(belief_map=BeliefMapConfig(cells=8)))


def test_the_extractor_reads_the_map_with_a_cnn_and_flattens_the_rest() -> None:
    space = gym.spaces.Dict(
        {
            "belief_map": gym.spaces.Box(0, 1, (4, 32, 32), np.float32),
            "estimate": gym.spaces.Box(-1, 1, (7,), np.float32),
        }
    )
    extractor = BeliefMapExtractor(space, belief_features=64)
    assert extractor.features_dim == 64 + 7
    conv = sum(p.numel() for m in extractor.cnn if isinstance(m, th.nn.Conv2d) for p in m.parameters())
    linear = sum(p.numel() for m in extractor.cnn if isinstance(m, th.nn.Linear) for p in m.parameters())
    assert (conv, linear) == (9264, 32832)  # the module docstring's counts
    batch = {key: th.as_tensor(np.stack([sub.sample() for _ in range(5)])) for key, sub in space.spaces.items()}
    out = extractor(batch)
    assert out.shape == (5, 71)
    np.testing.assert_array_equal(out[:, 64:].detach().numpy(), batch["estimate"].numpy())
    with pytest.raises(ValueError, match="needs a 'belief_map' Box"):
        BeliefMapExtractor(gym.spaces.Dict({"estimate": space["estimate"]}))


def test_a_task_with_the_belief_map_trains_with_the_cnn_and_its_model_acts(tmp_path) -> None:
    from stable_baselines3 import PPO

    from agents.rl.config import load_train_config
    from agents.rl.train import make_training_env, train

    overrides = {
        "total_timesteps": 64, "n_envs": 2, "vec_env": "dummy", "checkpoint_every": 64, "crowd_sizes": [3],
        "ppo.n_steps": 32, "ppo.batch_size": 32, "ppo.n_epochs": 1, "ppo.net_arch": [16],
        "observation.belief_map": {"cells": 16, "heading_bins": 4, "extent_m": 3.0},
    }  # fmt: skip
    config = load_train_config("ppo_candidate_sets", overrides)
    model = PPO.load(train(config, tmp_path, progress_bar=False), device="cpu")
    assert isinstance(model.policy.features_extractor, BeliefMapExtractor)
    env = make_training_env(config, 0)
    obs, _ = env.reset(seed=0)
    assert obs["belief_map"].shape == (4, 16, 16)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
