"""Fixed baseline policies with stable-baselines3's ``predict`` signature.

A fixed policy and a trained SB3 model are interchangeable in every evaluation loop:
``action, state = policy.predict(observation, state, episode_start, deterministic)``.
Policies see only the observation, never ``info``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray


class FixedPolicy:
    """Base class: one action per call for a single (non-vectorized) environment.

    Args:
        action_space: the env's ``Box(-1, 1, (2,))`` action space.
        seed: seed of the policy's own random stream (independent of the env's).
    """

    def __init__(self, action_space: spaces.Box, seed: int | None = None) -> None:
        if not isinstance(action_space, spaces.Box) or action_space.shape != (2,):
            raise ValueError(f"{type(self).__name__} needs a Box action space of shape (2,), got {action_space!r}")
        self.action_space = action_space
        self.rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        """Start a new episode (and optionally re-seed)."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)

    def predict(
        self,
        observation: dict[str, NDArray[np.float32]],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[NDArray[np.float32], Any]:
        if episode_start is not None and bool(np.any(episode_start)):
            self.reset()
        action = np.clip(self._act(observation), self.action_space.low, self.action_space.high)
        return action.astype(np.float32), state

    def _act(self, observation: dict[str, NDArray[np.float32]]) -> NDArray[np.float64]:
        raise NotImplementedError


class RandomWalk(FixedPolicy):
    """Drive forward at a fixed speed while the turn rate follows a bounded random walk.

    Args:
        speed: forward command in ``[-1, 1]``.
        turn_noise: standard deviation of the turn-rate increments per step.
        persistence: how much of the previous turn rate is kept each step.
    """

    def __init__(
        self,
        action_space: spaces.Box,
        seed: int | None = None,
        speed: float = 0.6,
        turn_noise: float = 0.25,
        persistence: float = 0.9,
    ) -> None:
        super().__init__(action_space, seed)
        if not -1.0 <= speed <= 1.0:
            raise ValueError(f"RandomWalk speed must be in [-1, 1], got {speed}")
        if not 0.0 <= persistence < 1.0:
            raise ValueError(f"RandomWalk persistence must be in [0, 1), got {persistence}")
        self.speed = speed
        self.turn_noise = turn_noise
        self.persistence = persistence
        self._turn = 0.0

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self._turn = 0.0

    def _act(self, observation: dict[str, NDArray[np.float32]]) -> NDArray[np.float64]:
        self._turn = float(np.clip(self.persistence * self._turn + self.rng.normal(0.0, self.turn_noise), -1.0, 1.0))
        return np.array([self.speed, self._turn])
