"""Monte Carlo localization with a 2-D LIDAR against the static map (``mcl_lidar``).

The MCL of the far-point paper (docs/papers.md section B, Fujii et al.): Probabilistic Robotics
MCL (Table 8.2) with 1000 particles, the odometry motion model whose alpha1..alpha4 are
scaled by one *sampling parameter*, and the beam range-finder model (Table 6.1). Options
beyond the paper: the likelihood-field model (Table 6.3), KLD-sampling (Fox 2003; Table
8.4) and augmented-MCL recovery (Table 8.3).

What depends only on the map is precomputed once per map:

- beam model: a *ray-cast table* of the expected range ``z*`` for every cell of a grid over
  the map bounds and every one of ``table_directions`` world directions, computed with
  :func:`localizers.raycast.cast_rays` and cached on disk (:func:`build_range_table`);
- likelihood field: ``log(z_hit N(d; 0, sigma^2) + z_rand / z_max)`` per cell, ``d`` the
  distance from the cell centre to the nearest wall.

Lookups take the cell containing the particle and the direction nearest to the beam's world
direction, so the expected range carries an error of up to half a cell diagonal and half a
direction step times the range. The per-particle, per-beam loop is a numba kernel; log
likelihoods are summed over beams (products of 16 beams at a time, then one log).

Motion is integrated lazily, as ROS amcl does: :meth:`LidarMCL.predict` composes the
odometry increments, and the particles are moved once, by the composed increment, when an
update is due (after ``update_min_travel_m`` of travel or ``update_min_rotation_rad`` of
turning; the paper localizes every 0.5 m). The alpha model's noise therefore refers to the
motion between two updates, not to the simulation step.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import statistics
import time
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Literal

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import (
    LandmarkMap,
    MeasurementError,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    ScanMeasurement,
    checked_dt,
    checked_odometry,
    require_reset,
)
from localizers.geometry import compose, wrap_angle
from localizers.particles import (
    gaussian_poses,
    prior_covariance,
    propagate_particles,
    systematic_resample,
    uniform_poses,
    weighted_pose_covariance,
    weighted_pose_mean,
)
from localizers.raycast import cast_rays
from localizers.schema import check

Array = NDArray[np.float64]
_log = logging.getLogger(__name__)

CACHE_ENV = "CROWDLOC_CACHE"
_TABLE_FORMAT = b"crowdloc-range-table-v1"
_P_FLOOR = 1e-12  # per-beam likelihood floor: a log never sees 0 (e.g. with z_rand = 0)
_CHUNK = 16  # beams multiplied before one log (16 * log10(1e-12) stays far above float64's range)
_GAUSS_U_MAX = 32.0  # the tabulated Gaussian exp(-u), u = d^2 / (2 sigma^2), is 0 beyond (e^-32 ~ 1e-14)
_GAUSS_SIZE = 8192  # entries over [0, _GAUSS_U_MAX]: nearest entry, relative error <= 0.2 %
_FIELD_MARGIN_M = 1.0  # the likelihood field extends this far beyond the map bounds


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
        resample_ess_fraction: resample when the effective sample size falls below this
            fraction of the set (1.0: after every update, as Table 8.2).
        kld: adapt the set size by KLD-sampling (Fox 2003).
        kld_epsilon, kld_delta: bound on the KL divergence and its confidence ``1 - delta``.
        kld_bin_xy_m, kld_bin_theta_rad: histogram bin size of KLD-sampling.
        min_particles, max_particles: limits of the KLD set size.
        recovery: augmented MCL, random particles when the short-term likelihood average
            drops below the long-term one (Table 8.3).
        alpha_slow, alpha_fast: rates of the long- and short-term averages.
        initial_position_std_m, initial_heading_std_rad: spread around a prior without a
            finite covariance.
        parallel: evaluate the particles on numba's thread pool. Off by default: on a
            shared 2-core machine, or with several envs in parallel processes, waking the
            pool costs more than it saves; on a quiet multi-core machine it divides the
            update time by about the number of cores. Do not use it with filters running in
            several threads of one process (numba's default threading layer is not
            thread-safe).
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
    resample_ess_fraction: float = 1.0
    kld: bool = False
    kld_epsilon: float = 0.05
    kld_delta: float = 0.01
    kld_bin_xy_m: float = 0.5
    kld_bin_theta_rad: float = math.radians(10.0)
    min_particles: int = 100
    max_particles: int = 5000
    recovery: bool = False
    alpha_slow: float = 0.001
    alpha_fast: float = 0.1
    initial_position_std_m: float = 0.1
    initial_heading_std_rad: float = 0.1
    parallel: bool = False

    def __post_init__(self) -> None:
        name = "LidarMCLParams"
        check(self.n_particles >= 2, f"{name}.n_particles must be >= 2, got {self.n_particles!r}")
        check(
            len(self.alphas_base) == 4 and all(math.isfinite(a) and a >= 0.0 for a in self.alphas_base),
            f"{name}.alphas_base must be four finite values >= 0, got {self.alphas_base!r}",
        )
        positive: tuple[str, ...] = ("sampling", "hit_std_m", "lambda_short", "table_resolution_m")
        positive += ("kld_epsilon", "kld_bin_xy_m", "kld_bin_theta_rad")
        for key in positive:
            value = getattr(self, key)
            check(math.isfinite(value) and value > 0.0, f"{name}.{key} must be > 0, got {value!r}")
        for key in (
            "min_translation_std_m",
            "min_rotation_std_rad",
            "update_min_travel_m",
            "update_min_rotation_rad",
            "z_hit",
            "z_short",
            "z_max",
            "z_rand",
            "initial_position_std_m",
            "initial_heading_std_rad",
        ):
            value = getattr(self, key)
            check(math.isfinite(value) and value >= 0.0, f"{name}.{key} must be >= 0, got {value!r}")
        total = self.z_hit + self.z_short + self.z_max + self.z_rand
        check(
            abs(total - 1.0) <= 1e-6,
            f"{name}: z_hit + z_short + z_max + z_rand must be 1 (Probabilistic Robotics Table 6.1), got {total!r}",
        )
        check(self.beam_stride >= 1, f"{name}.beam_stride must be >= 1, got {self.beam_stride!r}")
        check(self.table_directions >= 8, f"{name}.table_directions must be >= 8, got {self.table_directions!r}")
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

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        """The effective alpha1..alpha4: ``sampling * alphas_base``."""
        a1, a2, a3, a4 = (self.sampling * a for a in self.alphas_base)
        return (a1, a2, a3, a4)


# --------------------------------------------------------------------------------------
# Beam range-finder model (Probabilistic Robotics sec. 6.3, Table 6.1), pure functions


def p_hit(z: ArrayLike, z_star: ArrayLike, hit_std_m: float, max_range_m: float) -> Array:
    """Hit density, eqs. (6.4)-(6.6): ``eta N(z; z*, sigma^2)`` on ``[0, z_max]``, else 0.

    ``eta`` normalizes the Gaussian over ``[0, z_max]``, so the density integrates to one
    there for every ``z*`` in ``[0, z_max]``. Broadcasts ``z`` against ``z_star``.
    """
    zz, zs = np.broadcast_arrays(np.asarray(z, dtype=np.float64), np.asarray(z_star, dtype=np.float64))
    gauss = np.exp(-0.5 * ((zz - zs) / hit_std_m) ** 2) / (math.sqrt(2.0 * math.pi) * hit_std_m)
    return np.where((zz >= 0.0) & (zz <= max_range_m), gauss * _hit_eta(zs, hit_std_m, max_range_m), 0.0)


def p_short(z: ArrayLike, z_star: ArrayLike, lambda_short: float) -> Array:
    """Short-reading density, eqs. (6.7)-(6.9): ``eta lambda exp(-lambda z)`` on ``[0, z*]``.

    ``eta = 1 / (1 - exp(-lambda z*))`` normalizes it over ``[0, z*]``; for ``z* = 0`` (a
    particle on a wall) the interval is empty and the density is taken as 0.
    """
    zz, zs = np.broadcast_arrays(np.asarray(z, dtype=np.float64), np.asarray(z_star, dtype=np.float64))
    return np.where((zz >= 0.0) & (zz <= zs), lambda_short * np.exp(-lambda_short * zz) * _short_eta(zs, lambda_short), 0.0)


def p_max(z: ArrayLike, max_range_m: float) -> Array:
    """Max-range point mass, eq. (6.10): 1 where ``z >= z_max``, else 0.

    A probability mass, not a density: the mixture adds ``z_max * 1`` to a max-range beam's
    likelihood as Table 6.1 does, and it contributes nothing to an integral over
    ``[0, z_max)``.
    """
    return np.where(np.asarray(z, dtype=np.float64) >= max_range_m, 1.0, 0.0)


def p_rand(z: ArrayLike, max_range_m: float) -> Array:
    """Random-reading density, eq. (6.11): ``1 / z_max`` on ``[0, z_max)``, else 0."""
    zz = np.asarray(z, dtype=np.float64)
    return np.where((zz >= 0.0) & (zz < max_range_m), 1.0 / max_range_m, 0.0)


def beam_likelihood(z: ArrayLike, z_star: ArrayLike, params: LidarMCLParams, max_range_m: float) -> Array:
    """The mixture of Table 6.1 / eq. (6.12) for one beam: ``z_hit p_hit + z_short p_short +
    z_max p_max + z_rand p_rand``. Broadcasts ``z`` against ``z_star``."""
    return (
        params.z_hit * p_hit(z, z_star, params.hit_std_m, max_range_m)
        + params.z_short * p_short(z, z_star, params.lambda_short)
        + params.z_max * p_max(z, max_range_m)
        + params.z_rand * p_rand(z, max_range_m)
    )


def _hit_eta(z_star: Array, sigma: float, max_range_m: float) -> Array:
    """eq. (6.6): ``1 / (Phi((z_max - z*) / sigma) - Phi(-z* / sigma))``."""
    erf = np.frompyfunc(math.erf, 1, 1)
    scale = 1.0 / (sigma * math.sqrt(2.0))
    zs = np.asarray(z_star, dtype=np.float64)
    upper = np.asarray(erf((max_range_m - zs) * scale), dtype=np.float64)
    lower = np.asarray(erf(-zs * scale), dtype=np.float64)
    return np.asarray(2.0 / (upper - lower), dtype=np.float64)


def _short_eta(z_star: Array, lambda_short: float) -> Array:
    """eq. (6.9): ``1 / (1 - exp(-lambda z*))``, 0 for ``z* <= 0``."""
    zs = np.asarray(z_star, dtype=np.float64)
    denom = -np.expm1(-lambda_short * np.maximum(zs, 0.0))
    return np.divide(1.0, denom, out=np.zeros_like(denom), where=denom > 0.0)


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


# --------------------------------------------------------------------------------------
# Ray-cast table of the static map


def cache_dir() -> Path:
    """Where precomputed tables live: ``$CROWDLOC_CACHE``, default ``~/.cache/crowdloc``."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "crowdloc")


