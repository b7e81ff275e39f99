"""Scan accumulation and far-point extraction (docs/papers.md section B, Fujii et al.), and ``far_point_mcl``.

In a crowded room people stand *in front of* the walls as seen from the robot. The paper
therefore (1) accumulates the LIDAR hit points of the last ``travel_m`` of travel in one
frame, using odometry only, and (2) splits them into narrow angular bins around the
robot's current pose and keeps, in each bin, the point farthest from the robot. What is
left looks like a scan of the empty room and is fed to MCL in place of the raw scan.

Frames: the *odometry frame* starts at the robot's pose at :meth:`ScanFilter.reset` and
follows the composed odometry increments; everything the filter stores lives there.

``far_point_mcl`` reports the MCL's covariance plus what its fixes inherit from the odometry
that placed the window's points (``window_error``, ours; :func:`window_covariance`). Measured in
the crowded room (``random_walk``, 500 steps, seeds 0-4, ``tests/localizers/test_consistency_promises.py``'s
protocol): 75-100 % of the steps inside the 95 % region, NEES medians 0.7-1.7; without it
40-62 % and 6.5-17. The estimate is the same either way.

Mapping to the LIDAR's beam format: the full turn around the robot is split into
``n = round(2 pi / bin_width_rad)`` equal bins, bin ``j`` centred on the robot-frame
direction ``j 2 pi / n`` (so 0.25 deg bins are centred on the 0.25 deg beams of a
UTM-30LX). Beam ``b`` at angle ``a_b`` reads the bin ``round(a_b n / 2 pi) mod n`` that
contains its direction: the distance of that bin's far point, clipped to the maximum
range, or the maximum range when the bin is empty. Bins narrower than the beam spacing
leave some bins unread; wider bins give several beams the same point.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import between, compose, wrap_angle
from core.schema import check, check_at_most
from localizers.base import (
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    ScanMeasurement,
    checked_odometry,
    require_reset,
    validated_scan,
    within_spread,
)
from localizers.bounds import odometry_process_noise
from localizers.mcl_lidar import LidarMCL, LidarMCLParams, deskewed, informative, large_map_mcl

Array = NDArray[np.float64]


#: the most points the window may keep (ten times the default): about 60 bytes a point (its coordinates,
#: their buffer and the extraction's scratch), 300 MB at the bound
MAX_WINDOW_POINTS = 5_000_000
#: the most angular bins (0.01 deg): far finer than any LIDAR's beam step, and an array of each size per extraction
MAX_BINS = 36_000


@dataclass(frozen=True)
class ScanFilterParams:
    """Accumulation and far-point extraction (defaults: ``configs/localizers/far_point_mcl.yaml``).

    Attributes:
        travel_m: accumulation distance: the window holds the points of the scans taken
            during the last ``travel_m`` of travel (paper B: 0.5 m).
        bin_width_rad: angular bin width of the extraction, rounded so that a whole number
            of bins fills the turn (ours: 0.25 deg, the UTM-30LX beam step).
        max_points: most points kept; the oldest scans go first when it is exceeded (ours:
            bounds memory while the robot stands still and the window never closes).
    """

    travel_m: float = 0.5
    bin_width_rad: float = math.radians(0.25)
    max_points: int = 500_000

    def __post_init__(self) -> None:
        ok = math.isfinite(self.travel_m) and self.travel_m >= 0.0
        check(ok, f"ScanFilterParams.travel_m must be >= 0, got {self.travel_m!r}")
        check(
            math.isfinite(self.bin_width_rad) and 0.0 < self.bin_width_rad <= math.pi,
            f"ScanFilterParams.bin_width_rad must be in (0, pi], got {self.bin_width_rad!r}",
        )
        check(self.max_points >= 1, f"ScanFilterParams.max_points must be >= 1, got {self.max_points!r}")
        check_at_most(self, "ScanFilterParams", {"max_points": MAX_WINDOW_POINTS}, "memory: about 60 bytes a point")
        check(
            self.bins <= MAX_BINS,
            f"ScanFilterParams.bin_width_rad must be at least 2 pi / {MAX_BINS:,} (0.01 deg: finer than any LIDAR's beam "
            f"step, and memory: arrays of one entry per bin), got {self.bin_width_rad!r}",
        )

    @property
    def bins(self) -> int:
        """Number of angular bins in a full turn."""
        return max(2, round(2.0 * math.pi / self.bin_width_rad))


# --------------------------------------------------------------------------------------
# Far-point extraction (pure functions)


def _bin_positions(dx: Array, dy: Array, heading_rad: float, bins: int, out: Array) -> Array:
    """Continuous bin coordinate ``(atan2(dy, dx) - heading) n / 2 pi + 1/2 + 2 n``, in ``(0, 4 n + 1)``."""
    np.arctan2(dy, dx, out=out)  # numpy's SIMD arctan2: ~10x a scalar loop
    out -= float(wrap_angle(heading_rad))
    out *= bins / (2.0 * math.pi)
    out += 0.5 + 2.0 * bins
    return out


def angular_bins(dx: ArrayLike, dy: ArrayLike, heading_rad: float, bins: int) -> NDArray[np.int64]:
    """Bin of each direction ``(dx, dy)`` (world frame) relative to ``heading_rad``.

    Bin ``j`` of ``n`` is centred on the relative direction ``j 2 pi / n``:
    ``j = floor((atan2(dy, dx) - heading) n / 2 pi + 1/2) mod n``.

    Returns:
        ``(m,)`` bin indices in ``[0, bins)``.
    """
    x = np.ascontiguousarray(dx, dtype=np.float64)
    y = np.ascontiguousarray(dy, dtype=np.float64)
    pos = _bin_positions(x, y, heading_rad, bins, np.empty(x.shape))
    return np.floor(pos).astype(np.int64) % bins


@numba.njit(cache=True)
def _farthest(dx: Array, dy: Array, pos: Array, bins: int, best_d2: Array, best_index: NDArray[np.int64]) -> None:
    best_d2[:] = -1.0
    best_index[:] = -1
    for i in range(dx.shape[0]):
        j = int(pos[i]) % bins  # positions are positive: int() is floor
        d2 = dx[i] * dx[i] + dy[i] * dy[i]
        if d2 > best_d2[j]:  # strict: the first of equally far points stays
            best_d2[j] = d2
            best_index[j] = i


def far_points(
    x_m: ArrayLike,
    y_m: ArrayLike,
    origin_xy_m: ArrayLike,
    heading_rad: float,
    bins: int,
    *,
    scratch: tuple[Array, Array, Array] | None = None,
) -> tuple[NDArray[np.int64], Array]:
    """The farthest point from ``origin`` in each angular bin around ``(origin, heading)``.

    Args:
        x_m, y_m: ``(m,)`` point coordinates.
        origin_xy_m: ``(2,)`` the robot's position.
        heading_rad: the robot's heading (bin 0 is centred on it).
        bins: number of bins in the full turn (see :func:`angular_bins`).
        scratch: three float64 arrays of at least ``m`` values to reuse (speed only).

    Returns:
        ``(bins,)`` index of the far point in each bin (-1 when empty) and ``(bins,)`` its
        distance from ``origin`` (``nan`` when empty).
    """
    x = np.ascontiguousarray(x_m, dtype=np.float64)
    y = np.ascontiguousarray(y_m, dtype=np.float64)
    m = x.shape[0]
    if scratch is None or scratch[0].shape[0] < m:
        scratch = (np.empty(m), np.empty(m), np.empty(m))
    dx, dy, pos = (s[:m] for s in scratch)
    ox, oy = (float(v) for v in np.asarray(origin_xy_m, dtype=np.float64))
    np.subtract(x, ox, out=dx)
    np.subtract(y, oy, out=dy)
    _bin_positions(dx, dy, heading_rad, bins, pos)
    best_d2 = np.empty(bins)
    best_index = np.empty(bins, dtype=np.int64)
    _farthest(dx, dy, pos, bins, best_d2, best_index)
    dist = np.sqrt(best_d2, out=best_d2, where=best_index >= 0)
    dist[best_index < 0] = np.nan
    return best_index, dist


# --------------------------------------------------------------------------------------
# The accumulating filter


class ScanFilter:
    """Accumulates hit points in the odometry frame and extracts far points.

    Call :meth:`predict` with each odometry increment and :meth:`add_scan` with each scan
    (taken at the pose reached by the increments so far); :meth:`extract` returns the
    processed scan around the current odometry pose.
    """

    def __init__(self, params: ScanFilterParams) -> None:
        self.params = params
        self._bins = params.bins
        self._x = np.empty(0)
        self._y = np.empty(0)
        self._start = 0
        self._end = 0
        # (travel at the scan, number of points, odometry-frame pose at the scan)
        self._scans: deque[tuple[float, int, Array]] = deque()
        self._pose = np.zeros(3)
        self._travel_m = 0.0
        self._scratch: tuple[Array, Array, Array] | None = None
        self._far: tuple[NDArray[np.int64], Array] | None = None

    def reset(self) -> None:
        """Forget every point; the odometry frame restarts at the current pose."""
        self._start = self._end = 0
        self._scans.clear()
        self._pose = np.zeros(3)
        self._travel_m = 0.0
        self._far = None

    def predict(self, odometry: OdometryDelta) -> None:
        """Integrate one odometry increment into the odometry-frame pose."""
        d = checked_odometry("scan filter", odometry)
        self._pose = compose(self._pose, d)
        self._travel_m += math.hypot(d[0], d[1])
        self._far = None

    def add_scan(self, scan: ScanMeasurement) -> None:
        """Store the scan's hit points (ranges below the maximum) and drop what left the window."""
        self.add_readings(*validated_scan(scan, "scan filter"))

    def add_readings(self, ranges: Array, angles: Array, max_range: float) -> None:
        """:meth:`add_scan` of checked readings (robot frame; the angles in any order: a deskewed scan's)."""
        hit = ranges < max_range
        r, a = ranges[hit], angles[hit]
        x, y, theta = self._pose
        # robot frame -> odometry frame: rotate by the heading, then translate
        px = x + r * np.cos(a + theta)
        py = y + r * np.sin(a + theta)
        self._append(px, py)
        self._far = None

    def extract(self, angles_rad: ArrayLike, max_range_m: float) -> ScanMeasurement:
        """The far-point scan around the current odometry pose, in the given beam format.

        Args:
            angles_rad: ``(B,)`` beam angles (robot frame) of the output.
            max_range_m: the sensor's maximum range (empty bins; longer ranges are clipped).

        Returns:
            A :class:`ScanMeasurement` with ``(B,)`` ranges (see the module docstring).
        """
        angles = np.asarray(angles_rad, dtype=np.float64)
        index, dist = self._far_points()
        beam_bins = angular_bins(np.cos(angles), np.sin(angles), 0.0, self._bins)
        ranges = np.where(index[beam_bins] >= 0, np.minimum(dist[beam_bins], max_range_m), max_range_m)
        ranges = np.nan_to_num(ranges, nan=max_range_m)
        return ScanMeasurement(ranges, angles.copy(), float(max_range_m))

    def update(self, scan: ScanMeasurement) -> ScanMeasurement:
        """:meth:`add_scan`, then :meth:`extract` in the scan's own beam format."""
        self.add_scan(scan)
        return self.extract(scan.angles_rad, scan.max_range_m)

    # ------------------------------------------------------------------ views
    @property
    def odometry_pose(self) -> Array:
        """``(3,)`` the robot's pose in the odometry frame."""
        return self._pose.copy()

    @property
    def travel_m(self) -> float:
        """Path length travelled since the reset."""
        return self._travel_m

    @property
    def window_increment(self) -> Array:
        """``(3,)`` the odometry from the oldest scan still in the window to the current pose, in
        that scan's frame (zeros while the window is empty): how far odometry alone carried the
        points the window holds."""
        if not self._scans:
            return np.zeros(3)
        return between(self._scans[0][2], self._pose)

    @property
    def points_xy(self) -> Array:
        """``(m, 2)`` the accumulated points, oldest first (odometry frame)."""
        return np.stack([self._x[self._start : self._end], self._y[self._start : self._end]], axis=1)

    @property
    def far_points_xy(self) -> Array:
        """``(k, 2)`` the extracted far points around the current pose (odometry frame)."""
        index, _ = self._far_points()
        keep = index[index >= 0] + self._start
        return np.stack([self._x[keep], self._y[keep]], axis=1)

    def to_world(self, points_xy: Array, robot_pose_world: ArrayLike) -> Array:
        """Odometry-frame points ``(m, 2)`` -> world frame, given the robot's world pose now."""
        robot = np.asarray(robot_pose_world, dtype=np.float64)
        # world_from_odom = robot_world * inverse(robot_odom)
        dtheta = robot[2] - self._pose[2]
        c, s = math.cos(dtheta), math.sin(dtheta)
        rel = points_xy - self._pose[:2]
        out = np.empty_like(rel)
        out[:, 0] = robot[0] + c * rel[:, 0] - s * rel[:, 1]
        out[:, 1] = robot[1] + s * rel[:, 0] + c * rel[:, 1]
        return out

    # ------------------------------------------------------------------ internals
    def _far_points(self) -> tuple[NDArray[np.int64], Array]:
        if self._far is None:
            m = self._end - self._start
            if self._scratch is None or self._scratch[0].shape[0] < m:
                size = max(m, min(self.params.max_points, 2 * m))
                self._scratch = (np.empty(size), np.empty(size), np.empty(size))
            self._far = far_points(
                self._x[self._start : self._end],
                self._y[self._start : self._end],
                self._pose[:2],
                float(self._pose[2]),
                self._bins,
                scratch=self._scratch,
            )
        return self._far

    def _append(self, px: Array, py: Array) -> None:
        cap = self.params.max_points
        k = px.shape[0]
        if k > cap:  # a single scan above the cap: keep its last points
            px, py, k = px[-cap:], py[-cap:], cap
        self._scans.append((self._travel_m, k, self._pose.copy()))
        # drop scans that left the travel window, then the oldest ones beyond the cap
        while self._scans and self._travel_m - self._scans[0][0] > self.params.travel_m:
            self._start += self._scans.popleft()[1]
        while self._end - self._start + k > cap:
            self._start += self._scans.popleft()[1]
        if self._end + k > self._x.shape[0]:
            live = self._end - self._start
            size = min(cap, max(2 * (live + k), 4096))
            if size > self._x.shape[0]:
                x, y = np.empty(size), np.empty(size)
            else:
                x, y = self._x, self._y
            x[:live] = self._x[self._start : self._end]  # overlapping copies are safe: numpy buffers them
            y[:live] = self._y[self._start : self._end]
            self._x, self._y = x, y
            self._start, self._end = 0, live
        self._x[self._end : self._end + k] = px
        self._y[self._end : self._end + k] = py
        self._end += k


