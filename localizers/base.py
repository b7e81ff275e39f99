"""The localizer interface: measurements in, a pose estimate out.

Localizers import nothing from ``envs``: they work on the plain dataclasses of
:mod:`core.types` (the map, the measurements, the estimate and the overlay), which this module
presents beside the :class:`Localizer` protocol, the consistency promise and the input checks
every localizer makes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, Protocol, TypeVar, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from core.types import (
    EDGE_CHANNELS,
    EDGE_LEVELS,
    EDGE_POLARITIES,
    EDGE_TYPES,
    BearingMeasurement,
    EdgeMeasurement,
    LandmarkMap,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    ScanMeasurement,
)

__all__ = [
    "DEFAULT_MAX_SPREAD_M",
    "EDGE_CHANNELS",
    "EDGE_LEVELS",
    "EDGE_POLARITIES",
    "EDGE_TYPES",
    "BearingMeasurement",
    "ConsistencyPromise",
    "EdgeMeasurement",
    "LandmarkMap",
    "Localizer",
    "LocalizerBase",
    "MeasurementError",
    "OdometryDelta",
    "Overlay",
    "PoseEstimate",
    "ScanMeasurement",
    "check_max_spread",
    "checked_bearings",
    "checked_dt",
    "checked_increment",
    "checked_odometry",
    "finite_covariance",
    "require_reset",
    "validated_scan",
    "within_spread",
]


@dataclass(frozen=True)
class ConsistencyPromise:
    """How honest a localizer's reported covariance is on a seeded run of its world: the share of
    the steps with a pose whose error lies inside the reported 95 % region (NEES at most the
    chi-square 0.95 quantile, 3 dof) is at least ``inside_95`` (about 0.95 for a consistent
    estimator; measured on seed 0 and rounded down). The run: ``env_id`` from seed 0 driven by the
    fixed policy ``policy`` for ``steps`` steps, the localizer given the start pose. Each
    localizer's docstring says why it falls short where it does;
    ``tests/localizers/test_consistency_promises.py`` holds every localizer to its promise."""

    env_id: str
    policy: str
    steps: int
    inside_95: float

    def __post_init__(self) -> None:
        if not (0.0 <= self.inside_95 <= 1.0 and self.steps >= 1):
            raise ValueError(f"ConsistencyPromise: inside_95 in [0, 1] and steps >= 1, got {self.inside_95}, {self.steps}")


@runtime_checkable
class Localizer(Protocol):
    """Every localizer: ``reset`` once per episode, then ``predict`` and ``update`` each step."""

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Forget everything; ``prior`` is a known initial pose where the method needs one."""

    def predict(self, odometry: OdometryDelta) -> None:
        """Propagate by one odometry increment."""

    def update(self, measurement: Any) -> None:
        """Incorporate one frame's measurement (an empty one is legal)."""

    @property
    def estimate(self) -> PoseEstimate:
        """The current pose estimate (``valid=False`` when there is none)."""

    def overlay(self) -> Overlay:
        """Hypotheses to draw."""


ParamsT = TypeVar("ParamsT")


class LocalizerBase(Generic[ParamsT]):
    """What every built-in localizer holds from its constructor ``Cls(landmarks, params, *, dt_s)``,
    and its odometry check.

    Attributes:
        _map: the map it localizes on.
        _step_limit_m: the map's :attr:`LandmarkMap.step_limit_m`, the longest odometry
            translation :meth:`_checked_odometry` accepts.
        _params: its parameters (a frozen params class, ``ParamsT``).
        _dt_s: the env's step, s: ``dt_s`` checked by :func:`checked_dt`, whose ``ValueError``
            names ``owner`` (by default the class's name).
    """

    name: ClassVar[str]

    def __init__(self, landmarks: LandmarkMap, params: ParamsT, *, dt_s: float, owner: str = "") -> None:
        self._dt_s = checked_dt(owner or type(self).__name__, dt_s)
        self._map = landmarks
        self._step_limit_m = landmarks.step_limit_m
        self._params = params

    @property
    def params(self) -> ParamsT:
        """The parameters it was made with."""
        return self._params

    def _checked_odometry(self, odometry: OdometryDelta) -> NDArray[np.float64]:
        """The increment as a ``(3,)`` array (:func:`checked_odometry`, named :attr:`name`, bounded by the map)."""
        return checked_odometry(self.name, odometry, self._step_limit_m)

    def _checked_increment(self, odometry: OdometryDelta) -> tuple[float, float, float]:
        """The increment as floats (:func:`checked_increment`, named :attr:`name`, bounded by the map)."""
        return checked_increment(self.name, odometry, self._step_limit_m)


# --------------------------------------------------------------------------------------
# The input checks every localizer makes. Each message names the localizer (``owner``) and
# the bad value; the exception types are part of the interface.


def require_reset(owner: str, ready: bool) -> None:
    """Raise ``RuntimeError`` unless ``reset()`` has been called (``ready``)."""
    if not ready:
        raise RuntimeError(f"{owner}: call reset() before predict() or update()")


def checked_dt(owner: str, dt_s: float) -> float:
    """``dt_s`` as a float, or ``ValueError`` when it is not a finite number > 0."""
    if not (math.isfinite(dt_s) and dt_s > 0.0):
        raise ValueError(f"{owner}: dt_s must be a positive number of seconds, got {dt_s!r}")
    return float(dt_s)