def range_table_key(
    walls_m: ArrayLike, bounds_m: tuple[float, float, float, float], resolution_m: float, directions: int, max_range_m: float
) -> str:
    """sha256 (hex) of everything a ray-cast table depends on."""
    h = hashlib.sha256(_TABLE_FORMAT)
    h.update(np.ascontiguousarray(np.asarray(walls_m, dtype=np.float64).reshape(-1, 4)).tobytes())
    h.update(np.asarray([*bounds_m, resolution_m, float(directions), max_range_m], dtype=np.float64).tobytes())
    return h.hexdigest()


@dataclass(frozen=True)
class RangeTable:
    """Expected ranges of the static map on a grid of cells x directions.

    Attributes:
        ranges_m: ``(nx, ny, D)`` float32: the range from the centre of cell ``(i, j)``,
            ``(x0 + (i + 1/2) res, y0 + (j + 1/2) res)``, in world direction ``2 pi k / D``
            (``max_range_m`` where no wall is hit).
        origin_xy_m: ``(x0, y0)``, the grid's lower-left corner (the map bounds' minimum).
        resolution_m: cell size.
        max_range_m: the range given to rays that hit nothing.
        key: the cache key (:func:`range_table_key`).
        loaded: whether the table came from the disk cache.
    """

    ranges_m: NDArray[np.float32]
    origin_xy_m: tuple[float, float]
    resolution_m: float
    max_range_m: float
    key: str
    loaded: bool

    @property
    def directions(self) -> int:
        return int(self.ranges_m.shape[2])

    def cell_index(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]:
        """Indices ``(i, j)`` of the cells containing the points, and whether they are inside the grid."""
        nx, ny, _ = self.ranges_m.shape
        fx = (np.asarray(x_m, dtype=np.float64) - self.origin_xy_m[0]) / self.resolution_m
        fy = (np.asarray(y_m, dtype=np.float64) - self.origin_xy_m[1]) / self.resolution_m
        inside = (fx >= 0) & (fx < nx) & (fy >= 0) & (fy < ny)
        i = np.clip(np.floor(fx), 0, nx - 1).astype(np.int64)
        j = np.clip(np.floor(fy), 0, ny - 1).astype(np.int64)
        return i, j, inside

    def lookup(self, x_m: ArrayLike, y_m: ArrayLike, world_angles_rad: ArrayLike) -> Array:
        """Expected ranges (nearest cell, nearest direction), ``nan`` outside the grid.

        Args:
            x_m, y_m: positions, broadcast against ``world_angles_rad``.
            world_angles_rad: world-frame directions.

        Returns:
            The broadcast shape of ranges (float64).
        """
        x, y, a = np.broadcast_arrays(
            np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64), np.asarray(world_angles_rad, dtype=np.float64)
        )
        i, j, inside = self.cell_index(x, y)
        d = self.directions
        k = np.floor(a * (d / (2.0 * math.pi)) + 0.5).astype(np.int64) % d
        return np.where(inside, self.ranges_m[i, j, k].astype(np.float64), np.nan)


