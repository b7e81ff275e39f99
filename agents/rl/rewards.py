"""The active-localization reward: be localized, be localized early, don't bump into people,
and, where the task has a route or a goal, get on with it.

The reward is computed from ``info`` (the truth and the localizer's estimate), which the
policy never observes. Per step:

    r = - position * min(|p_est - p_true|, position_clip_m)
        - heading * |wrap(theta_est - theta_true)|
        - no_fix                      while there is no valid estimate
        + first_fix_bonus             once, on the first step with a valid estimate
        - collision                   on a step where our robot starts touching something
        - wrong_pose                  while a valid estimate is at least wrong_pose_m off, or its heading
                                      at least wrong_pose_rad off (confidently wrong)
        - time                        every step (the sooner the goal, the better)
        + progress * (s_t - s_{t-1})  s: how far along the task's route the true position is (m;
                                      agents.rl.observation.RouteCursor)
        + goal_bonus                  on the step the world ends the episode at its goal

Each term goes into ``info["reward_terms"]``; they sum to the reward. The last four weigh 0 by
default, which keeps the soccer tasks' reward as it was: there, localizing is the whole task. In
the room, the corridor and the campus it is not: with the first five terms alone, standing still
scores best, so their tasks weigh time, progress and a confident wrong pose too.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np

from agents.rl.observation import RouteConfig, RouteCursor, route_cursor
from core.geometry import wrap_angle
from core.schema import check, from_mapping

TERMS = ("position", "heading", "no_fix", "first_fix", "collision", "wrong_pose", "time", "progress", "goal")


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms (all >= 0; the sign is in the formula)."""

    position: float = 1.0  # per metre of position error
    position_clip_m: float = 1.0  # position errors are clipped here (a lost robot is just lost)
    heading: float = 0.3  # per radian of heading error
    no_fix: float = 1.0  # per step without a valid estimate
    first_fix_bonus: float = 5.0  # once per episode
    collision: float = 0.5  # per step in which our robot starts touching anything
    wrong_pose: float = 0.0  # per step with a valid estimate at least wrong_pose_m from the truth
    wrong_pose_m: float = 1.0  # a valid estimate this far off is a confident wrong pose
    wrong_pose_rad: float = math.inf  # ... and one whose heading is this far off (a twin turned about a room's centre)
    time: float = 0.0  # per step
    progress: float = 0.0  # per metre of true progress along the task's route (needs a route: RouteConfig)
    goal_bonus: float = 0.0  # once, when the world ends the episode at its goal

    def __post_init__(self) -> None:
        for name in ("position", "position_clip_m", "heading", "no_fix", "first_fix_bonus", "collision", "wrong_pose",
                     "time", "progress", "goal_bonus"):  # fmt: skip
            check(getattr(self, name) >= 0, f"reward weight {name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("wrong_pose_m", "wrong_pose_rad"):
            check(getattr(self, name) > 0, f"reward weight {name} must be > 0, got {getattr(self, name)!r}")


class ActiveLocalizationReward(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Replace the env's reward by the active-localization reward.

    Args:
        env: a crowdloc env wrapped by ``LocalizationObservation`` (``info["estimate"]``).
        weights: :class:`RewardWeights` or a mapping of overrides.
        route: the task's route, for the progress term (default: the map's).
    """

    def __init__(
        self, env: gym.Env[Any, Any], weights: RewardWeights | Mapping[str, Any] | None = None, route: RouteConfig | None = None
    ) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, weights=weights, route=route)
        gym.Wrapper.__init__(self, env)
        if weights is None:
            weights = RewardWeights()
        elif not isinstance(weights, RewardWeights):
            weights = from_mapping(RewardWeights, dict(weights), where="reward weights")
        self.weights = weights
        self._had_fix = False
        #: the true position's place on the task's route when progress is weighed, else None
        self.cursor: RouteCursor | None = None
        if weights.progress > 0:
            self.cursor = route_cursor(env.unwrapped, route or RouteConfig(), f"reward weight progress = {weights.progress}")
        self._remaining_m = 0.0

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        if "estimate" not in info:
            raise KeyError("ActiveLocalizationReward needs a localizer: make the env with localizer=...")
        self._had_fix = bool(info["estimate"].valid)
        if self.cursor is not None:
            self.cursor.reset()
            self._remaining_m = self._rest_of_route(info)
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, _, terminated, truncated, info = self.env.step(action)
        terms = self.terms(info, terminated)
        info["reward_terms"] = terms
        return obs, float(sum(terms.values())), terminated, truncated, info

    def terms(self, info: Mapping[str, Any], terminated: bool = False) -> dict[str, float]:
        """The reward terms of one step (advances the first-fix and progress bookkeeping);
        ``terminated``: the world ended the episode (at its goal)."""
        w = self.weights
        est = info["estimate"]
        truth = np.asarray(info["true_pose"], dtype=np.float64)
        terms = dict.fromkeys(TERMS, 0.0)
        if est.valid:
            error = float(np.hypot(est.x_m - truth[0], est.y_m - truth[1]))
            terms["position"] = -w.position * min(error, w.position_clip_m)
            heading_error = abs(float(wrap_angle(est.theta_rad - truth[2])))
            terms["heading"] = -w.heading * heading_error
            if not self._had_fix:
                terms["first_fix"] = w.first_fix_bonus
                self._had_fix = True
            if w.wrong_pose and (error >= w.wrong_pose_m or heading_error >= w.wrong_pose_rad):
                terms["wrong_pose"] = -w.wrong_pose
        else:
            terms["no_fix"] = -w.no_fix
        if info.get("contacts"):
            terms["collision"] = -w.collision
        terms["time"] = -w.time
        if self.cursor is not None:
            remaining = self._rest_of_route(info)
            terms["progress"] = w.progress * (self._remaining_m - remaining)
            self._remaining_m = remaining
        if terminated:
            terms["goal"] = w.goal_bonus
        return terms

    def _rest_of_route(self, info: Mapping[str, Any]) -> float:
        """The rest of the route from the true position (m)."""
        assert self.cursor is not None
        truth = info["true_pose"]
        return self.cursor.update(float(truth[0]), float(truth[1]))
