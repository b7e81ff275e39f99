"""A user's benchmark entry, as ``docs/benchmark.md`` shows it: ``crowdloc benchmark --plugins tests.agents.benchmark_plugin``.

``start_pose`` claims the start pose it was given for the whole episode (the robot "never moved"):
a localizer reading odometry only, so it runs in every world. ``straight_ahead`` drives forward.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from agents.policies import FixedPolicy, register_policy
from localizers.base import LandmarkMap, OdometryDelta, Overlay, PoseEstimate
from localizers.registry import LocalizerSpec, register_localizer


@dataclass(frozen=True)
class StartPoseParams:
    """No parameters to speak of (a plug-in without ``configs/localizers/<name>.yaml`` gets these defaults)."""

    scale: float = 1.0


class StartPoseLocalizer:
    """Claims the prior pose forever; no pose without one."""

    def __init__(self, landmarks: LandmarkMap, params: StartPoseParams, dt_s: float) -> None:
        self._pose: PoseEstimate | None = None

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        self._pose = prior

    def predict(self, odometry: OdometryDelta) -> None:
        pass

    def update(self, measurement: Any) -> None:
        pass

    @property
    def estimate(self) -> PoseEstimate:
        if self._pose is None:
            return PoseEstimate(np.nan, np.nan, np.nan, np.full((3, 3), np.nan), False)
        return self._pose

    def overlay(self) -> Overlay:
        return Overlay(label="start pose")


class StraightAhead(FixedPolicy):
    """Full speed ahead, no turning."""

    def _act(self, observation: Any) -> NDArray[np.float64]:
        return np.array([1.0, 0.0])


register_localizer(
    "start_pose",
    LocalizerSpec(
        __name__, "StartPoseLocalizer", "StartPoseParams", "odometry", True, "the start pose, forever", covariance=False
    ),
)
register_policy("straight_ahead", StraightAhead)