@numba.njit(parallel=True, cache=True)
def _fill_range_table(
    x0: float, y0: float, res: float, nx: int, ny: int, directions: int, max_range: float, seg_a: Array, seg_b: Array
) -> NDArray[np.float32]:
    """``(nx, ny, D)`` ranges by :func:`cast_rays` from every cell centre."""
    out = np.empty((nx, ny, directions), dtype=np.float32)
    angles = 2.0 * math.pi * np.arange(directions) / directions
    no_centres = np.zeros((0, 2))
    no_radii = np.zeros(0)
    for c in numba.prange(nx * ny):
        i = c // ny
        j = c - i * ny
        origin = np.array([x0 + (i + 0.5) * res, y0 + (j + 0.5) * res])
        out[i, j, :] = cast_rays(origin, angles, max_range, seg_a, seg_b, no_centres, no_radii)
    return out


def build_range_table(
    landmarks: LandmarkMap, *, resolution_m: float, directions: int, max_range_m: float, cache: Path | None = None
) -> RangeTable:
    """The ray-cast table of a map's walls, loaded from the disk cache when present.

    The grid covers the map bounds (``ceil(extent / resolution)`` cells a side). The table is
    stored as ``<cache>/range_table_<sha256>.npy``, written atomically, and loaded
    memory-mapped (read-only); a cache that cannot be read or written is logged and skipped.

    Args:
        landmarks: the map (its ``walls_m`` and ``bounds_m``).
        resolution_m: cell size in metres.
        directions: world directions per cell, evenly spaced from 0.
        max_range_m: the sensor's maximum range.
        cache: cache directory (default: :func:`cache_dir`).
    """
    xmin, ymin, xmax, ymax = landmarks.bounds_m
    nx = max(1, math.ceil((xmax - xmin) / resolution_m - 1e-9))
    ny = max(1, math.ceil((ymax - ymin) / resolution_m - 1e-9))
    key = range_table_key(landmarks.walls_m, landmarks.bounds_m, resolution_m, directions, max_range_m)
    path = (cache or cache_dir()) / f"range_table_{key}.npy"
    shape = (nx, ny, directions)
    meta = ((xmin, ymin), float(resolution_m), float(max_range_m), key)
    if path.is_file():
        try:
            # memory-mapped, read-only: envs in several processes share one copy of the table
            ranges = np.asarray(np.load(path, mmap_mode="r", allow_pickle=False))
        except (OSError, ValueError) as exc:
            _log.warning("ignoring unreadable range table %s: %s", path, exc)
        else:
            if ranges.shape == shape and ranges.dtype == np.float32 and ranges.flags.c_contiguous:
                return RangeTable(ranges, *meta, loaded=True)
            _log.warning("ignoring range table %s of shape %s, dtype %s", path, ranges.shape, ranges.dtype)
    walls = landmarks.walls_m
    ranges = _fill_range_table(
        float(xmin), float(ymin), float(resolution_m), nx, ny, int(directions), float(max_range_m),
        np.ascontiguousarray(walls[:, :2]), np.ascontiguousarray(walls[:, 2:]),
    )  # fmt: skip
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.{time.monotonic_ns()}.tmp.npy")
        np.save(tmp, ranges)
        os.replace(tmp, path)
    except OSError as exc:
        _log.warning("could not cache the range table in %s: %s", path.parent, exc)
    ranges.setflags(write=False)
    return RangeTable(ranges, *meta, loaded=False)


