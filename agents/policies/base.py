"""The base of the fixed policies (:class:`FixedPolicy`) and the helpers they share.

:mod:`agents.policies.fixed` has the baseline policies and their registry; the policies in
:mod:`agents.policies.navigation` and :mod:`agents.policies.route_following` build on this
module too, which imports none of them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from core.geometry import ring_directions, wrap_angle
from core.schema import is_real
from envs.wrappers import decode_estimate

if TYPE_CHECKING:
    from envs.config import WorldConfig

Observation = dict[str, NDArray[np.float32]]


class FixedPolicy:
    """Base class: one action per call for a single (non-vectorized) environment.

    Args:
        action_space: the env's ``Box(-1, 1, (2,))`` action space.
        seed: seed of the policy's own random stream (independent of the env's).
    """

    #: the sensor type whose readings the policy reads besides the estimate (None: only odometry and the estimate)
    needs_sensor: ClassVar[str | None] = None
    #: the world feature type whose map data the policy plans on (None: none)
    needs_feature: ClassVar[str | None] = None

    @classmethod
    def unmet_need(cls, world: WorldConfig) -> tuple[str, str] | None:
        """What ``world`` lacks for this policy, as ``(need, what it has)``
        (``("a sonar sensor", "its sensors: odometry, lidar")``); None when it has everything."""
        if cls.needs_sensor is not None and world.sensor_of_type(cls.needs_sensor) is None:
            return f"a {cls.needs_sensor} sensor", f"its sensors: {', '.join(world.sensors) or 'none'}"
        if cls.needs_feature is not None and not world.features_of_type(cls.needs_feature):
            return f"a {cls.needs_feature} feature", f"its features: {', '.join(world.features) or 'none'}"
        return None

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
        observation: Observation,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[NDArray[np.float32], Any]:
        if episode_start is not None and bool(np.any(episode_start)):
            self.reset()
        action = np.clip(self._act(observation), self.action_space.low, self.action_space.high)
        return action.astype(np.float32), state

    def _act(self, observation: Observation) -> NDArray[np.float64]:
        raise NotImplementedError


def read_estimate(observation: Observation, bounds_m: tuple[float, float, float, float], who: str) -> NDArray[np.float64] | None:
    """The localizer's estimated pose ``(x, y, theta)`` in world units, None while it claims none.

    Raises:
        KeyError: when the observation has no ``estimate`` (the env was made without a
            localizer), naming ``who`` needs it.
    """
    if "estimate" not in observation:
        raise KeyError(
            f"{who} plans from the localizer's estimate: make the env with localizer=... "
            f"(observation keys: {sorted(observation)})"
        )
    if observation["estimate_valid"][0] < 0.5:
        return None
    return decode_estimate(observation["estimate"], bounds_m)


def sonar_cones(count: int, directions_rad: ArrayLike, halfwidth_rad: float) -> NDArray[np.bool_]:
    """``(..., count)``: which sensors of a ring of ``count`` (the ``sonar`` observation's layout,
    evenly from the heading counter-clockwise) point within ``halfwidth_rad`` of each direction
    ``(...)`` relative to the heading."""
    directions = np.asarray(directions_rad, dtype=np.float64)
    return np.abs(wrap_angle(ring_directions(count) - directions[..., None])) <= halfwidth_rad


def check_command(name: str, value: float) -> None:
    if not (is_real(value) and -1.0 <= value <= 1.0):
        raise ValueError(f"{name} must be a number in [-1, 1] (action units), got {value!r}")


def arc_end_poses(poses: NDArray[np.float64], speeds_mps: NDArray[np.float64], turn_rates_rps: NDArray[np.float64],
                  horizon_s: float) -> NDArray[np.float64]:  # fmt: skip
    """``(C, K, 3)``: each of ``K`` poses ``(K, 3)`` after each of ``C`` motions (a forward speed and a turn rate
    held ``horizon_s``), along the exact arc."""
    v = np.asarray(speeds_mps, dtype=np.float64)[:, None]
    w = np.asarray(turn_rates_rps, dtype=np.float64)[:, None]
    turn = w * horizon_s
    straight = np.abs(turn) < 1e-9
    safe_w = np.where(straight, 1.0, w)
    dx = np.where(straight, v * horizon_s, v / safe_w * np.sin(turn))
    dy = np.where(straight, 0.0, v / safe_w * (1.0 - np.cos(turn)))
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)[None]
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    return np.stack([p[..., 0] + c * dx - s * dy, p[..., 1] + s * dx + c * dy, p[..., 2] + turn], axis=-1)


def sonar_blocked(observation: Observation, directions_rad: ArrayLike, clearance_m: float) -> NDArray[np.bool_]:
    """Which travel directions (relative to the heading) the sonar finds obstructed: a sonar cone within
    45 deg of it reads closer than ``clearance_m``. Without a sonar nothing is obstructed."""
    directions = np.asarray(directions_rad, dtype=np.float64)
    if "sonar" not in observation:
        return np.zeros(directions.shape, dtype=bool)
    ranges = np.asarray(observation["sonar"], dtype=np.float64)
    return np.any(sonar_cones(ranges.shape[0], directions, math.pi / 4) & (ranges < clearance_m), axis=-1)
