"""Monte Carlo localization with a 2-D LIDAR against the static map (``mcl_lidar``).

The MCL of the far-point paper (docs/papers.md section B, Fujii et al.): Probabilistic Robotics
MCL (Table 8.2) with 1000 particles, the odometry motion model whose alpha1..alpha4 are
scaled by one *sampling parameter*, and the beam range-finder model (Table 6.1). Options
beyond the paper: the likelihood-field model (Table 6.3), KLD-sampling (Fox 2003; Table
8.4) and augmented-MCL recovery (Table 8.3).

What depends only on the map is precomputed once per map:

- beam model: a *ray-cast table* of the expected range ``z*`` for every cell of a grid over
  the map bounds and every one of ``table_directions`` world directions, computed with
  :func:`localizers.raycast.cast_rays` and cached on disk
  (:func:`localizers.range_table.build_range_table`);
- likelihood field: ``log(z_hit N(d; 0, sigma^2) + z_rand / z_max)`` per cell, ``d`` the
  distance from the cell centre to the nearest wall.

The measurement models and their numba kernels are in :mod:`localizers.beam_model`, the
table and its cache in :mod:`localizers.range_table`; this module re-exports their public
names.

Map size (measured on a synthetic 150 m x 100 m campus of 1,000 walls, one core): the
likelihood field is the only map model a ``likelihood_field`` filter builds (the ray-cast
table is built by :meth:`LidarMCL.beam_model` alone, for ``model: beam``); at 5 cm it is
6.2 M cells, 8 bytes each for the distances and 4 for the log field of each maximum range
(75 MB), built in about 0.4 s plus 0.4 s for the log field. The beam model's table of the
same grid at 720 directions would be 17 GB: the beam model is for rooms. Every table's memory
is estimated before it is built and one above ``max_table_mb`` refused (a beam model whose
table would be, when the filter is made); in such a world the env wrapper gives ``mcl_lidar``
:data:`LARGE_MAP_PARAMS`, the campus reference's likelihood field at 0.1 m (:func:`large_map_params`;
``crowdloc eval --env-id crowdloc/StereoCampus-v0 --localizers mcl_lidar``: peak RSS about
0.5 GB, errors of 6 cm, a pose on every step over 300 steps of ``route_follower``). What does not
scale: ``recovery_candidates`` (and the particles of a reset without a prior) are uniform
over the map bounds, so their density falls with the area: 20,000 candidates put about 4
within 0.25 m and 10 deg of the true pose in the 7 m x 7 m room, and 0.015 on the campus,
where injection therefore almost never recovers a lost filter; the weighing costs the
same (about 20 ms).

Motion is integrated lazily, as ROS amcl does: :meth:`LidarMCL.predict` composes the
odometry increments, and the particles are moved once, by the composed increment, when an
update is due (after ``update_min_travel_m`` of travel or ``update_min_rotation_rad`` of
turning; the paper localizes every 0.5 m). The alpha model's noise therefore refers to the
motion between two updates, not to the simulation step.

Consistency (measured, ``crowdloc reproduce lidar-far-point``, 10 seeds, NEES against the
truth at the updates): with the paper's beam model on all 1081 beams, each beam counted as
independent, the weights after an update are so peaked that resampling leaves copies of one
particle: the covariance is singular (NEES inf) on most updates at sampling >= 0.2 and the
NEES median is in the millions at 0.1, with errors of 8-9 cm. This is the beam model's
independence assumption, not a bug: ROS amcl's defaults (likelihood field, 30 beams) are
consistent in the same runs (NEES median 1.97, 84 % of updates inside the 95 % region); the
reference (these defaults on the LIDAR at 1.9 m, which sees over the crowd) has a NEES median
of 20-24. Between updates the covariance grows with the odometry not yet applied
(:func:`localizers.particles.motion_covariance`).
"""

from __future__ import annotations