def wall_distance_field(
    walls_m: ArrayLike, origin_xy_m: tuple[float, float], resolution_m: float, shape: tuple[int, int]
) -> Array:
    """``(nx, ny)`` distance from each cell centre to the nearest wall segment (inf without walls)."""
    walls = np.asarray(walls_m, dtype=np.float64).reshape(-1, 4)
    nx, ny = shape
    cx = origin_xy_m[0] + (np.arange(nx) + 0.5) * resolution_m
    cy = origin_xy_m[1] + (np.arange(ny) + 0.5) * resolution_m
    px, py = np.meshgrid(cx, cy, indexing="ij")
    best = np.full(shape, np.inf)
    for x1, y1, x2, y2 in walls:
        ex, ey = x2 - x1, y2 - y1
        length2 = ex * ex + ey * ey
        t = np.zeros(shape) if length2 == 0.0 else np.clip(((px - x1) * ex + (py - y1) * ey) / length2, 0.0, 1.0)
        np.minimum(best, np.hypot(px - (x1 + t * ex), py - (y1 + t * ey)), out=best)
    return best


# --------------------------------------------------------------------------------------
# Likelihood kernels (particles x beams)


@numba.njit(fastmath=True, cache=True, inline="always")
def _beam_one(
    x: float, y: float, heading: float, table: NDArray[np.float32], grid: Array, beam_dir: Array,
    beams: NDArray[np.float32], norms: NDArray[np.float32], gauss: NDArray[np.float32], consts: Array,
) -> float:  # fmt: skip
    """Sum over beams of ``log p(z_b | x)`` for one pose (see :class:`BeamModel`).

    Args:
        grid: ``(x0, y0, 1 / resolution, directions per radian)``.
        beam_dir: ``(B,)`` beam angles in direction units, in ``[0, D)``, plus 1/2.
        beams: ``(3, B)`` float32 rows ``z``, ``lambda exp(-lambda z)`` and ``z_max`` (for
            a max-range reading) or ``z_rand / z_max``.
        consts: ``(1 / dz of norms, 1 / (2 sigma^2 du) of gauss, log-likelihood outside the grid)``.
    """
    nx, ny, nd = table.shape
    fx = (x - grid[0]) * grid[2]
    fy = (y - grid[1]) * grid[2]
    if not (fx >= 0.0 and fx < nx and fy >= 0.0 and fy < ny):
        return consts[2]
    row = table[int(fx), int(fy)]
    h = heading * grid[3]
    h -= math.floor(h / nd) * nd
    base = int(h)
    if base >= nd:
        base -= nd
    frac = h - base
    inv_dz = np.float32(consts[0])
    gauss_scale = np.float32(consts[1])
    half = np.float32(0.5)
    zero = np.float32(0.0)
    floor = np.float32(_P_FLOOR)
    last = gauss.shape[0] - 1
    z = beams[0]
    short_rate = beams[1]
    rest = beams[2]
    n = z.shape[0]
    acc = 0.0
    # float32 per beam and branch-free: ~25 % faster than float64 with branches
    for start in range(0, n, _CHUNK):
        prod = 1.0  # float64: 16 beams of ~1e-3 would underflow float32
        for b in range(start, min(n, start + _CHUNK)):
            # nearest direction: round(heading + beam angle) in direction units, modulo D
            k = base + int(frac + beam_dir[b])
            k = k - nd if k >= nd else k
            k = k - nd if k >= nd else k
            zs = row[k]
            q = np.int32(zs * inv_dz + half)
            d = z[b] - zs
            g = gauss[min(np.int32(d * d * gauss_scale + half), last)]
            short = norms[q, 1] * short_rate[b] if d <= zero else zero  # z_short p_short, eqs. (6.7)-(6.9)
            p = norms[q, 0] * g + rest[b] + short  # + z_hit p_hit + (z_max p_max or z_rand p_rand)
            prod *= max(p, floor)
        acc += math.log(prod)
    return acc


