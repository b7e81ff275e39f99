"""The ray-cast range table of a map's walls, its disk cache, and the wall-distance field.

What the LIDAR MCL (:mod:`localizers.mcl_lidar`) precomputes once per map:

- beam model: a *ray-cast table* of the expected range ``z*`` for every cell of a grid over
  the map bounds and every one of ``table_directions`` world directions, computed with
  :func:`core.raycast.cast_rays` and cached on disk (:func:`build_range_table`);
- likelihood field: the distance from each cell centre to the nearest wall
  (:func:`wall_distance_field`).

Both grow with the map's area: a table's memory is estimated before anything is allocated
(:func:`check_table_size`) and a table above its bound (:data:`MAX_TABLE_MB` by default) is
refused with a :class:`~core.schema.ConfigError` that gives the estimate and what to
change. The beam model's table of a 150 m x 100 m campus at 5 cm and 720 directions would be
17 GB; its likelihood field, 75 MB.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.raycast import cast_rays
from core.schema import ConfigError
from localizers.base import LandmarkMap

Array = NDArray[np.float64]
_log = logging.getLogger(__name__)

CACHE_ENV = "CROWDLOC_CACHE"
_TABLE_FORMAT = b"crowdloc-range-table-v1"


#: the default bound of one map table's memory, MB: a 7 m x 7 m room's ray-cast table at 5 cm and 720
#: directions is 56 MB, a campus's likelihood field 75 MB; the campus's ray-cast table (17 GB) is refused
MAX_TABLE_MB = 1024.0


#: bytes an entry of the beam model's ray-cast table takes (float32 ranges)
RANGE_TABLE_ENTRY_BYTES = 4


def table_megabytes(shape: tuple[int, ...], bytes_per_entry: float) -> float:
    """The memory of a table of ``shape`` at ``bytes_per_entry``, in MB (10**6 bytes)."""
    return math.prod(shape) * bytes_per_entry / 1e6


def check_table_size(what: str, shape: tuple[int, ...], bytes_per_entry: float, max_mb: float, advice: str) -> float:
    """The memory of a table of ``shape`` at ``bytes_per_entry`` in MB (:func:`table_megabytes`),
    estimated before it is allocated.

    Raises:
        ConfigError: when it exceeds ``max_mb``, naming ``what``, its shape, the estimate, the
            bound and ``advice`` (what to change).
    """
    megabytes = table_megabytes(shape, bytes_per_entry)
    if not megabytes <= max_mb:
        raise ConfigError(
            f"{what} of {' x '.join(f'{n:,}' for n in shape)} entries would need about {megabytes:,.0f} MB, above the bound "
            f"of {max_mb:,.0f} MB (memory, per process): {advice}"
        )
    return megabytes


def range_table_shape(bounds_m: tuple[float, float, float, float], resolution_m: float, directions: int) -> tuple[int, int, int]:
    """``(nx, ny, D)`` of the ray-cast table of a map with these bounds (``ceil(extent / resolution)`` cells a side)."""
    xmin, ymin, xmax, ymax = bounds_m
    nx = max(1, math.ceil((xmax - xmin) / resolution_m - 1e-9))
    ny = max(1, math.ceil((ymax - ymin) / resolution_m - 1e-9))
    return nx, ny, int(directions)


def check_range_table_size(
    bounds_m: tuple[float, float, float, float], resolution_m: float, directions: int, max_mb: float
) -> tuple[int, int, int]:
    """The ray-cast table's shape (:func:`range_table_shape`), or a :class:`ConfigError` when it
    would take more than ``max_mb`` (4 bytes an entry), saying what to change."""
    shape = range_table_shape(bounds_m, resolution_m, directions)
    check_table_size(
        "the beam model's ray-cast table (cells x cells x directions)",
        shape,
        RANGE_TABLE_ENTRY_BYTES,
        max_mb,
        "use the likelihood field (model: likelihood_field), a coarser table_resolution_m, fewer table_directions or a "
        "larger max_table_mb",
    )
    return shape


def cache_dir() -> Path:
    """Where precomputed tables live: ``$CROWDLOC_CACHE``, default ``~/.cache/crowdloc``."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "crowdloc")


