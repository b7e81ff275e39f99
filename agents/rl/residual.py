"""A trained policy that corrects a fixed one: residual actions (a training config's ``action:``).

A policy learnt from scratch on a long task has to find out first what a hand-made policy
already does. On the campus two PPO runs learnt to keep the pose but drove at 0.3-0.4 m/s
and never reached the route's end, where ``route_follower`` drives it at 1 m/s
(``models/README.md``). Residual policy learning (Silver et al. 2018, "Residual Policy
Learning"; Johannink et al. 2019, "Residual Reinforcement Learning for Robot Control") starts
the learner from the hand-made policy instead: the command sent to the robot is

    command = clip(base(observation) + residual_scale * action, -1, 1)

where ``base`` is a fixed policy of :mod:`agents.policies` run on the task's full observation
(its estimate and range sensor; never the truth) and ``action`` the trained policy's output in
``[-1, 1]``. With ``residual_scale`` 2 (the default) every command in ``[-1, 1]`` stays
reachable from every base command, so the policy's choices are the same as without a base;
what changes is where learning starts: a policy whose output is near 0 (stable-baselines3's
initial one) drives as the base does.

``deadband`` > 0 counts an action number within it of 0 as 0 (beyond it the correction rises
linearly, ``sign(a) (|a| - deadband) / (1 - deadband)``, so ``+-1`` stays ``+-1``). Training
explores with Gaussian noise about the policy's output; without a deadband every command is the
base's plus noise, and two things a task may need become rare: the base's own command, and
standing still (a world's goal ends an episode once the commands stay under 2 % of their limits
for 1 s: Gaussian noise of sd 0.13 does that with odds of about 1e-19). On the campus (seeds
1000-1003, crowds 30 and 100), ``route_follower`` plus noise of sd 0.13 scored -86 and -98 on
the task's reward and never reached the end, against +8 and +14 and 4 of 4 for ``route_follower``;
with the same noise before a deadband of 0.1 (an sd of 0.067 before the scale of 2, so 86 % of
the numbers fall within it) it scored -2.5 and -2.5 and reached the end 4 of 4 times.

:class:`ResidualAction` does this and adds ``base_action`` ``(2,)`` to the observation: the
base's command for this step, so that the policy knows what it corrects (the base reads sensors
the policy may not see whole, and keeps state: its progress, whether it waits). Its
observation differs from a plain task's, so a residual model cannot be run by mistake where no
base adds its command (``crowdloc eval`` names the missing entry).

``crowdloc train`` records the section in the model (:data:`MODEL_ACTION_ATTR`), and ``crowdloc
eval`` refuses a model whose record differs from its conditions' (:func:`check_trained_action`).

The task is unchanged: its world, crowd, reward and episode are the plain task's, and a fixed
policy evaluated on it drives the plain task (``crowdloc eval`` gives only trained policies the
task's observation and action). The scale and the deadband are not in the observation, so only
that record tells a model's: with another deadband a model runs, but drives otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agents.policies.fixed import FIXED_POLICIES, make_policy, task_route_kwargs
from agents.rl.observation import RouteConfig
from core.schema import ConfigError, check, is_real

#: the observation entry with the base policy's command
BASE_KEY = "base_action"
#: the attribute of a model trained by ``crowdloc train`` that records its ``action:`` (saved in its .zip)
MODEL_ACTION_ATTR = "crowdloc_action"


@dataclass(frozen=True)
class ActionConfig:
    """What a task's action means (module docstring); the defaults change nothing."""

    residual_to: str | None = None  # a fixed policy whose command the action corrects (None: the action is the command)
    residual_scale: float = 2.0  # the action times this is added to the base's command
    deadband: float = 0.0  # an action number this close to 0 counts as 0 (module docstring)

    def __post_init__(self) -> None:
        check(
            self.residual_to is None or self.residual_to in FIXED_POLICIES,
            f"action.residual_to must be a fixed policy ({', '.join(sorted(FIXED_POLICIES))}) or null, got {self.residual_to!r}",
        )
        check(
            is_real(self.residual_scale, finite=True) and self.residual_scale > 0,
            f"action.residual_scale must be finite and > 0, got {self.residual_scale!r}",
        )
        check(
            is_real(self.deadband) and 0 <= self.deadband < 1,
            f"action.deadband must be in [0, 1), got {self.deadband!r}",
        )

    @property
    def changes_anything(self) -> bool:
        return self.residual_to is not None

    def as_record(self) -> dict[str, Any]:
        """The settings as plain data, as a trained model records them (:data:`MODEL_ACTION_ATTR`)."""
        return {"residual_to": self.residual_to, "residual_scale": float(self.residual_scale), "deadband": float(self.deadband)}