import logging
import math
import statistics
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    ConsistencyPromise,
    LandmarkMap,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    ScanMeasurement,
    check_max_spread,
    checked_dt,
    checked_odometry,
    require_reset,
    within_spread,
)
from localizers.beam_model import BeamModel, LikelihoodFieldModel, beam_likelihood, p_hit, p_max, p_rand, p_short
from localizers.geometry import compose, wrap_angle
from localizers.particles import (
    MAX_PARTICLES,
    PARTICLE_MEMORY,
    LikelihoodAverages,
    gaussian_poses,
    motion_covariance,
    prior_covariance,
    propagate_particles,
    systematic_resample,
    uniform_poses,
    weighted_pose_covariance,
    weighted_pose_mean,
)
from localizers.range_table import (
    CACHE_ENV,
    MAX_TABLE_MB,
    RangeTable,
    build_range_table,
    cache_dir,
    check_range_table_size,
    range_table_key,
    range_table_shape,
    wall_distance_field,
)
from localizers.schema import check, check_at_most, check_ranges

__all__ = [
    "CACHE_ENV",
    "BeamModel",
    "LidarMCL",
    "LidarMCLParams",
    "LikelihoodFieldModel",
    "RangeTable",
    "beam_likelihood",
    "build_range_table",
    "cache_dir",
    "chi_square_sample_count",
    "informative",
    "kld_resample",
    "p_hit",
    "p_max",
    "p_rand",
    "p_short",
    "range_table_key",
    "validated_scan",
    "wall_distance_field",
]

Array = NDArray[np.float64]
_log = logging.getLogger(__name__)

#: mcl_lidar's parameters where the beam model's ray-cast table of the world's map would exceed
#: ``max_table_mb`` (a campus) and the user did not choose ``model``: ROS amcl's likelihood-field
#: configuration at 0.1 m, as the campus's LIDAR reference runs it (:mod:`agents.experiments.scene_maps`; no recovery or
#: lost test: injection drawn over a campus almost never lands near the robot, and the lost test fires
#: when people pass). With the beam model's defaults on the likelihood field, the campus filter spreads
#: along the sidewalk and claims a pose on 7 % of the steps (measured, 300 steps of route_follower)
LARGE_MAP_PARAMS: dict[str, Any] = {
    "model": "likelihood_field",
    "table_resolution_m": 0.1,
    "beam_stride": 8,
    "sampling": 1.0,
    "recovery": False,
    "lost_ratio": 0.0,
}

#: the most directions per cell of the ray-cast table (0.1 deg)
MAX_TABLE_DIRECTIONS = 3600


# --------------------------------------------------------------------------------------
# Parameters