def write_atomically(path: Path, write: Callable[[Path], object]) -> Path:
    """Write a file by ``write(tmp)`` to a temporary file beside ``path`` (same folder, same suffix),
    then rename it over ``path`` (``os.replace``, atomic): a killed or concurrent writer never
    leaves a truncated ``path``, and readers see the old file or the new one. The folder is made
    if needed; the temporary file is removed if ``write`` fails. Returns ``path``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.{time.monotonic_ns()}.tmp{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


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
    landmarks: LandmarkMap,
    *,
    resolution_m: float,
    directions: int,
    max_range_m: float,
    cache: Path | None = None,
    max_mb: float = MAX_TABLE_MB,
) -> RangeTable:
    """The ray-cast table of a map's walls, loaded from the disk cache when present.

    The grid covers the map bounds (``ceil(extent / resolution)`` cells a side). The table is
    stored as ``<cache>/range_table_<sha256>.npy``, written atomically, and loaded
    memory-mapped (read-only); a cache that cannot be read or written is logged and skipped. A map
    with ``disk_cache`` False (a seeded layout's) has its table built in memory, never written.

    Args:
        landmarks: the map (its ``walls_m`` and ``bounds_m``).
        resolution_m: cell size in metres.
        directions: world directions per cell, evenly spaced from 0.
        max_range_m: the sensor's maximum range.
        cache: cache directory (default: :func:`cache_dir`).
        max_mb: the most memory the table may take (4 bytes an entry), checked first.

    Raises:
        ConfigError: a table above ``max_mb`` (:func:`check_table_size`), before anything is allocated.
    """
    xmin, ymin, xmax, ymax = landmarks.bounds_m
    nx, ny, _ = shape = check_range_table_size(landmarks.bounds_m, resolution_m, directions, max_mb)
    key = range_table_key(landmarks.walls_m, landmarks.bounds_m, resolution_m, directions, max_range_m)
    path = (cache or cache_dir()) / f"range_table_{key}.npy" if landmarks.disk_cache else None
    meta = ((xmin, ymin), float(resolution_m), float(max_range_m), key)
    if path is not None and path.is_file():
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
    if path is not None:
        try:
            write_atomically(path, lambda tmp: np.save(tmp, ranges))
        except OSError as exc:
            _log.warning("could not cache the range table in %s: %s", path.parent, exc)
    ranges.setflags(write=False)
    return RangeTable(ranges, *meta, loaded=False)


#: cells per side of the blocks of :func:`wall_distance_field` (1.2 m at 5 cm; measured on a
#: campus-like map, 16 and 32 cells cost 10-25 % more)
DISTANCE_BLOCK_CELLS = 24


@numba.njit(cache=True, inline="always")
def _segment_distance(px: float, py: float, x1: float, y1: float, ex: float, ey: float, length2: float) -> float:
    """Distance from ``(px, py)`` to the segment ``(x1, y1) + t (ex, ey)``, ``t`` in ``[0, 1]``:
    the nearest point by the clipped projection, a zero-length segment's point itself."""
    t = 0.0
    if length2 != 0.0:
        t = min(max(((px - x1) * ex + (py - y1) * ey) / length2, 0.0), 1.0)
    return math.hypot(px - (x1 + t * ex), py - (y1 + t * ey))


@numba.njit(cache=True)
def _fill_distance_field(walls: Array, x0: float, y0: float, res: float, nx: int, ny: int, block: int, slack: float) -> Array:
    """:func:`wall_distance_field` by blocks of ``block x block`` cells (see there)."""
    out = np.full((nx, ny), np.inf)
    count = walls.shape[0]
    if count == 0:
        return out
    x1 = walls[:, 0].copy()
    y1 = walls[:, 1].copy()
    ex = walls[:, 2] - walls[:, 0]
    ey = walls[:, 3] - walls[:, 1]
    length2 = ex * ex + ey * ey
    from_centre = np.empty(count)
    near = np.empty(count, dtype=np.int64)
    for i0 in range(0, nx, block):
        i1 = min(nx, i0 + block) - 1
        xa = x0 + (i0 + 0.5) * res
        xb = x0 + (i1 + 0.5) * res
        for j0 in range(0, ny, block):
            j1 = min(ny, j0 + block) - 1
            ya = y0 + (j0 + 0.5) * res
            yb = y0 + (j1 + 0.5) * res
            # every cell centre of the block lies within r of its middle c: a wall at d from c is
            # between d - r and d + r from each of them, so only walls with d <= min d + 2 r can
            # be the nearest to any of them (slack: rounding)
            cx = 0.5 * (xa + xb)
            cy = 0.5 * (ya + yb)
            r = 0.5 * math.hypot(xb - xa, yb - ya)
            nearest = np.inf
            for k in range(count):
                d = _segment_distance(cx, cy, x1[k], y1[k], ex[k], ey[k], length2[k])
                from_centre[k] = d
                nearest = min(nearest, d)
            limit = nearest + 2.0 * r + slack
            m = 0
            for k in range(count):
                if from_centre[k] <= limit:
                    near[m] = k
                    m += 1
            for i in range(i0, i1 + 1):
                px = x0 + (i + 0.5) * res
                for j in range(j0, j1 + 1):
                    py = y0 + (j + 0.5) * res
                    best = np.inf
                    for q in range(m):
                        k = near[q]
                        best = min(best, _segment_distance(px, py, x1[k], y1[k], ex[k], ey[k], length2[k]))
                    out[i, j] = best
    return out


def wall_distance_field(
    walls_m: ArrayLike,
    origin_xy_m: tuple[float, float],
    resolution_m: float,
    shape: tuple[int, int],
    max_mb: float = MAX_TABLE_MB,
) -> Array:
    """``(nx, ny)`` distance from each cell centre to the nearest wall segment (inf without walls).

    Cell ``(i, j)``'s centre is ``origin + (i + 1/2, j + 1/2) resolution``; a zero-length
    segment is its point. Exact: each distance is computed by the clipped projection
    ``t = clip(((p - a) . e) / |e|^2, 0, 1)``, ``hypot(p - (a + t e))``, and the minimum taken
    over every wall that can be the nearest. Only the walls within a block's diagonal of the
    nearest one to the middle of a block of :data:`DISTANCE_BLOCK_CELLS` x
    :data:`DISTANCE_BLOCK_CELLS` cells are measured from its cells, so the cost is about
    ``cells x (nearby walls) + blocks x walls`` instead of ``cells x walls``: a 150 m x 100 m
    map at 5 cm (6 M cells) with 1,000 walls takes about 0.4 s on one core (measured; the
    full-grid loop over walls it replaced, about 2 min), and the result, 8 bytes a cell (48 MB
    there), is all the memory it needs besides a few arrays of one entry per wall. Serial, and
    compiled once (numba's disk cache).

    Raises:
        ValueError: for a wall coordinate, origin or resolution that is not finite, a
            resolution <= 0 or a negative shape; a :class:`ConfigError` (a ``ValueError``) for
            a field above ``max_mb`` (8 bytes a cell), before it is allocated.
    """
    walls = np.ascontiguousarray(np.asarray(walls_m, dtype=np.float64).reshape(-1, 4))
    nx, ny = (int(n) for n in shape)
    x0, y0 = (float(v) for v in origin_xy_m)
    res = float(resolution_m)
    if not (np.isfinite(walls).all() and math.isfinite(x0) and math.isfinite(y0) and math.isfinite(res) and res > 0.0):
        raise ValueError(
            f"wall_distance_field needs finite walls, origin and a resolution > 0, got origin {origin_xy_m!r}, "
            f"resolution {resolution_m!r} and {int((~np.isfinite(walls)).any(axis=1).sum())} walls with a non-finite coordinate"
        )
    if nx < 0 or ny < 0:
        raise ValueError(f"wall_distance_field: shape must be two counts >= 0, got {shape!r}")
    check_table_size("the wall-distance field (cells x cells)", (nx, ny), 8, max_mb, "use a coarser resolution")
    # rounding of the distances compared against the block bound: ~1e-16 of the coordinates' size, taken generously
    size = max(abs(x0), abs(y0), abs(x0 + nx * res), abs(y0 + ny * res), float(np.abs(walls).max(initial=0.0)))
    slack = 1e-9 * (1.0 + size)
    return _fill_distance_field(walls, x0, y0, res, nx, ny, DISTANCE_BLOCK_CELLS, slack)
