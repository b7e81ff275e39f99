"""Wheel odometry: the *commanded* motion since the last step, with alpha-model noise.

Displacement by contacts never enters it: a push is a real, unobserved pose jump.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState
from localizers.motion import odometry_noise_std, sample_odometry
from localizers.schema import check

if TYPE_CHECKING:
    from envs.config import WorldConfig


@dataclass(frozen=True)
class OdometryConfig(SensorConfig):
    """Probabilistic Robotics odometry noise (variances per squared unit)."""

    key: str = "odometry"
    alpha1: float = 0.01  # rad^2 / rad^2   rotation noise from rotation
    alpha2: float = 0.01  # rad^2 / m^2     rotation noise from translation
    alpha3: float = 0.01  # m^2 / m^2       translation noise from translation
    alpha4: float = 0.01  # m^2 / rad^2     translation noise from rotation

    def __post_init__(self) -> None:
        for name in ("alpha1", "alpha2", "alpha3", "alpha4"):
            check(getattr(self, name) >= 0, f"odometry.{name} must be >= 0, got {getattr(self, name)}")

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        return (self.alpha1, self.alpha2, self.alpha3, self.alpha4)


@register_sensor("odometry", OdometryConfig)
class Odometry(SensorBase):
    """Noisy increment ``(dx, dy, dtheta)`` of the commanded motion since the last step, in the previous frame.

    ``command(delta)`` is called by the env with the exact commanded increment before the
    physics step. The noise follows the alpha model (:mod:`localizers.motion`).
    """

    def __init__(self, name: str, config: OdometryConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.alphas = np.asarray(config.alphas)
        # bounds: the largest commanded step, widened for noise; clipping at 8 noise sds
        # of the largest step is never reached in practice and keeps the space finite
        trans = world.robot.max_speed_mps * world.dt_s
        rot = world.robot.max_turn_rate_rps * world.dt_s
        std = odometry_noise_std([trans * math.cos(rot / 2), trans * math.sin(rot / 2), rot], self.alphas)
        self.bound = np.array([trans + 8 * std[1] + 1e-3, trans + 8 * std[1] + 1e-3, rot + 16 * std[0] + 1e-3], dtype=np.float32)
        self._delta = np.zeros(3)

    def space(self) -> spaces.Box:
        return spaces.Box(-self.bound, self.bound, dtype=np.float32)

    def reset(self) -> None:
        self._delta = np.zeros(3)

    def command(self, delta: NDArray[np.float64], rng: np.random.Generator) -> None:
        """Record the commanded increment ``(3,)`` of this step, corrupted by the alpha model."""
        self._delta = sample_odometry(rng, delta, self.alphas)

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        return np.clip(self._delta.astype(np.float32), -self.bound, self.bound), {}

    def metadata(self) -> dict[str, Any]:
        return {"alphas": self.config.alphas}