@numba.njit(fastmath=True, cache=True, inline="always")
def _field_one(x: float, y: float, heading: float, field: NDArray[np.float32], grid: Array, ends: Array, outside: float) -> float:
    """Sum over beams of the field's log-likelihood at the beam end points ``ends`` ``(2, B)``
    (robot frame, in cell units); ``grid``: ``(x0, y0, 1 / resolution)``."""
    nx, ny = field.shape
    c = math.cos(heading)
    s = math.sin(heading)
    bx = (x - grid[0]) * grid[2]
    by = (y - grid[1]) * grid[2]
    acc = 0.0
    for b in range(ends.shape[1]):
        # beam end point, Table 6.3 lines 4-5
        fx = bx + c * ends[0, b] - s * ends[1, b]
        fy = by + s * ends[0, b] + c * ends[1, b]
        if fx >= 0.0 and fx < nx and fy >= 0.0 and fy < ny:
            acc += field[int(fx), int(fy)]
        else:
            acc += outside
    return acc


# one contiguous block of particles per thread (a prange over single particles costs more in scheduling)


@numba.njit(fastmath=True, cache=True)
def _beam_serial(blocks, particles, table, grid, beam_dir, beams, norms, gauss, consts, out):  # type: ignore[no-untyped-def]
    for i in range(particles.shape[1]):
        x, y, heading = particles[0, i], particles[1, i], particles[2, i]
        out[i] = _beam_one(x, y, heading, table, grid, beam_dir, beams, norms, gauss, consts)


