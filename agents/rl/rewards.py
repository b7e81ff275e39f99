"""The active-localization reward: be localized, be localized early, don't bump into people.

The reward is computed from ``info`` (the truth and the localizer's estimate), which the
policy never observes. Per step:

    r = - position * min(|p_est - p_true|, position_clip_m)
        - heading * |wrap(theta_est - theta_true)|
        - no_fix                      while there is no valid estimate
        + first_fix_bonus             once, on the first step with a valid estimate
        - collision                   on a step where our robot starts touching something

Each term goes into ``info["reward_terms"]``; they sum to the reward.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from localizers.geometry import wrap_angle
from localizers.schema import check, from_mapping

TERMS = ("position", "heading", "no_fix", "first_fix", "collision")


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms (all >= 0; the sign is in the formula)."""

    position: float = 1.0  # per metre of position error
    position_clip_m: float = 1.0  # position errors are clipped here (a lost robot is just lost)
    heading: float = 0.3  # per radian of heading error
    no_fix: float = 1.0  # per step without a valid estimate
    first_fix_bonus: float = 5.0  # once per episode
    collision: float = 0.5  # per step in which our robot starts touching anything

    def __post_init__(self) -> None:
        for name in ("position", "position_clip_m", "heading", "no_fix", "first_fix_bonus", "collision"):
            check(getattr(self, name) >= 0, f"reward weight {name} must be >= 0, got {getattr(self, name)!r}")


class ActiveLocalizationReward(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replace the env's reward by the active-localization reward.

    Args:
        env: a crowdloc env wrapped by ``LocalizationObservation`` (``info["estimate"]``).
        weights: :class:`RewardWeights` or a mapping of overrides.
    """

    def __init__(self, env: gym.Env[Any, Any], weights: RewardWeights | Mapping[str, Any] | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, weights=weights)
        gym.Wrapper.__init__(self, env)
        if weights is None:
            weights = RewardWeights()
        elif not isinstance(weights, RewardWeights):
            weights = from_mapping(RewardWeights, dict(weights), where="reward weights")
        self.weights = weights
        self._had_fix = False

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        if "estimate" not in info:
            raise KeyError("ActiveLocalizationReward needs a localizer: make the env with localizer=...")
        self._had_fix = bool(info["estimate"].valid)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, _, terminated, truncated, info = self.env.step(action)
        terms = self.terms(info)
        info["reward_terms"] = terms
        return obs, float(sum(terms.values())), terminated, truncated, info

    def terms(self, info: Mapping[str, Any]) -> dict[str, float]:
        """The reward terms of one step (advances the first-fix bookkeeping)."""
        w = self.weights
        est = info["estimate"]
        truth = np.asarray(info["true_pose"], dtype=np.float64)
        terms = dict.fromkeys(TERMS, 0.0)
        if est.valid:
            error = float(np.hypot(est.x_m - truth[0], est.y_m - truth[1]))
            terms["position"] = -w.position * min(error, w.position_clip_m)
            terms["heading"] = -w.heading * abs(float(wrap_angle(est.theta_rad - truth[2])))
            if not self._had_fix:
                terms["first_fix"] = w.first_fix_bonus
                self._had_fix = True
        else:
            terms["no_fix"] = -w.no_fix
        if info.get("contacts"):
            terms["collision"] = -w.collision
        return terms