def checked_increment(owner: str, odometry: OdometryDelta, limit_m: float | None = None) -> tuple[float, float, float]:
    """The increment ``(dx, dy, dtheta)`` as floats, or :class:`MeasurementError` when it is impossible.

    Rejected: NaN and infinities; a translation ``hypot(dx, dy)`` longer than ``limit_m`` (a
    localizer passes its map's :attr:`LandmarkMap.step_limit_m`: by default the map's diagonal,
    which no single step can exceed); a turn ``|dtheta|`` of more than a full turn (2 pi).
    ``limit_m=None`` checks the turn only (a part without a map; its owner checks the
    translation). Raised before anything is changed, so the estimate stays as it was. Checked on
    Python floats: it runs every step of every localizer.
    """
    if not isinstance(odometry, OdometryDelta):
        raise MeasurementError(f"{owner}: expected an OdometryDelta, got {type(odometry).__name__}")
    d = (float(odometry.dx_m), float(odometry.dy_m), float(odometry.dtheta_rad))
    if not (math.isfinite(d[0]) and math.isfinite(d[1]) and math.isfinite(d[2])):
        raise MeasurementError(f"{owner}: odometry increment {list(d)} is not finite")
    if limit_m is not None:
        step = math.hypot(d[0], d[1])
        if step > limit_m:
            raise MeasurementError(
                f"{owner}: odometry increment {list(d)} translates {step!r} m, more than the bound of {limit_m!r} m"
                " (LandmarkMap.max_step_m, by default the map's diagonal)"
            )
    if abs(d[2]) > 2.0 * math.pi:
        raise MeasurementError(f"{owner}: odometry increment {list(d)} turns {d[2]!r} rad, more than a full turn (2 pi)")
    return d


def checked_odometry(owner: str, odometry: OdometryDelta, limit_m: float | None = None) -> NDArray[np.float64]:
    """:func:`checked_increment` as a ``(3,)`` float64 array."""
    return np.array(checked_increment(owner, odometry, limit_m), dtype=np.float64)


def checked_bearings(owner: str, measurement: BearingMeasurement, landmark_count: int) -> BearingMeasurement:
    """:meth:`BearingMeasurement.validated`, after checking that it is one (:class:`MeasurementError`)."""
    if not isinstance(measurement, BearingMeasurement):
        raise MeasurementError(f"{owner}: expected a BearingMeasurement, got {type(measurement).__name__}")
    return measurement.validated(landmark_count, source=owner)


def validated_scan(scan: ScanMeasurement, source: str = "scan") -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``(ranges, angles, max_range)`` of a scan as float64, or a :class:`MeasurementError`.

    Checked: a finite positive ``max_range_m``; 1-D ranges and angles of equal length;
    finite angles, strictly ascending (as :class:`ScanMeasurement` requires);
    ranges finite and in ``[0, max_range_m]``. The message names the first bad value and its
    beam index.
    """
    if not isinstance(scan, ScanMeasurement):
        raise MeasurementError(f"{source}: expected a ScanMeasurement, got {type(scan).__name__}")
    max_range = float(scan.max_range_m)
    if not (math.isfinite(max_range) and max_range > 0.0):
        raise MeasurementError(f"{source}: max_range_m must be a positive number of metres, got {scan.max_range_m!r}")
    ranges = np.asarray(scan.ranges_m, dtype=np.float64)
    angles = np.asarray(scan.angles_rad, dtype=np.float64)
    if ranges.ndim != 1 or angles.ndim != 1 or ranges.shape != angles.shape:
        raise MeasurementError(
            f"{source}: ranges_m and angles_rad must be 1-D of equal length, got shapes {ranges.shape} and {angles.shape}"
        )
    bad = ~np.isfinite(angles)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeasurementError(f"{source}: beam angle {float(angles[i])!r} rad at index {i} is not finite")
    bad = ~(np.diff(angles) > 0.0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0]) + 1
        raise MeasurementError(
            f"{source}: beam angles must ascend (ScanMeasurement.angles_rad), got {float(angles[i])!r} rad at index {i} "
            f"after {float(angles[i - 1])!r} rad"
        )
    bad = ~((ranges >= 0.0) & (ranges <= max_range))  # NaN fails both comparisons
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeasurementError(
            f"{source}: range {float(ranges[i])!r} m at index {i} is not a finite value in [0, max_range_m = {max_range!r}]"
        )
    return ranges, angles, max_range


#: the default position spread (m) past which a localizer stops claiming a pose (``max_spread_m``)
DEFAULT_MAX_SPREAD_M = 1.0


def check_max_spread(owner: str, value: float) -> float:
    """``value`` as a ``max_spread_m`` (a finite number of metres > 0, or ``inf``: never give up),
    else a :class:`~core.schema.ConfigError` naming ``owner`` and the value."""
    check(not math.isnan(value) and value > 0.0, f"{owner}.max_spread_m must be > 0 m (inf: no limit), got {value!r}")
    return float(value)


def within_spread(covariance: NDArray[np.float64], max_spread_m: float) -> bool:
    """Whether a pose with this ``(3, 3)`` covariance may be claimed: its position spread
    ``sqrt(P_xx + P_yy)`` is finite and at most ``max_spread_m``."""
    spread = math.sqrt(max(float(covariance[0, 0]) + float(covariance[1, 1]), 0.0))
    return math.isfinite(spread) and spread <= max_spread_m


def finite_covariance(estimate: PoseEstimate) -> NDArray[np.float64] | None:
    """The estimate's covariance as float64 when it is a finite ``(3, 3)``, else ``None`` (unknown)."""
    cov = np.asarray(estimate.covariance, dtype=np.float64)
    if cov.shape == (3, 3) and np.isfinite(cov).all():
        return cov
    return None