# --------------------------------------------------------------------------------------
# far_point_mcl: the filtered scan fed to LIDAR MCL


def window_covariance(pose: ArrayLike, window: ArrayLike, mcl: LidarMCLParams) -> Array:
    """``(3, 3)`` what a fix on the accumulation window inherits from its odometry
    (:attr:`FarPointMCLParams.window_error`): a third of the MCL's motion-model noise
    (:func:`localizers.bounds.odometry_process_noise`) for the increment ``window`` that ends
    at ``pose``, the estimate with the fix applied."""
    end = np.asarray(pose, dtype=np.float64)
    start = compose(end, between(window, np.zeros(3)))  # the pose at the window's oldest scan
    noise = odometry_process_noise(start, window, mcl.alphas, min_translation_std_m=mcl.min_translation_std_m,
                                   min_rotation_std_rad=mcl.min_rotation_std_rad)  # fmt: skip
    return noise / 3.0


@dataclass(frozen=True)
class FarPointMCLParams:
    """``far_point_mcl`` (defaults: ``configs/localizers/far_point_mcl.yaml``).

    Attributes:
        mcl: the LIDAR MCL that consumes the processed scans; its estimate is this
            localizer's, its ``max_spread_m`` the limit past which no pose is claimed.
        filter: accumulation and far-point extraction.
        deskew: undo the robot's motion during each swept scan before accumulating it (ours;
            off in the paper's reproduction): ``mcl_lidar``'s option
            (:attr:`localizers.mcl_lidar.LidarMCLParams.deskew`) applied to the raw scans,
            whose hit points the window keeps. ``mcl.deskew`` is refused: the far-point scans the
            MCL weighs are made at the current pose and have no beam times.
        window_error: add the odometry noise of the accumulation window to the reported
            covariance (ours; the paper reports none). The window's points were placed by
            odometry alone, so a fix on them inherits its error, shared by all their beams, which
            the beam model counts as independent. The oldest points carry the noise of the whole
            increment from their scan to now (:attr:`ScanFilter.window_increment`, under the
            MCL's motion model), the newest none; the fix inherits about their mean
            displacement, and the average of a random walk over the window has a third of its
            end's variance, so a third is added, from each fix until the next (the particles'
            own spread grows meanwhile). The estimate itself is the same either way.
    """

    mcl: LidarMCLParams = field(default_factory=LidarMCLParams)
    filter: ScanFilterParams = field(default_factory=ScanFilterParams)
    deskew: bool = False
    window_error: bool = True

    def __post_init__(self) -> None:
        check(
            not self.mcl.deskew,
            "FarPointMCLParams.mcl.deskew must be false: far_point_mcl deskews the raw scans it accumulates (set its "
            "top-level deskew: true); the far-point scans its MCL weighs are made at the current pose, with no beam times",
        )


