"""Baseline (1) of the two-landmark bearings paper: dead reckoning from a known initial pose.

The pose is the running SE(2) product of the odometry increments. Its covariance grows
with a random-walk drift model (ours; the paper gives none): every increment of length
``s`` metres and turn ``|dtheta|`` radians adds, in the robot frame,

    var(along-track) = var(cross-track) = position_var_m2_per_m * s
    var(heading)     = heading_var_rad2_per_m * s + heading_var_rad2_per_rad * |dtheta|

so the position standard deviation grows like the square root of the distance travelled
(independent of how finely the path is cut into steps), and heading uncertainty leaks into
cross-track error through the linearized motion model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from core.geometry import compose, wrap_angle
from core.schema import check_ranges
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    BearingMeasurement,
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    checked_bearings,
    finite_covariance,
    require_reset,
    within_spread,
)


@dataclass(frozen=True)
class DeadReckoningParams:
    """Drift rates of the covariance model (defaults: ``configs/localizers/dead_reckoning.yaml``).

    Attributes:
        position_var_m2_per_m: position variance added per metre, along and across track.
        heading_var_rad2_per_m: heading variance added per metre travelled.
        heading_var_rad2_per_rad: heading variance added per radian turned.
        initial_position_std_m: prior position std when the prior has no finite covariance.
        initial_heading_std_rad: prior heading std when the prior has no finite covariance.
        max_spread_m: past this position spread (m) the estimate is not claimed
            (``valid`` false; ours). Dead reckoning cannot notice a kidnapping or recover: this
            is where it stops claiming a pose. With the default drift (1e-3 m^2 per m per
            axis) the spread reaches 1 m after 500 m of travel; the coasting test checks that
            the drift is at least the odometry's own.
    """

    position_var_m2_per_m: float = 1e-3
    heading_var_rad2_per_m: float = 1e-3
    heading_var_rad2_per_rad: float = 1e-3
    initial_position_std_m: float = 0.0
    initial_heading_std_rad: float = 0.0
    max_spread_m: float = DEFAULT_MAX_SPREAD_M

    def __post_init__(self) -> None:
        check_max_spread("DeadReckoningParams", self.max_spread_m)
        check_ranges(
            self,
            "DeadReckoningParams",
            non_negative=(
                "position_var_m2_per_m",
                "heading_var_rad2_per_m",
                "heading_var_rad2_per_rad",
                "initial_position_std_m",
                "initial_heading_std_rad",
            ),
        )


def dead_reckon(
    pose: NDArray[np.float64],
    cov: NDArray[np.float64],
    d: NDArray[np.float64],
    position_var_m2_per_m: float,
    heading_var_rad2_per_m: float,
    heading_var_rad2_per_rad: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One dead-reckoning step: ``pose`` (3,) composed with the increment ``d`` (3,) and its
    covariance propagated as ``F P F^T + G Q G^T`` with the random-walk drift of the module
    docstring (``Q`` in the robot frame). Returns the new pose and covariance."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    # Jacobian of compose(pose, d) w.r.t. the pose
    F = np.array([[1.0, 0.0, -s * d[0] - c * d[1]], [0.0, 1.0, c * d[0] - s * d[1]], [0.0, 0.0, 1.0]])
    drift = drift_covariance(float(pose[2]), d, position_var_m2_per_m, heading_var_rad2_per_m, heading_var_rad2_per_rad)
    return compose(pose, d), F @ cov @ F.T + drift


def drift_covariance(
    heading_rad: float,
    d: NDArray[np.float64],
    position_var_m2_per_m: float,
    heading_var_rad2_per_m: float,
    heading_var_rad2_per_rad: float,
) -> NDArray[np.float64]:
    """``(3, 3)`` world-frame covariance ``G Q G^T`` that one increment ``d`` (3,) adds at
    ``heading_rad``: the random-walk drift of the module docstring (``Q`` in the robot frame,
    ``G`` the Jacobian of the composition w.r.t. the increment)."""
    c, s = math.cos(heading_rad), math.sin(heading_rad)
    G = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    dist = math.hypot(d[0], d[1])
    q_pos = position_var_m2_per_m * dist
    Q = np.diag([q_pos, q_pos, heading_var_rad2_per_m * dist + heading_var_rad2_per_rad * abs(d[2])])
    return G @ Q @ G.T


class DeadReckoningLocalizer(LocalizerBase[DeadReckoningParams]):
    """Integrates odometry from the prior pose; bearings are validated and ignored. The
    estimate is valid while its position spread is at most ``max_spread_m``."""

    name: ClassVar[str] = "dead_reckoning"
    #: measured on this run: share 0.330, NEES median 145. The robot's true motion differs from its commands by
    #: 4.7 m over its 10.8 m path, 4.6 m of it on the 290 of 400 steps where the random walk drives it against
    #: the field's edge (the wheels turn, the robot stays). The drift model knows nothing of that; without the
    #: crowd the share is the same (0.330), and so it is without the odometry's systematic errors (0.328)
    #: (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.3)

    def __init__(self, landmarks: LandmarkMap, params: DeadReckoningParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s, owner="DeadReckoningLocalizer")
        self._pose: NDArray[np.float64] | None = None
        self._cov = np.zeros((3, 3))

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Start from ``prior`` (required: dead reckoning cannot find a pose by itself).

        Raises:
            ValueError: when ``prior`` is missing or not valid.
        """
        del rng  # deterministic
        if prior is None or not prior.valid or not np.isfinite(prior.as_array()).all():
            raise ValueError(
                f"DeadReckoningLocalizer.reset needs a valid initial pose (prior), got {prior!r}: "
                "dead reckoning only integrates odometry from a known start"
            )
        self._pose = np.array([prior.x_m, prior.y_m, wrap_angle(prior.theta_rad)])
        cov = finite_covariance(prior)
        if cov is not None:
            self._cov = 0.5 * (cov + cov.T)
        else:
            p = self._params
            self._cov = np.diag([p.initial_position_std_m**2] * 2 + [p.initial_heading_std_rad**2])

    def _require_reset(self) -> NDArray[np.float64]:
        pose = self._pose
        require_reset("DeadReckoningLocalizer", pose is not None)
        assert pose is not None  # for mypy: require_reset raised otherwise
        return pose

    def predict(self, odometry: OdometryDelta) -> None:
        """Compose the increment and propagate the covariance (:func:`dead_reckon`)."""
        pose = self._require_reset()
        d = self._checked_odometry(odometry)
        p = self._params
        self._pose, self._cov = dead_reckon(
            pose, self._cov, d, p.position_var_m2_per_m, p.heading_var_rad2_per_m, p.heading_var_rad2_per_rad
        )

    def update(self, measurement: BearingMeasurement | OdometryDelta) -> None:
        """Validate (bad bearings still raise) and otherwise ignore the measurement. In a world
        without a bearing camera the env wrapper hands it the odometry increment instead (its
        registry entry's ``fallback`` kind), which :meth:`predict` has already integrated."""
        self._require_reset()
        if not isinstance(measurement, OdometryDelta):
            checked_bearings(self.name, measurement, self._map.count)

    @property
    def estimate(self) -> PoseEstimate:
        if self._pose is None:
            return PoseEstimate.invalid()
        x, y, th = self._pose
        return PoseEstimate(float(x), float(y), float(th), self._cov.copy(), within_spread(self._cov, self._params.max_spread_m))

    def overlay(self) -> Overlay:
        if self._pose is None:
            return Overlay(label="dead reckoning: not started")
        return Overlay(poses=self._pose[None, :].copy(), weights=np.ones(1), label="dead reckoning")