@dataclass(frozen=True)
class LidarMCLParams:
    """LIDAR MCL parameters (defaults: ``configs/localizers/mcl_lidar.yaml``).

    Attributes:
        n_particles: set size (paper B: 1000); the initial size when KLD-sampling is on.
        sampling: the paper's "sampling parameter" (swept 0.1..1.0): the motion model uses
            ``alphas = sampling * alphas_base``.
        alphas_base: alpha1..alpha4 of the odometry motion model at ``sampling = 1``
            (Probabilistic Robotics Table 5.6; alpha1 rad^2/rad^2, alpha2 rad^2/m^2,
            alpha3 m^2/m^2, alpha4 m^2/rad^2).
        min_translation_std_m, min_rotation_std_rad: per-update motion-noise floors.
        update_min_travel_m, update_min_rotation_rad: an update is done once the robot has
            travelled or turned this much since the last one (0: at every scan).
        model: ``"beam"`` (Table 6.1, the paper's) or ``"likelihood_field"`` (Table 6.3).
        hit_std_m: sd of the hit Gaussian (the paper's "hit", swept 0.1..1.0).
        lambda_short: rate of the exponential of unexpected short readings, 1/m.
        z_hit, z_short, z_max, z_rand: mixture weights (sum to 1; the likelihood field uses
            z_hit and z_rand and skips max-range beams).
        beam_stride: use every ``beam_stride``-th beam (1: all).
        table_resolution_m: cell size of the ray-cast table and of the likelihood field.
        table_directions: directions per cell of the ray-cast table (720: 0.5 deg).
        max_table_mb: the most memory (MB, per process) one map table may take: the ray-cast
            table (4 bytes per cell and direction) or the likelihood field (about 12 bytes a
            cell). A table above it is refused with a :class:`~localizers.schema.ConfigError`
            when the filter is made (the beam model's) or its field built, giving the estimate
            and what to change. The beam model's table of a 150 m x 100 m campus at 5 cm and 720
            directions would be 17 GB: in such a world the env wrapper picks
            :data:`LARGE_MAP_PARAMS` unless ``model`` is given (:func:`large_map_params`).
        resample_ess_fraction: resample when the effective sample size falls below this
            fraction of the set (1.0: after every update, as Table 8.2).
        kld: adapt the set size by KLD-sampling (Fox 2003).
        kld_epsilon, kld_delta: bound on the KL divergence and its confidence ``1 - delta``.
        kld_bin_xy_m, kld_bin_theta_rad: histogram bin size of KLD-sampling.
        min_particles, max_particles: limits of the KLD set size.
        recovery: augmented MCL, random particles when the short-term likelihood average
            drops below the long-term one (Table 8.3), drawn from the scan (see
            ``recovery_candidates``). On by default (ours, issue 19); off is the paper's plain
            MCL, as its reproduction runs it.
        alpha_slow, alpha_fast: rates of the long- and short-term averages (kept with or
            without ``recovery``: they also tell when the filter is lost).
        lost_ratio: lost detection (ours): no pose is claimed while the short-term average of
            the per-beam likelihood is below ``lost_ratio`` times the long-term one (0: never).
        recovery_candidates: the injected particles are drawn, in proportion to their
            likelihood, from this many poses uniform over the map bounds, weighed by the scan
            (every ``recovery_beam_stride``-th beam) through the same measurement model (ours,
            sensor-resetting after Lenser and Veloso 2000; uniform particles alone almost
            never land near the pose in a room, so the book's injection does not recover).
            Only done when particles are injected.
        recovery_beam_stride: the beam stride of that weighing.
        max_spread_m: no pose is claimed while the position spread exceeds this (ours).
        min_range_m, min_informative_fraction: a scan in which fewer than this fraction of the
            (strided) beams read a range in ``(min_range_m, max_range)`` carries no information
            on the pose (a blank or blocked scan: all at the maximum range, all zero): it is not
            weighed, and the particles only move by the odometry (ours).
        initial_position_std_m, initial_heading_std_rad: spread around a prior without a
            finite covariance.
        parallel: evaluate the particles on numba's thread pool. Off by default: on a
            shared 2-core machine, or with several envs in parallel processes, waking the
            pool costs more than it saves; on a quiet multi-core machine it divides the
            update time by about the number of cores. Do not use it with filters running in
            several threads of one process (numba's default threading layer is not
            thread-safe). Not bit-reproducible against the serial kernel: freshly compiled,
            the parallel kernel gives the serial results exactly, but loaded from numba's disk
            cache its beam-model log-likelihoods differ by up to ~1e-9 relative (measured:
            5.2e-6 absolute on sums of ~-4000 over 1081 beams, 1000 particles; likelihood
            field 1.8e-12), with or without ``fastmath`` on the parallel variant (each particle
            is summed by one thread, in beam order, so it is not a thread-order reduction).
            Calls of one compiled kernel are deterministic; the pinned numbers use the serial one.
    """

    n_particles: int = 1000
    sampling: float = 0.1
    alphas_base: tuple[float, float, float, float] = (0.2, 0.2, 0.2, 0.2)
    min_translation_std_m: float = 0.005
    min_rotation_std_rad: float = 0.005
    update_min_travel_m: float = 0.5
    update_min_rotation_rad: float = math.pi / 6.0
    model: Literal["beam", "likelihood_field"] = "beam"
    hit_std_m: float = 0.2
    lambda_short: float = 0.1
    z_hit: float = 0.8
    z_short: float = 0.1
    z_max: float = 0.05
    z_rand: float = 0.05
    beam_stride: int = 1
    table_resolution_m: float = 0.05
    table_directions: int = 720
    max_table_mb: float = MAX_TABLE_MB
    resample_ess_fraction: float = 1.0
    kld: bool = False
    kld_epsilon: float = 0.05
    kld_delta: float = 0.01
    kld_bin_xy_m: float = 0.5
    kld_bin_theta_rad: float = math.radians(10.0)
    min_particles: int = 100
    max_particles: int = 5000
    recovery: bool = True
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    parallel: bool = False
    lost_ratio: float = 0.9
    recovery_candidates: int = 20_000
    recovery_beam_stride: int = 8
    max_spread_m: float = DEFAULT_MAX_SPREAD_M
    min_range_m: float = 0.1
    min_informative_fraction: float = 0.1

    def __post_init__(self) -> None:
        name = "LidarMCLParams"
        check(self.n_particles >= 2, f"{name}.n_particles must be >= 2, got {self.n_particles!r}")
        check(
            len(self.alphas_base) == 4 and all(math.isfinite(a) and a >= 0.0 for a in self.alphas_base),
            f"{name}.alphas_base must be four finite values >= 0, got {self.alphas_base!r}",
        )
        check_ranges(
            self,
            name,
            positive=(
                "sampling",
                "hit_std_m",
                "lambda_short",
                "table_resolution_m",
                "max_table_mb",
                "kld_epsilon",
                "kld_bin_xy_m",
                "kld_bin_theta_rad",
            ),
            non_negative=(
                "min_translation_std_m",
                "min_rotation_std_rad",
                "update_min_travel_m",
                "update_min_rotation_rad",
                "z_hit",
                "z_short",
                "z_max",
                "z_rand",
                "min_range_m",
                "initial_position_std_m",
                "initial_heading_std_rad",
            ),
        )
        total = self.z_hit + self.z_short + self.z_max + self.z_rand
        check(
            abs(total - 1.0) <= 1e-6,
            f"{name}: z_hit + z_short + z_max + z_rand must be 1 (Probabilistic Robotics Table 6.1), got {total!r}",
        )
        check_at_most(
            self,
            name,
            dict.fromkeys(("n_particles", "min_particles", "max_particles", "recovery_candidates"), MAX_PARTICLES),
            PARTICLE_MEMORY,
        )
        check(self.beam_stride >= 1, f"{name}.beam_stride must be >= 1, got {self.beam_stride!r}")
        check(self.table_directions >= 8, f"{name}.table_directions must be >= 8, got {self.table_directions!r}")
        check_at_most(
            self,
            name,
            {"table_directions": MAX_TABLE_DIRECTIONS},
            "0.1 deg, finer than a LIDAR's beam step (the UTM-30LX's is 0.25 deg), and memory: the ray-cast table holds a "
            "range per cell and direction",
        )
        check(
            0.0 < self.resample_ess_fraction <= 1.0,
            f"{name}.resample_ess_fraction must be in (0, 1], got {self.resample_ess_fraction!r}",
        )
        check(0.0 < self.kld_delta < 1.0, f"{name}.kld_delta must be in (0, 1), got {self.kld_delta!r}")
        check(
            2 <= self.min_particles <= self.max_particles,
            f"{name} needs 2 <= min_particles <= max_particles, got {self.min_particles!r}, {self.max_particles!r}",
        )
        check(
            0.0 < self.alpha_slow < self.alpha_fast <= 1.0,
            f"{name} needs 0 < alpha_slow < alpha_fast <= 1, got {self.alpha_slow!r}, {self.alpha_fast!r}",
        )
        check(0.0 <= self.lost_ratio <= 1.0, f"{name}.lost_ratio must be in [0, 1] (0: never lost), got {self.lost_ratio!r}")
        check(self.recovery_candidates >= 1, f"{name}.recovery_candidates must be >= 1, got {self.recovery_candidates!r}")
        check(self.recovery_beam_stride >= 1, f"{name}.recovery_beam_stride must be >= 1, got {self.recovery_beam_stride!r}")
        check_max_spread(name, self.max_spread_m)
        check(
            0.0 <= self.min_informative_fraction <= 1.0,
            f"{name}.min_informative_fraction must be in [0, 1], got {self.min_informative_fraction!r}",
        )

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        """The effective alpha1..alpha4: ``sampling * alphas_base``."""
        a1, a2, a3, a4 = (self.sampling * a for a in self.alphas_base)
        return (a1, a2, a3, a4)