def large_map_params(env: Any, sensor: str, params: Mapping[str, Any] | None) -> Mapping[str, Any] | None:
    """``far_point_mcl``'s preparation (its registry entry names it): its ``mcl`` section gets what
    ``mcl_lidar`` gets in a world too large for the beam model's table
    (:func:`localizers.mcl_lidar.large_map_mcl`: the campus reference's likelihood field, logged);
    elsewhere, or when the section names a ``model``, ``params`` unchanged."""
    from localizers.registry import load_params

    section = (params or {}).get("mcl") if isinstance(params, Mapping) else None
    if (params is not None and not isinstance(params, Mapping)) or (section is not None and not isinstance(section, Mapping)):
        return params  # refused by name when the parameters are loaded
    resolved = load_params("far_point_mcl", params)
    assert isinstance(resolved, FarPointMCLParams)
    chosen = large_map_mcl(env, sensor, section, resolved.mcl, "far_point_mcl")
    return params if chosen is section else {**(params or {}), "mcl": chosen}


class FarPointMCL(LocalizerBase[FarPointMCLParams]):
    """LIDAR MCL on accumulated, far-point-extracted scans (paper B's method).

    Every scan is accumulated; when the MCL is due for an update (every
    ``mcl.update_min_travel_m`` of travel, 0.5 m in the paper) the far-point scan around the
    current pose is extracted and weighed instead of the raw scan.
    """

    name: ClassVar[str] = "far_point_mcl"
    #: measured on this run: share 0.854, NEES median 1.70 (without ``window_error``: 0.400 and 11.9, the
    #: beams of scans accumulated over 0.5 m counting as independent while the odometry that placed them
    #: shifts them all) (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/CrowdedRoom-v0", "random_walk", 500, 0.8)

    def __init__(self, landmarks: LandmarkMap, params: FarPointMCLParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s)
        self.mcl = LidarMCL(landmarks, params.mcl, dt_s=self._dt_s)
        self.filter = ScanFilter(params.filter)
        self._ready = False
        self._last: ScanMeasurement | None = None
        self._processed: ScanMeasurement | None = None
        # what the last fix on the window's points inherits from their odometry (window_covariance
        # at the estimate right after it; zeros before the first, or when that fix left no valid pose)
        self._window_cov = np.zeros((3, 3))
        #: fixes made on the window's points since the reset (an update on a blank scan is none)
        self.window_fixes = 0

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        self.mcl.reset(rng, prior)
        self.filter.reset()
        self._ready = True
        self._last = None
        self._processed = None
        self._window_cov = np.zeros((3, 3))
        self.window_fixes = 0

    def predict(self, odometry: OdometryDelta) -> None:
        require_reset(type(self).__name__, self._ready)
        self._checked_odometry(odometry)  # named for this localizer (the parts check again)
        self.mcl.predict(odometry)
        self.filter.predict(odometry)

    def update(self, measurement: ScanMeasurement) -> None:
        """Accumulate the scan; when MCL is due, weigh the particles by the far-point scan.

        When the scan itself carries no information (:func:`localizers.mcl_lidar.informative`:
        blank, or blocked), the window holds only older points: the MCL gets a blank scan
        instead (it moves the particles and weighs nothing), so that a sensor that sees nothing
        now does not fix the pose on points already weighed.
        """
        require_reset(type(self).__name__, self._ready)
        if self.params.deskew:
            ranges, angles, max_range = validated_scan(measurement, self.name)
            lags = None if measurement.beam_lags_s is None else np.asarray(measurement.beam_lags_s)
            self.filter.add_readings(
                *deskewed(ranges, angles, max_range, lags, self.mcl.increment, self.mcl.dt_s, self.name), max_range
            )
        else:
            self.filter.add_scan(measurement)  # validates
        self._last = measurement
        if self.mcl.update_due:
            max_range = float(measurement.max_range_m)
            ranges = np.asarray(measurement.ranges_m, dtype=np.float64)
            if informative(ranges[:: self.params.mcl.beam_stride], max_range, self.params.mcl):
                self._processed = self.filter.extract(measurement.angles_rad, max_range)
                self.mcl.update(self._processed)
                self.window_fixes += 1
                if self.params.window_error:  # the fix was made on the window's points: it keeps their error
                    est = self.mcl.estimate
                    window = self.filter.window_increment
                    self._window_cov = (
                        window_covariance(est.as_array(), window, self.params.mcl) if est.valid else np.zeros((3, 3))
                    )
            else:
                self._processed = ScanMeasurement(np.full(ranges.shape, max_range), np.asarray(measurement.angles_rad), max_range)
                self.mcl.update(self._processed)

    @property
    def estimate(self) -> PoseEstimate:
        """The MCL's estimate; its covariance widened by the window's odometry noise at the last
        fix (``window_error``, :func:`window_covariance`)."""
        est = self.mcl.estimate
        if not (est.valid and self.params.window_error):
            return est
        cov = est.covariance + self._window_cov
        return PoseEstimate(est.x_m, est.y_m, est.theta_rad, cov, within_spread(cov, self.params.mcl.max_spread_m))

    @property
    def updates(self) -> int:
        """Number of far-point scans weighed since the last reset."""
        return self.mcl.updates

    @property
    def processed_scan(self) -> ScanMeasurement | None:
        """The far-point scan handed to the MCL at its latest update (None before the first)."""
        return self._processed

    def overlay(self) -> Overlay:
        """The particles, and the accumulated and far points placed by the current estimate."""
        base = self.mcl.overlay()
        est = self.mcl.estimate
        if not est.valid or self._last is None:
            return base
        pose = est.as_array()
        points = np.concatenate(
            [self.filter.to_world(self.filter.points_xy, pose), self.filter.to_world(self.filter.far_points_xy, pose)]
        )
        return Overlay(base.poses, base.weights, points, f"{base.label}, {points.shape[0]} scan points")
