"""Coasting: a localizer that has a fix drives on with nothing to see; how its reported spread
compares with the spread the odometry's own noise (the alpha model) builds up over the same
increments. Shared by the honest-spread tests of every localizer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.geometry import compose
from core.motion import sample_odometry
from localizers.base import PoseEstimate
from tests.localizers.lost import blank, drive, during


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
    """Drive :data:`tests.localizers.lost.CIRCLE` for ``localized_steps`` with the localizer
    seeing its sensor, then ``coast_steps`` more feeding it the odometry and blank frames only."""
    run = drive(
        localizer,
        env_id,
        localized_steps + coast_steps,
        seed,
        localizer_params=localizer_params,
        frame=during(blank, localized_steps + 1),
        **env_kwargs,
    )
    start = run.estimates[localized_steps - 1]
    alphas = np.asarray(run.sensor_metadata["odometry"]["alphas"], dtype=np.float64)
    origin = start.as_array() if start.valid else np.zeros(3)
    reference = motion_model_spread(origin, run.odometry[localized_steps:], alphas)
    return Coast(start, run.estimates[localized_steps:], reference)