def large_map_params(env: Any, sensor: str, params: Mapping[str, Any] | None) -> Mapping[str, Any] | None:
    """``mcl_lidar``'s preparation (its registry entry names it): in a world whose map would give
    the beam model a ray-cast table above ``max_table_mb`` (``env.landmark_map`` cut at the
    sensor's height), :data:`LARGE_MAP_PARAMS` under the user's ``params``, logged; otherwise, or
    when ``params`` names a ``model``, ``params`` unchanged (an explicit beam model is then
    refused when the filter is made, with the table's estimate)."""
    from localizers.registry import load_params

    if params is not None and not isinstance(params, Mapping):
        return params  # refused by name when the parameters are loaded
    return large_map_mcl(env, sensor, params, load_params("mcl_lidar", params), "mcl_lidar")


def large_map_mcl(
    env: Any, sensor: str, params: Mapping[str, Any] | None, resolved: LidarMCLParams, who: str
) -> Mapping[str, Any] | None:
    """The LIDAR MCL parameters ``params`` (which resolve to ``resolved``) for the world of ``env``:
    :data:`LARGE_MAP_PARAMS` under ``params`` where the beam model's table would exceed
    ``max_table_mb`` and ``params`` names no ``model``, logged as ``who``'s choice; else ``params``
    itself (the same object). Shared by ``mcl_lidar`` and ``far_point_mcl`` (its ``mcl`` section)."""
    from localizers.measurements import sensor_map

    if "model" in (params or {}) or resolved.model != "beam":
        return params
    bounds = sensor_map(env.landmark_map, env.sensor_metadata[sensor]).bounds_m
    shape = range_table_shape(bounds, resolved.table_resolution_m, resolved.table_directions)
    megabytes = math.prod(shape) * 4 / 1e6
    if megabytes <= resolved.max_table_mb:
        return params
    chosen = {**LARGE_MAP_PARAMS, **(params or {})}
    _log.warning(
        "%s: the beam model's ray-cast table of this %g m x %g m map would be %d x %d cells x %d directions "
        "(%.0f MB, above max_table_mb %g): using %s (the campus reference's likelihood field; give localizer_params "
        "model=... to choose)",
        who, bounds[2] - bounds[0], bounds[3] - bounds[1], *shape, megabytes, resolved.max_table_mb,
        ", ".join(f"{k} {v}" for k, v in chosen.items() if k in LARGE_MAP_PARAMS),
    )  # fmt: skip
    return chosen