def check_trained_action(policy: str, model: Any, given: ActionConfig) -> None:
    """Refuse to run ``model`` with another ``action:`` than it trained with, where it records one
    (models trained before the record existed do not: nothing to compare).

    Raises:
        ConfigError: naming the policy, what it trained with and what it was given.
    """
    trained = getattr(model, MODEL_ACTION_ATTR, None)
    if trained is not None and dict(trained) != given.as_record():
        raise ConfigError(
            f"policy {policy!r} was trained with action {dict(trained)} and these conditions give {given.as_record()}: "
            "evaluate it in the conditions it trained in (crowdloc eval --conditions its training config)"
        )


class ResidualAction(gym.Wrapper[dict[str, Any], NDArray[np.float32], dict[str, Any], NDArray[np.float32]],
                     gym.utils.RecordConstructorArgs):  # fmt: skip
    """Send ``clip(base + residual_scale * deadband(action))``, ``base`` the fixed policy's command (module docstring).

    Args:
        env: a task (a world behind its localizer, with the task's reward), its raw observation.
        config: :class:`ActionConfig` with ``residual_to`` set.
        route: the task's route; a route-following base drives its points when it gives them
            (as ``crowdloc eval`` has ``route_follower`` do), else the map's route.

    Attributes:
        base: the fixed policy.
        command: the command sent on the last step (``(2,)``; zeros before the first).

    Raises:
        ConfigError: without ``residual_to``, or for a base the world cannot run (naming what it lacks).
    """

    def __init__(self, env: gym.Env[Any, Any], config: ActionConfig, route: RouteConfig | None = None) -> None:
        gym.utils.RecordConstructorArgs.__init__(self, config=config, route=route)
        gym.Wrapper.__init__(self, env)
        if config.residual_to is None:
            raise ConfigError("ResidualAction needs action.residual_to: the fixed policy the action corrects")
        space = env.observation_space
        check(isinstance(space, spaces.Dict) and BASE_KEY not in space.spaces,
              f"ResidualAction needs a Dict observation without a {BASE_KEY!r} entry, got {space!r}")  # fmt: skip
        assert isinstance(space, spaces.Dict)
        action_space = env.action_space
        check(isinstance(action_space, spaces.Box) and action_space.shape == (2,),
              f"ResidualAction needs a Box action space of shape (2,), got {action_space!r}")  # fmt: skip
        assert isinstance(action_space, spaces.Box)
        self.config = config
        self._low, self._high = action_space.low.astype(np.float64), action_space.high.astype(np.float64)
        kwargs = task_route_kwargs(config.residual_to, route.points_m if route is not None else ())
        try:
            self.base = make_policy(config.residual_to, env, seed=None, **kwargs)
        except (ValueError, KeyError) as exc:
            raise ConfigError(f"action.residual_to {config.residual_to!r} cannot drive this task: {exc}") from exc
        self.observation_space = spaces.Dict({**space.spaces, BASE_KEY: spaces.Box(-1.0, 1.0, (2,), np.float32)})
        self._base_command = np.zeros(2)
        self.command = np.zeros(2)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        self.base.reset()
        self.command = np.zeros(2)
        return self._with_base(observation), info

    def step(self, action: Any) -> tuple[dict[str, Any], Any, bool, bool, dict[str, Any]]:
        residual = np.asarray(action, dtype=np.float64).reshape(-1)
        if residual.shape != (2,) or not np.all(np.isfinite(residual)):
            raise ValueError(f"ResidualAction: the action must be 2 finite numbers, got {action!r}")
        residual = self.correction(np.clip(residual, self._low, self._high))
        self.command = np.clip(self._base_command + self.config.residual_scale * residual, self._low, self._high)
        observation, reward, terminated, truncated, info = self.env.step(self.command.astype(np.float32))
        return self._with_base(observation), reward, terminated, truncated, info

    def correction(self, action: NDArray[np.float64]) -> NDArray[np.float64]:
        """The action in ``[-1, 1]`` after the deadband: 0 within it, beyond it rising linearly to
        ``+-1`` at ``+-1`` (so the whole range stays reachable)."""
        band = self.config.deadband
        return np.sign(action) * np.maximum(np.abs(action) - band, 0.0) / (1.0 - band)

    def _with_base(self, observation: dict[str, Any]) -> dict[str, Any]:
        """The observation with the base's command for it (which the next step corrects)."""
        command, _ = self.base.predict(observation, deterministic=True)
        self._base_command = np.asarray(command, dtype=np.float64)
        return {**observation, BASE_KEY: np.asarray(command, dtype=np.float32)}