@numba.njit(parallel=True, fastmath=True, cache=True)
def _beam_parallel(blocks, particles, table, grid, beam_dir, beams, norms, gauss, consts, out):  # type: ignore[no-untyped-def]
    n = particles.shape[1]
    size = (n + blocks - 1) // blocks
    for blk in numba.prange(blocks):
        for i in range(blk * size, min(n, blk * size + size)):
            x, y, heading = particles[0, i], particles[1, i], particles[2, i]
            out[i] = _beam_one(x, y, heading, table, grid, beam_dir, beams, norms, gauss, consts)


@numba.njit(fastmath=True, cache=True)
def _field_serial(blocks, particles, field, grid, ends, outside, out):  # type: ignore[no-untyped-def]
    for i in range(particles.shape[1]):
        out[i] = _field_one(particles[0, i], particles[1, i], particles[2, i], field, grid, ends, outside)


@numba.njit(parallel=True, fastmath=True, cache=True)
def _field_parallel(blocks, particles, field, grid, ends, outside, out):  # type: ignore[no-untyped-def]
    n = particles.shape[1]
    size = (n + blocks - 1) // blocks
    for blk in numba.prange(blocks):
        for i in range(blk * size, min(n, blk * size + size)):
            out[i] = _field_one(particles[0, i], particles[1, i], particles[2, i], field, grid, ends, outside)