# --------------------------------------------------------------------------------------
# Scan validation


def validated_scan(scan: ScanMeasurement, source: str = "scan") -> tuple[Array, Array, float]:
    """``(ranges, angles, max_range)`` of a scan as float64, or a :class:`MeasurementError`.

    Checked: a finite positive ``max_range_m``; 1-D ranges and angles of equal length;
    finite angles, strictly ascending (as :class:`~localizers.base.ScanMeasurement` requires);
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


def informative(ranges: Array, max_range: float, params: LidarMCLParams) -> bool:
    """Whether a scan carries information on the pose: at least ``min_informative_fraction`` of
    its beams read a range in ``(min_range_m, max_range)`` (not blank, not blocked)."""
    hits = int(np.count_nonzero((ranges > params.min_range_m) & (ranges < max_range)))
    return hits > 0 and hits >= params.min_informative_fraction * ranges.size


# --------------------------------------------------------------------------------------
# The filter


def chi_square_sample_count(k: ArrayLike, epsilon: float, delta: float) -> Array:
    """KLD-sampling bound (Fox 2003; Probabilistic Robotics Table 8.4, line 17).

    ``M_chi = (k - 1) / (2 eps) * (1 - 2 / (9 (k - 1)) + sqrt(2 / (9 (k - 1))) z_{1-delta})^3``
    samples keep the KL divergence between the sample-based and the true posterior below
    ``eps`` with probability ``1 - delta`` when the samples occupy ``k`` bins (0 for k <= 1).
    """
    kk = np.asarray(k, dtype=np.float64)
    z = statistics.NormalDist().inv_cdf(1.0 - delta)
    km1 = np.maximum(kk - 1.0, 1.0)
    a = 2.0 / (9.0 * km1)
    out = km1 / (2.0 * epsilon) * (1.0 - a + np.sqrt(a) * z) ** 3
    return np.where(kk > 1.0, out, 0.0)


def kld_resample(particles: Array, weights: Array, rng: np.random.Generator, params: LidarMCLParams) -> NDArray[np.intp]:
    """Ancestor indices of a KLD-sized resample (Fox 2003; Probabilistic Robotics Table 8.4).

    Up to ``max_particles`` ancestors are drawn by low-variance resampling and put in random
    order; the sample is cut at the first size ``M >= max(min_particles, M_chi(k(M)))``,
    ``k(M)`` the number of histogram bins (x, y, heading) occupied by the first ``M``.
    """
    cap = params.max_particles
    idx = systematic_resample(weights, cap, rng)
    idx = idx[rng.permutation(cap)]
    x = np.floor(particles[0, idx] / params.kld_bin_xy_m).astype(np.int64)
    y = np.floor(particles[1, idx] / params.kld_bin_xy_m).astype(np.int64)
    t = np.floor((np.asarray(wrap_angle(particles[2, idx])) + math.pi) / params.kld_bin_theta_rad).astype(np.int64)
    keys = (x * 1_000_003 + y) * 100_003 + t
    _, first = np.unique(keys, return_index=True)
    new_bin = np.zeros(cap, dtype=np.int64)
    new_bin[first] = 1
    k = np.cumsum(new_bin)
    m = np.arange(1, cap + 1)
    ok = (m >= params.min_particles) & (m >= chi_square_sample_count(k, params.kld_epsilon, params.kld_delta))
    count = int(np.argmax(ok)) + 1 if ok.any() else cap
    return idx[:count]


class LidarMCL:
    """MCL on LIDAR scans against the map's walls (Probabilistic Robotics Table 8.2).

    Per due update: move every particle by the odometry composed since the last update
    (alpha model, ``sampling * alphas_base``); add each particle's scan log-likelihood to its
    log-weight; with ``recovery``, update the averages of augmented MCL (of the per-beam
    geometric-mean likelihood, so scans of different lengths compare); resample (low
    variance, or KLD-sized) when the effective sample size is low, injecting uniform random
    particles with probability ``max(0, 1 - w_fast / w_slow)``.

    The estimate is the weighted mean (circular in heading) composed with the odometry not
    yet applied, and the weighted covariance. It is valid after a prior, or once a scan has
    been weighed.
    """

    name: ClassVar[str] = "mcl_lidar"
    #: measured on this run: share 0.562, NEES median 5.6: the beam model counts every beam as independent, so
    #: the cloud is narrower than the error (module docstring) (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/CrowdedRoom-v0", "random_walk", 500, 0.5)

    def __init__(self, landmarks: LandmarkMap, params: LidarMCLParams, *, dt_s: float) -> None:
        self._dt = checked_dt(type(self).__name__, dt_s)
        self._map = landmarks
        self._step_limit_m = landmarks.step_limit_m
        self._params = params
        self._alphas = np.asarray(params.alphas, dtype=np.float64)
        if params.model == "beam":  # refused here, not at the first scan: the table's size depends on the map only
            check_range_table_size(landmarks.bounds_m, params.table_resolution_m, params.table_directions, params.max_table_mb)
        self._beam_models: dict[float, BeamModel] = {}
        self._field: LikelihoodFieldModel | None = None
        self._rng: np.random.Generator | None = None
        self._particles = np.zeros((3, 0))
        self._log_w = np.zeros(0)
        self._weights = np.zeros(0)
        self._loglik = np.zeros(0)
        self._pending = np.zeros(3)
        self._travel_m = 0.0
        self._turn_rad = 0.0
        self._updates = 0
        self._valid = False
        self._averages = LikelihoodAverages(params.alpha_slow, params.alpha_fast)
        self._cache: tuple[Array, Array] | None = None

    # ------------------------------------------------------------------ map models
    def beam_model(self, max_range_m: float) -> BeamModel:
        """The beam model (and its ray-cast table) for a sensor of this maximum range."""
        model = self._beam_models.get(max_range_m)
        if model is None:
            p = self._params
            table = build_range_table(
                self._map,
                resolution_m=p.table_resolution_m,
                directions=p.table_directions,
                max_range_m=max_range_m,
                max_mb=p.max_table_mb,
            )
            model = self._beam_models[max_range_m] = BeamModel(table, p)
        return model

    def likelihood_field(self) -> LikelihoodFieldModel:
        if self._field is None:
            self._field = LikelihoodFieldModel(self._map, self._params)
        return self._field

    # ------------------------------------------------------------------ localizer API
    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Gaussian around ``prior`` (its covariance when finite), else uniform over the bounds."""
        self._rng = rng
        p = self._params
        n = p.n_particles
        if prior is None or not prior.valid:
            self._particles = uniform_poses(self._map.bounds_m, n, rng)
            self._valid = False
        else:
            cov = prior_covariance(prior, p.initial_position_std_m, p.initial_heading_std_rad)
            self._particles = gaussian_poses(prior.as_array(), cov, n, rng)
            self._valid = True
        self._set_uniform_weights(n)
        self._pending = np.zeros(3)
        self._travel_m = self._turn_rad = 0.0
        self._updates = 0
        self._averages.reset()
        self._cache = None

    def predict(self, odometry: OdometryDelta) -> None:
        """Compose the increment into the motion not yet applied to the particles."""
        self._generator()
        d = checked_odometry(self.name, odometry, self._step_limit_m)
        self._pending = compose(self._pending, d)
        self._travel_m += math.hypot(d[0], d[1])
        self._turn_rad += abs(d[2])

    def update(self, measurement: ScanMeasurement) -> None:
        """Weigh the particles by the scan when an update is due; resample when needed."""
        rng = self._generator()
        ranges, angles, max_range = validated_scan(measurement, self.name)
        p = self._params
        if not self.update_due:
            return
        stride = p.beam_stride
        ranges = np.ascontiguousarray(ranges[::stride])
        angles = np.ascontiguousarray(angles[::stride])
        used = ranges.size if p.model == "beam" else int(np.count_nonzero(ranges < max_range))
        if not informative(ranges, max_range, p):  # (no beam short of max_range is never informative)
            # nothing observed: the particles only move (once motion is due), nothing is weighed
            if self._travel_m >= p.update_min_travel_m or self._turn_rad >= p.update_min_rotation_rad:
                self._apply_motion(rng)
            return
        self._apply_motion(rng)
        n = self._particles.shape[1]
        if self._loglik.shape[0] != n:
            self._loglik = np.empty(n)
        ll = self._loglik
        self._log_likelihood(self._particles, ranges, angles, max_range, ll)
        self._updates += 1
        self._valid = True
        self._cache = None
        log_w = self._log_w
        log_w += ll
        peak = float(log_w.max())
        w = self._weights
        np.subtract(log_w, peak, out=w)
        np.exp(w, out=w)
        total = float(w.sum())
        w /= total
        log_w -= peak + math.log(total)  # normalized: logsumexp(log_w) == 0
        # Table 8.3 with w_avg = mean_i p(z | x_i), as a per-beam geometric mean
        ll_peak = float(ll.max())
        self._averages.update(math.exp((ll_peak + math.log(float(np.exp(ll - ll_peak).sum()) / n)) / used))
        n_inject = 0
        if p.recovery:
            p_inject = self._averages.injection_probability()
            n_inject = int(rng.binomial(n, p_inject)) if p_inject > 0.0 else 0
        if n_inject == 0 and 1.0 / float(w @ w) >= p.resample_ess_fraction * n:
            return
        self._resample(rng, n_inject, (ranges, angles, max_range))

    @property
    def params(self) -> LidarMCLParams:
        """The parameters it was made with."""
        return self._params

    @property
    def estimate(self) -> PoseEstimate:
        """Weighted mean and covariance, both carried through the pending odometry (the
        covariance by :func:`localizers.particles.motion_covariance`: the noise the particles
        will get when it is applied). No pose is claimed past ``max_spread_m`` or while lost."""
        if self._rng is None or not self._valid:
            return PoseEstimate.invalid()
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        mean, cov = self._cache
        pose = compose(mean, self._pending)
        p = self._params
        if self._pending.any():
            floors = {"min_translation_std_m": p.min_translation_std_m, "min_rotation_std_rad": p.min_rotation_std_rad}
            cov = motion_covariance(mean, cov, self._pending, self._alphas, **floors)
        valid = within_spread(cov, p.max_spread_m) and not self.lost
        return PoseEstimate(float(pose[0]), float(pose[1]), float(pose[2]), cov.copy(), valid)

    @property
    def lost(self) -> bool:
        """Whether the short-term average likelihood is below ``lost_ratio`` times the long-term one."""
        return self._averages.lost(self._params.lost_ratio)

    def overlay(self) -> Overlay:
        """The particles (moved by the pending odometry), shaded by weight."""
        n = self._particles.shape[1]
        if n == 0:
            return Overlay(label=f"{self.name}: no particles")
        w = self._weights / self._weights.max()
        return Overlay(poses=self.particles, weights=w, label=f"{self.name}: {n} particles")

    # ------------------------------------------------------------------ extras
    @property
    def particles(self) -> Array:
        """``(N, 3)`` particle poses with the pending odometry applied (heading wrapped)."""
        return compose(self._particles.T, self._pending)

    @property
    def weights(self) -> Array:
        """``(N,)`` normalized particle weights."""
        return self._weights.copy()

    @property
    def update_due(self) -> bool:
        """Whether the next scan will be weighed: the first after a reset, then after
        ``update_min_travel_m`` of travel or ``update_min_rotation_rad`` of turning."""
        p = self._params
        return self._updates == 0 or self._travel_m >= p.update_min_travel_m or self._turn_rad >= p.update_min_rotation_rad

    @property
    def likelihood_averages(self) -> tuple[float | None, float | None]:
        """``(w_slow, w_fast)`` of augmented MCL (None before the first weighed scan)."""
        return self._averages.slow, self._averages.fast

    @property
    def updates(self) -> int:
        """Number of scans weighed since the last reset."""
        return self._updates

    # ------------------------------------------------------------------ internals
    def _generator(self) -> np.random.Generator:
        rng = self._rng
        require_reset(type(self).__name__, rng is not None)
        assert rng is not None  # for mypy: require_reset raised otherwise
        return rng

    def _set_uniform_weights(self, n: int) -> None:
        self._log_w = np.full(n, -math.log(n))
        self._weights = np.full(n, 1.0 / n)

    def _apply_motion(self, rng: np.random.Generator) -> None:
        p = self._params
        if self._particles.shape[1]:
            propagate_particles(
                self._particles,
                self._pending,
                self._alphas,
                rng,
                min_translation_std_m=p.min_translation_std_m,
                min_rotation_std_rad=p.min_rotation_std_rad,
            )
        self._pending = np.zeros(3)
        self._travel_m = self._turn_rad = 0.0
        self._cache = None

    def _log_likelihood(self, particles: Array, ranges: Array, angles: Array, max_range: float, out: Array) -> None:
        p = self._params
        if p.model == "beam":
            self.beam_model(max_range).log_likelihood(particles, ranges, angles, out, parallel=p.parallel)
        else:
            self.likelihood_field().log_likelihood(particles, ranges, angles, max_range, out, parallel=p.parallel)

    def _injected(self, count: int, scan: tuple[Array, Array, float], rng: np.random.Generator) -> Array:
        """``(3, count)`` particles drawn from ``recovery_candidates`` uniform poses in
        proportion to their likelihood under the (strided) scan."""
        p = self._params
        pool = uniform_poses(self._map.bounds_m, p.recovery_candidates, rng)
        ranges, angles, max_range = scan
        stride = p.recovery_beam_stride
        ll = np.empty(pool.shape[1])
        self._log_likelihood(pool, np.ascontiguousarray(ranges[::stride]), np.ascontiguousarray(angles[::stride]), max_range, ll)
        w = np.exp(ll - ll.max())
        w /= w.sum()
        return pool[:, systematic_resample(w, count, rng)]

    def _resample(self, rng: np.random.Generator, n_inject: int, scan: tuple[Array, Array, float]) -> None:
        p = self._params
        w = self._weights
        if p.kld:
            idx = kld_resample(self._particles, w, rng, p)
            n = idx.shape[0]
            n_inject = min(n_inject, n)
            idx = idx[: n - n_inject]
        else:
            n = self._particles.shape[1]
            idx = systematic_resample(w, n - n_inject, rng)
        particles = np.empty((3, n))
        np.take(self._particles, idx, axis=1, out=particles[:, : n - n_inject])
        if n_inject:
            particles[:, n - n_inject :] = self._injected(n_inject, scan, rng)
        self._particles = particles
        self._set_uniform_weights(n)
        self._cache = None
