"""The active-localization reward: terms sum to the reward, each term does what it says."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents.rl.rewards import TERMS, ActiveLocalizationReward, RewardWeights
from core.schema import ConfigError
from localizers.base import PoseEstimate


@pytest.mark.parametrize("localizer", ["candidate_sets", "mcl_bearing", "kalman"])
def test_reward_terms_sum_to_the_reward(localizer: str) -> None:
    env = ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer=localizer, crowd_size=10))
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    seen = set()
    for _ in range(300):
        _, reward, _, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
        terms = info["reward_terms"]
        assert set(terms) == set(TERMS)
        assert reward == pytest.approx(sum(terms.values()), abs=1e-12)
        seen |= {k for k, v in terms.items() if v != 0.0}
    assert {"position", "heading"} <= seen


def test_terms_follow_the_formula() -> None:
    env = ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer="mcl_bearing"), {"position_clip_m": 0.5})
    env.reset(seed=0)
    env._had_fix = False
    est = PoseEstimate(1.0, 1.0, 0.2, np.eye(3), True)
    terms = env.terms({"estimate": est, "true_pose": np.array([1.3, 1.4, -0.1]), "contacts": ["x"]})
    assert terms["position"] == pytest.approx(-0.5)  # 0.5 m error, clipped at 0.5
    assert terms["heading"] == pytest.approx(-0.3 * 0.3)
    assert terms["first_fix"] == pytest.approx(5.0)
    assert terms["collision"] == pytest.approx(-0.5)
    again = env.terms({"estimate": est, "true_pose": np.array([1.0, 1.1, 0.2 + 2 * math.pi]), "contacts": []})
    assert again["first_fix"] == 0.0  # the bonus comes once
    assert again["heading"] == pytest.approx(0.0, abs=1e-12)  # wrapped
    assert again["position"] == pytest.approx(-0.1)
    lost = env.terms({"estimate": PoseEstimate.invalid(), "true_pose": np.zeros(3), "contacts": []})
    assert lost["no_fix"] == pytest.approx(-1.0) and lost["position"] == 0.0


def test_a_wrong_pose_is_one_too_far_off_or_turned_too_far() -> None:
    weights = {"wrong_pose": 0.1, "wrong_pose_m": 1.0, "wrong_pose_rad": math.pi / 4}
    env = ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer="mcl_bearing"), weights)
    env.reset(seed=0)

    def wrong(dx: float, dtheta: float) -> float:
        est = PoseEstimate(1.0 + dx, 1.0, 0.5 + dtheta, np.eye(3), True)
        return env.terms({"estimate": est, "true_pose": np.array([1.0, 1.0, 0.5]), "contacts": []})["wrong_pose"]

    assert wrong(0.3, 0.1) == 0.0
    assert wrong(1.2, 0.0) == pytest.approx(-0.1)  # too far off
    assert wrong(0.1, math.pi) == pytest.approx(-0.1)  # a twin turned about a room's centre, near it
    assert wrong(0.1, -0.9) == pytest.approx(-0.1)
    position_only = ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer="mcl_bearing"), {"wrong_pose": 0.1})
    position_only.reset(seed=0)
    turned = PoseEstimate(1.1, 1.0, 0.5 + math.pi, np.eye(3), True)
    assert position_only.terms({"estimate": turned, "true_pose": np.array([1.0, 1.0, 0.5]), "contacts": []})["wrong_pose"] == 0.0
    with pytest.raises(ConfigError, match="wrong_pose_rad must be > 0, got 0.0"):
        RewardWeights(wrong_pose_rad=0.0)


def test_the_reward_needs_a_localizer_and_checks_its_weights() -> None:
    with pytest.raises(KeyError, match="localizer"):
        ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0")).reset(seed=0)
    with pytest.raises(ConfigError, match="no_fixx"):
        ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer="kalman"), {"no_fixx": 1.0})
    with pytest.raises(ConfigError, match="-1"):
        RewardWeights(collision=-1.0)


def test_the_policy_never_sees_the_truth_through_the_reward_wrapper() -> None:
    env = ActiveLocalizationReward(gym.make("crowdloc/RoboCupCrowded-v0", localizer="candidate_sets"))
    obs, info = env.reset(seed=2)
    rng = np.random.default_rng(2)
    for _ in range(100):
        truth = np.asarray(info["true_pose"])
        for key, leaf in obs.items():
            assert not np.any(np.isclose(np.asarray(leaf, np.float64).reshape(-1, 1), truth[None], atol=1e-6, rtol=0)), key
        obs, _, _, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