class BeamModel:
    """Beam-model log-likelihoods of particles against a ray-cast table (Table 6.1, in logs).

    The normalizers ``eta`` of p_hit and p_short depend on ``z*`` only; they are tabulated
    over ``z*`` at ``min(1 cm, hit_std_m / 4)``, and ``exp(-u)`` of the hit Gaussian over
    ``u = (z - z*)^2 / (2 sigma^2)`` (relative error below 0.2 %).
    """

    def __init__(self, table: RangeTable, params: LidarMCLParams) -> None:
        self.table = table
        self.params = params
        zmax = table.max_range_m
        sigma = params.hit_std_m
        dz = min(0.01, sigma / 4.0)
        zq = np.arange(int(zmax / dz + 0.5) + 1, dtype=np.float64) * dz
        norms = np.empty((zq.size, 2), dtype=np.float32)
        norms[:, 0] = params.z_hit * _hit_eta(zq, sigma, zmax) / (math.sqrt(2.0 * math.pi) * sigma)
        norms[:, 1] = params.z_short * _short_eta(zq, params.lambda_short)
        self._norms = norms
        self._inv_dz = 1.0 / dz
        u = np.arange(_GAUSS_SIZE + 1) * (_GAUSS_U_MAX / _GAUSS_SIZE)
        gauss = np.exp(-u).astype(np.float32)
        gauss[-1] = 0.0
        self._gauss = gauss
        self._gauss_scale = _GAUSS_SIZE / _GAUSS_U_MAX / (2.0 * sigma * sigma)
        self._dir_per_rad = table.directions / (2.0 * math.pi)
        self._grid = np.array([*table.origin_xy_m, 1.0 / table.resolution_m, self._dir_per_rad])

    def log_likelihood(self, particles: Array, ranges_m: Array, angles_rad: Array, out: Array, *, parallel: bool) -> None:
        """``out[i] = sum_b log p(z_b | x_i)`` for ``(3, N)`` particles and ``(B,)`` beams."""
        p = self.params
        zmax = self.table.max_range_m
        beam_dir = np.mod(angles_rad, 2.0 * math.pi) * self._dir_per_rad + 0.5
        rest = np.where(ranges_m >= zmax, p.z_max, p.z_rand / zmax)
        beams = np.stack([ranges_m, p.lambda_short * np.exp(-p.lambda_short * ranges_m), rest]).astype(np.float32)
        # a particle outside the grid explains no beam: only the max / random components remain
        outside = float(np.sum(np.log(np.maximum(rest, _P_FLOOR))))
        consts = np.array([self._inv_dz, self._gauss_scale, outside])
        kernel = _beam_parallel if parallel else _beam_serial
        t = self.table
        kernel(numba.get_num_threads(), particles, t.ranges_m, self._grid, beam_dir, beams, self._norms, self._gauss, consts, out)


class LikelihoodFieldModel:
    """Likelihood-field log-likelihoods (Table 6.3): ``sum_b log(z_hit N(d_b; 0, sigma^2) + z_rand / z_max)``.

    ``d_b`` is the distance from the end point of beam ``b`` to the nearest wall, read from a
    grid over the map bounds plus 1 m at ``table_resolution_m``; end points off the grid
    score ``log(z_rand / z_max)``. Max-range beams are skipped (Table 6.3, line 3).
    """

    def __init__(self, landmarks: LandmarkMap, params: LidarMCLParams) -> None:
        self.params = params
        res = params.table_resolution_m
        xmin, ymin, xmax, ymax = landmarks.bounds_m
        self.origin_xy_m = (xmin - _FIELD_MARGIN_M, ymin - _FIELD_MARGIN_M)
        shape = (
            max(1, math.ceil((xmax - xmin + 2 * _FIELD_MARGIN_M) / res - 1e-9)),
            max(1, math.ceil((ymax - ymin + 2 * _FIELD_MARGIN_M) / res - 1e-9)),
        )
        self.distance_m = wall_distance_field(landmarks.walls_m, self.origin_xy_m, res, shape)
        self._fields: dict[float, NDArray[np.float32]] = {}

    def log_field(self, max_range_m: float) -> NDArray[np.float32]:
        """``(nx, ny)`` per-cell ``log(z_hit N(d; 0, sigma^2) + z_rand / z_max)``."""
        if max_range_m not in self._fields:
            p = self.params
            sigma = p.hit_std_m
            q = p.z_hit * np.exp(-0.5 * (self.distance_m / sigma) ** 2) / (math.sqrt(2.0 * math.pi) * sigma)
            q += p.z_rand / max_range_m
            self._fields[max_range_m] = np.log(np.maximum(q, _P_FLOOR)).astype(np.float32)
        return self._fields[max_range_m]

    def log_likelihood(
        self, particles: Array, ranges_m: Array, angles_rad: Array, max_range_m: float, out: Array, *, parallel: bool
    ) -> None:
        """``out[i] = sum_b log q_b`` over the beams shorter than ``max_range_m``."""
        p = self.params
        keep = ranges_m < max_range_m
        inv_res = 1.0 / p.table_resolution_m
        ends = np.stack([ranges_m[keep] * np.cos(angles_rad[keep]), ranges_m[keep] * np.sin(angles_rad[keep])]) * inv_res
        outside = math.log(max(p.z_rand / max_range_m, _P_FLOOR))
        grid = np.array([*self.origin_xy_m, inv_res])
        kernel = _field_parallel if parallel else _field_serial
        kernel(numba.get_num_threads(), particles, self.log_field(max_range_m), grid, ends, outside, out)


# --------------------------------------------------------------------------------------
# Scan validation


