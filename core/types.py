"""The data both sides of crowdloc share: the known map, the measurement dataclasses a sensor's
observation decodes to, a localizer's pose estimate and what a renderer may draw of it.

Plain frozen dataclasses over numpy arrays, so the same localizer code runs on simulated and
on recorded data. Units are metres and radians; bearings are counter-clockwise from the
robot's heading, in ``[-pi, pi)``.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from core.geometry import spanning
from core.schema import is_real


class MeasurementError(ValueError):
    """A measurement handed to a localizer is malformed (NaN, out of range, wrong shape)."""


@dataclass(frozen=True)
class LandmarkMap:
    """The known map: landmark positions, static walls and the field they live on.

    Attributes:
        positions_xy_m: ``(L, 2)`` landmark positions in the world frame.
        names: ``L`` landmark names (for reports).
        bounds_m: ``(xmin, ymin, xmax, ymax)`` of the region the robot can be in.
        walls_m: ``(S, 4)`` static wall segments ``(x1, y1, x2, y2)`` (what a LIDAR sees of the map).
        wall_heights_m: ``(S, 2)`` the height interval ``[bottom, top)`` each segment spans (a
            table's top, a shelf lower than a sensor); ``None``: every wall from the floor up
            without end. :meth:`at_height` keeps the walls a sensor at one height sees.
        features: per world feature name, its map data as plain values (a ceiling's targets:
            their positions and colour codes); empty for worlds without features.
        max_step_m: the longest translation one odometry increment may have, in metres; a
            longer one is a :class:`MeasurementError` (see :func:`checked_increment`). ``None``
            (the default) means the diagonal of ``bounds_m``: no single step can cross more than
            the whole map. Recorded data whose steps are known to be shorter (a logged robot's top
            speed times its period, with margin) may set a tighter, documented limit here.
        disk_cache: whether tables built from this map (a LIDAR's range table) may be kept in the
            disk cache. A seeded layout's map (:mod:`envs.layouts`) says False: a task draws
            thousands of layouts, and a room's table (56 MB) is rebuilt in memory in about 0.3 s.
    """

    positions_xy_m: NDArray[np.float64]
    names: tuple[str, ...]
    bounds_m: tuple[float, float, float, float]
    walls_m: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 4)))
    features: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)
    max_step_m: float | None = None
    wall_heights_m: NDArray[np.float64] | None = None
    disk_cache: bool = True

    def __post_init__(self) -> None:
        pos = np.asarray(self.positions_xy_m, dtype=np.float64)
        if pos.ndim != 2 or pos.shape[1] != 2:
            raise ValueError(f"LandmarkMap.positions_xy_m must have shape (L, 2), got {pos.shape}")
        if len(self.names) != pos.shape[0]:
            raise ValueError(f"LandmarkMap has {pos.shape[0]} positions but {len(self.names)} names")
        xmin, ymin, xmax, ymax = self.bounds_m
        if not (xmax > xmin and ymax > ymin):
            raise ValueError(f"LandmarkMap.bounds_m must be (xmin, ymin, xmax, ymax) with max > min, got {self.bounds_m}")
        walls = np.asarray(self.walls_m, dtype=np.float64).reshape(-1, 4)
        if self.max_step_m is not None and not (math.isfinite(self.max_step_m) and self.max_step_m > 0.0):
            raise ValueError(f"LandmarkMap.max_step_m must be a finite number of metres > 0 or None, got {self.max_step_m!r}")
        if self.wall_heights_m is None:
            heights = np.tile([-math.inf, math.inf], (walls.shape[0], 1))
        else:
            heights = np.asarray(self.wall_heights_m, dtype=np.float64).reshape(-1, 2)
            if heights.shape[0] != walls.shape[0] or np.isnan(heights).any() or np.any(heights[:, 0] >= heights[:, 1]):
                raise ValueError(
                    f"LandmarkMap.wall_heights_m must hold one (bottom, top) with bottom < top per wall ({walls.shape[0]}), "
                    f"got shape {heights.shape}"
                )
        for array in (pos, walls, heights):
            array.setflags(write=False)
        object.__setattr__(self, "positions_xy_m", pos)
        object.__setattr__(self, "walls_m", walls)
        object.__setattr__(self, "wall_heights_m", heights)

    def at_height(self, height_m: float) -> LandmarkMap:
        """The map as a sensor at ``height_m`` sees it: only the walls spanning that height."""
        if not math.isfinite(height_m):
            raise ValueError(f"LandmarkMap.at_height: height_m must be finite, got {height_m!r}")
        h = self.heights
        keep = spanning(h[:, 0], h[:, 1], height_m)
        if keep.all():
            return self
        return dataclasses.replace(self, walls_m=self.walls_m[keep], wall_heights_m=h[keep])

    @property
    def heights(self) -> NDArray[np.float64]:
        """``(S, 2)`` each wall's ``[bottom, top)`` (set in ``__post_init__``)."""
        assert self.wall_heights_m is not None
        return self.wall_heights_m

    @property
    def count(self) -> int:
        return int(self.positions_xy_m.shape[0])

    @property
    def step_limit_m(self) -> float:
        """The longest odometry translation a localizer on this map accepts: ``max_step_m``, else the diagonal of ``bounds_m``."""
        if self.max_step_m is not None:
            return float(self.max_step_m)
        xmin, ymin, xmax, ymax = self.bounds_m
        return math.hypot(xmax - xmin, ymax - ymin)


@dataclass(frozen=True)
class OdometryDelta:
    """Motion since the previous step, in the frame of the previous (odometry) pose.

    Each field must be a real number (numpy's included; not a bool or a string), else
    :class:`MeasurementError` names the field at construction; finiteness and size are checked
    where a localizer takes it (:func:`checked_increment`).
    """

    dx_m: float
    dy_m: float
    dtheta_rad: float

    def __post_init__(self) -> None:
        if type(self.dx_m) is float and type(self.dy_m) is float and type(self.dtheta_rad) is float:
            return  # the usual case, every step: nothing more to look at
        for name in ("dx_m", "dy_m", "dtheta_rad"):
            value = getattr(self, name)
            if not is_real(value):
                raise MeasurementError(f"OdometryDelta.{name} must be a number, got {type(value).__name__} {value!r}")

    def as_array(self) -> NDArray[np.float64]:
        return np.array([self.dx_m, self.dy_m, self.dtheta_rad], dtype=np.float64)


@dataclass(frozen=True)
class BearingMeasurement:
    """Bearings to identified landmarks seen in one frame.

    Attributes:
        landmark_ids: ``(n,)`` indices into the :class:`LandmarkMap` (unique).
        bearings_rad: ``(n,)`` bearings in the robot frame, in ``[-pi, pi]``.
    """

    landmark_ids: NDArray[np.int64]
    bearings_rad: NDArray[np.float64]

    @staticmethod
    def empty() -> BearingMeasurement:
        return BearingMeasurement(np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float64))

    def validated(self, landmark_count: int, source: str = "bearing measurement") -> BearingMeasurement:
        """Return a copy with checked dtypes, or raise :class:`MeasurementError` naming the bad value."""
        ids = np.asarray(self.landmark_ids)
        bearings = np.asarray(self.bearings_rad, dtype=np.float64)
        if ids.ndim != 1 or bearings.ndim != 1 or ids.shape != bearings.shape:
            raise MeasurementError(
                f"{source}: landmark_ids and bearings_rad must be 1-D of equal length, got {ids.shape} and {bearings.shape}"
            )
        # Checked on Python lists: a frame has a handful of ids, and this runs every step.
        listed = ids.tolist()
        if listed and (ids.dtype.kind not in "iu" or min(listed) < 0 or max(listed) >= landmark_count):
            raise MeasurementError(f"{source}: landmark id out of range 0..{landmark_count - 1}: {listed}")
        if len(set(listed)) != len(listed):
            raise MeasurementError(f"{source}: repeated landmark id in {listed}")
        limit = np.pi + 1e-9
        for i, b in enumerate(bearings.tolist()):
            if not -limit <= b <= limit:  # also NaN and inf
                raise MeasurementError(
                    f"{source}: bearing {bearings[i]!r} rad to landmark {int(ids[i])} is not a finite angle in [-pi, pi]"
                )
        return BearingMeasurement(ids.astype(np.int64), bearings)


@dataclass(frozen=True)
class ScanMeasurement:
    """One 2-D range scan.

    Attributes:
        ranges_m: ``(B,)`` ranges; ``max_range_m`` where nothing was hit.
        angles_rad: ``(B,)`` beam angles in the robot frame, ascending.
        max_range_m: the sensor's maximum range.
        beam_lags_s: ``(B,)`` how long before the scan's end each beam was taken (a swept scanner:
            a driver stamping each beam, as ROS's ``LaserScan.time_increment`` does); None: all at
            the end. Only a localizer's ``deskew`` reads it.
    """

    ranges_m: NDArray[np.float64]
    angles_rad: NDArray[np.float64]
    max_range_m: float
    beam_lags_s: NDArray[np.float64] | None = None


#: what types a stereo camera's vertical edges have (paper D): colour channel (R, G, B) x detection
#: row (topmost first) x polarity (rising, falling), numbered by :func:`envs.stereo.edges.edge_type`
EDGE_CHANNELS, EDGE_LEVELS, EDGE_POLARITIES = 3, 5, 2
EDGE_TYPES = EDGE_CHANNELS * EDGE_LEVELS * EDGE_POLARITIES  # 30


@dataclass(frozen=True)
class EdgeMeasurement:
    """Typed vertical edges seen by a stereo camera in one frame (paper D's landmarks).

    Attributes:
        types: ``(n,)`` edge types in ``0..EDGE_TYPES - 1`` (:func:`envs.stereo.edges.edge_type`).
        inverse_range_m: ``(n,)`` 1 / range from the robot centre, 1/m, finite and > 0.
        bearings_rad: ``(n,)`` bearings in the robot frame, counter-clockwise from the heading.
    """

    types: NDArray[np.int64]
    inverse_range_m: NDArray[np.float64]
    bearings_rad: NDArray[np.float64]

    def validated(self, source: str = "edge measurement") -> EdgeMeasurement:
        """Return a copy with checked dtypes, or raise :class:`MeasurementError` naming the bad value."""
        t = np.asarray(self.types)
        inv = np.asarray(self.inverse_range_m, dtype=np.float64)
        b = np.asarray(self.bearings_rad, dtype=np.float64)
        if t.ndim != 1 or inv.shape != t.shape or b.shape != t.shape:
            raise MeasurementError(f"{source}: types, inverse_range_m and bearings_rad must be 1-D of one length, got "
                                   f"{t.shape}, {inv.shape}, {b.shape}")  # fmt: skip
        if t.size and (t.dtype.kind not in "iu" or t.min() < 0 or t.max() >= EDGE_TYPES):
            raise MeasurementError(f"{source}: edge types must be integers in 0..{EDGE_TYPES - 1}, got {t.tolist()!r}")
        bad = ~(np.isfinite(inv) & (inv > 0.0))
        if bad.any():
            raise MeasurementError(
                f"{source}: inverse ranges must be finite and > 0 (a range in (0, inf)), got {float(inv[bad][0])!r}"
            )
        if not np.isfinite(b).all():
            raise MeasurementError(f"{source}: bearings must be finite, got {float(b[~np.isfinite(b)][0])!r}")
        return EdgeMeasurement(t.astype(np.int64), inv, b)


@dataclass(frozen=True, eq=False)
class PoseEstimate:
    """A localizer's answer.

    Attributes:
        x_m, y_m, theta_rad: the pose (heading in ``[-pi, pi)``); meaningless when not ``valid``.
        covariance: ``(3, 3)`` covariance of (x, y, theta), or a spread-equivalent diagonal.
        valid: whether the localizer currently claims a pose at all.
    """

    x_m: float
    y_m: float
    theta_rad: float
    covariance: NDArray[np.float64] = field(default_factory=lambda: np.full((3, 3), np.nan))
    valid: bool = True

    def __eq__(self, other: object) -> bool:
        # NaN-aware and array-aware, so that equal estimates compare equal (determinism checks)
        if not isinstance(other, PoseEstimate):
            return NotImplemented
        return (
            self.valid == other.valid
            and np.array_equal(self.as_array(), other.as_array(), equal_nan=True)
            and np.array_equal(self.covariance, other.covariance, equal_nan=True)
        )

    __hash__ = None  # type: ignore[assignment]

    def __deepcopy__(self, memo: dict[int, Any]) -> PoseEstimate:
        # The fields are immutable but the covariance: copy just that (the generic dataclass
        # path is ~5x slower, and stable-baselines3's DummyVecEnv deep-copies every info each step).
        copied = PoseEstimate(self.x_m, self.y_m, self.theta_rad, copy.deepcopy(self.covariance, memo), self.valid)
        memo[id(self)] = copied
        return copied

    @staticmethod
    def invalid() -> PoseEstimate:
        return PoseEstimate(np.nan, np.nan, np.nan, np.full((3, 3), np.nan), False)

    def as_array(self) -> NDArray[np.float64]:
        return np.array([self.x_m, self.y_m, self.theta_rad], dtype=np.float64)

    @property
    def position_spread_m(self) -> float:
        """sqrt of the trace of the position covariance (nan when unknown)."""
        return float(np.sqrt(self.covariance[0, 0] + self.covariance[1, 1]))

    @property
    def heading_spread_rad(self) -> float:
        return float(np.sqrt(self.covariance[2, 2]))


@dataclass(frozen=True)
class Overlay:
    """What a renderer may draw for a localizer (all arrays may be empty).

    Attributes:
        poses: ``(n, 3)`` hypotheses (particles, candidates) in the world frame.
        weights: ``(n,)`` relative importance in ``[0, 1]`` for shading.
        points_xy: ``(m, 2)`` extra points (accumulated scan points, for example).
        label: a short caption.
    """

    poses: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 3)))
    weights: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    points_xy: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    label: str = ""
