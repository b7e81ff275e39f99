"""Coasting: a localizer that has a fix drives on with nothing to see; how its reported spread
compares with the spread the odometry's own noise (the alpha model) builds up over the same
increments. Shared by the honest-spread tests of every localizer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import envs  # noqa: F401
from localizers.base import BearingMeasurement, OdometryDelta, PoseEstimate, ScanMeasurement
from localizers.geometry import compose
from localizers.motion import sample_odometry

#: a gentle circle: forward at 40 % of top speed, turning at 20 % of the top turn rate
CIRCLE = np.array([0.4, 0.2], dtype=np.float32)


def motion_model_spread(
    start: NDArray[np.float64], increments: NDArray[np.float64], alphas: NDArray[np.float64], samples: int = 4000, seed: int = 0
) -> NDArray[np.float64]:
    """``(N,)`` the position spread ``sqrt(var x + var y)`` after each of the ``(N, 3)``
    odometry increments, of poses dead-reckoned from the exact ``start`` ``(3,)`` with every
    increment drawn from the alpha model (Monte Carlo, ``samples`` poses)."""
    rng = np.random.default_rng(seed)
    poses = np.tile(np.asarray(start, dtype=np.float64), (samples, 1))
    out = np.empty(increments.shape[0])
    for k, d in enumerate(increments):
        poses = compose(poses, sample_odometry(rng, d, alphas, size=samples))
        out[k] = math.sqrt(poses[:, 0].var() + poses[:, 1].var())
    return out


def blank(measurement: Any) -> Any:
    """The frame a sensor gives when it sees nothing: no bearings; every beam at its maximum range."""
    if isinstance(measurement, BearingMeasurement):
        return BearingMeasurement.empty()
    if isinstance(measurement, ScanMeasurement):
        return ScanMeasurement(
            np.full_like(measurement.ranges_m, measurement.max_range_m), measurement.angles_rad, measurement.max_range_m
        )
    raise TypeError(f"no blank frame for {type(measurement).__name__}")


@dataclass
class Coast:
    """What one coasting run gave.

    Attributes:
        start: the estimate when coasting began (after the localized phase).
        estimates: one per coasting step.
        reference: ``(N,)`` :func:`motion_model_spread` of the same increments from ``start``.
    """

    start: PoseEstimate
    estimates: list[PoseEstimate]
    reference: NDArray[np.float64]

    @property
    def spreads(self) -> NDArray[np.float64]:
        return np.array([e.position_spread_m if e.valid else math.nan for e in self.estimates])

    @property
    def valid(self) -> NDArray[np.bool_]:
        return np.array([e.valid for e in self.estimates])


def coast(
    localizer: str,
    env_id: str,
    localized_steps: int,
    coast_steps: int,
    seed: int = 0,
    localizer_params: dict[str, Any] | None = None,
    **env_kwargs: Any,
) -> Coast:
    """Drive :data:`CIRCLE` for ``localized_steps`` with the localizer seeing its sensor, then
    ``coast_steps`` more feeding it the odometry and blank frames only."""
    env = gym.make(env_id, localizer=localizer, localizer_params=localizer_params or {}, **env_kwargs)
    wrapper = env
    while not hasattr(wrapper, "localizer"):
        wrapper = wrapper.env
    env.reset(seed=seed)
    for _ in range(localized_steps):
        env.step(CIRCLE)
    loc = wrapper.localizer
    start = loc.estimate
    base = wrapper.env
    odometry_key = wrapper._odometry_key
    frame = wrapper._decode(base.unwrapped.last_observation[wrapper._sensor_key], wrapper._sensor_meta)
    alphas = np.asarray(base.unwrapped.sensor_metadata["odometry"]["alphas"], dtype=np.float64)
    increments, estimates = [], []
    for _ in range(coast_steps):
        obs, *_ = base.step(CIRCLE)
        d = np.asarray(obs[odometry_key], dtype=np.float64)
        increments.append(d)
        loc.predict(OdometryDelta(float(d[0]), float(d[1]), float(d[2])))
        loc.update(blank(frame))
        estimates.append(loc.estimate)
    env.close()
    origin = start.as_array() if start.valid else np.zeros(3)
    return Coast(start, estimates, motion_model_spread(origin, np.array(increments), alphas))