def validated_scan(scan: ScanMeasurement, source: str = "scan") -> tuple[Array, Array, float]:
    """``(ranges, angles, max_range)`` of a scan as float64, or a :class:`MeasurementError`.

    Checked: a finite positive ``max_range_m``; 1-D ranges and angles of equal length;
    finite angles; ranges finite and in ``[0, max_range_m]``. The message names the first
    bad value and its beam index.
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
    bad = ~((ranges >= 0.0) & (ranges <= max_range))  # NaN fails both comparisons
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise MeasurementError(
            f"{source}: range {float(ranges[i])!r} m at index {i} is not a finite value in [0, max_range_m = {max_range!r}]"
        )
    return ranges, angles, max_range


# --------------------------------------------------------------------------------------
# The filter


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

    def __init__(self, landmarks: LandmarkMap, params: LidarMCLParams, *, dt_s: float) -> None:
        self._dt = checked_dt(type(self).__name__, dt_s)
        self._map = landmarks
        self._params = params
        self._alphas = np.asarray(params.alphas, dtype=np.float64)
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
        self._w_slow: float | None = None
        self._w_fast: float | None = None
        self._cache: tuple[Array, Array] | None = None

    # ------------------------------------------------------------------ map models
    def beam_model(self, max_range_m: float) -> BeamModel:
        """The beam model (and its ray-cast table) for a sensor of this maximum range."""
        model = self._beam_models.get(max_range_m)
        if model is None:
            p = self._params
            table = build_range_table(
                self._map, resolution_m=p.table_resolution_m, directions=p.table_directions, max_range_m=max_range_m
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
        self._w_slow = self._w_fast = None
        self._cache = None

    def predict(self, odometry: OdometryDelta) -> None:
        """Compose the increment into the motion not yet applied to the particles."""
        self._generator()
        d = checked_odometry(self.name, odometry)
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
        if used == 0:
            return  # nothing observed: keep the motion pending
        self._apply_motion(rng)
        n = self._particles.shape[1]
        if self._loglik.shape[0] != n:
            self._loglik = np.empty(n)
        ll = self._loglik
        if p.model == "beam":
            self.beam_model(max_range).log_likelihood(self._particles, ranges, angles, ll, parallel=p.parallel)
        else:
            self.likelihood_field().log_likelihood(self._particles, ranges, angles, max_range, ll, parallel=p.parallel)
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
        n_inject = 0
        if p.recovery:
            # Table 8.3 with w_avg = mean_i p(z | x_i), as a per-beam geometric mean
            ll_peak = float(ll.max())
            w_avg = math.exp((ll_peak + math.log(float(np.exp(ll - ll_peak).sum()) / n)) / used)
            if self._w_slow is None or self._w_fast is None:
                self._w_slow = self._w_fast = w_avg
            else:
                self._w_slow += p.alpha_slow * (w_avg - self._w_slow)
                self._w_fast += p.alpha_fast * (w_avg - self._w_fast)
            p_inject = max(0.0, 1.0 - self._w_fast / self._w_slow) if self._w_slow > 0.0 else 0.0
            n_inject = int(rng.binomial(n, p_inject)) if p_inject > 0.0 else 0
        if n_inject == 0 and 1.0 / float(w @ w) >= p.resample_ess_fraction * n:
            return
        self._resample(rng, n_inject)

    @property
    def estimate(self) -> PoseEstimate:
        """Weighted mean (composed with the pending odometry) and weighted covariance."""
        if self._rng is None or not self._valid:
            return PoseEstimate.invalid()
        if self._cache is None:
            mean = weighted_pose_mean(self._particles, self._weights)
            self._cache = (mean, weighted_pose_covariance(self._particles, mean, self._weights))
        mean, cov = self._cache
        pose = compose(mean, self._pending)
        return PoseEstimate(float(pose[0]), float(pose[1]), float(pose[2]), cov.copy(), True)

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
        """``(w_slow, w_fast)`` of augmented MCL (None before the first update with recovery)."""
        return self._w_slow, self._w_fast

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

    def _resample(self, rng: np.random.Generator, n_inject: int) -> None:
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
            particles[:, n - n_inject :] = uniform_poses(self._map.bounds_m, n_inject, rng)
        self._particles = particles
        self._set_uniform_weights(n)
        self._cache = None
