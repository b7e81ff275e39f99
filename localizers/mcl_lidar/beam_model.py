"""LIDAR measurement models of ``mcl_lidar``: the beam range-finder model (Probabilistic
Robotics sec. 6.3, Table 6.1) and the likelihood field (Table 6.3).

The pure functions (:func:`p_hit`, ..., :func:`beam_likelihood`) are the model's
definition; :class:`BeamModel` and :class:`LikelihoodFieldModel` evaluate it for many
particles at once with numba kernels, against a ray-cast table
(:mod:`localizers.range_table`) or a wall-distance field. Lookups take the cell containing
the particle and the direction nearest to the beam's world direction, so the expected
range carries an error of up to half a cell diagonal and half a direction step times the
range. Log likelihoods are summed over beams (products of 16 beams at a time, then one log).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import LandmarkMap
from localizers.mcl_lidar.params import LidarMCLParams
from localizers.range_table import RangeTable, check_table_size, wall_distance_field

Array = NDArray[np.float64]

_P_FLOOR = 1e-12  # per-beam likelihood floor: a log never sees 0 (e.g. with z_rand = 0)
_CHUNK = 16  # beams multiplied before one log (16 * log10(1e-12) stays far above float64's range)
_GAUSS_U_MAX = 32.0  # the tabulated Gaussian exp(-u), u = d^2 / (2 sigma^2), is 0 beyond (e^-32 ~ 1e-14)
_GAUSS_SIZE = 8192  # entries over [0, _GAUSS_U_MAX]: nearest entry, relative error <= 0.2 %
_FIELD_MARGIN_M = 1.0  # the likelihood field extends this far beyond the map bounds
_FIELD_BYTES_PER_CELL = 12  # the distance (float64) and the log field of one maximum range (float32)


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


def _blocks(parallel: bool) -> int:
    """The particle blocks of a kernel: one per thread of numba's pool, or one for the serial kernel.
    Only a parallel kernel asks numba for its thread count: asking starts the pool (OpenMP, where TBB
    is not installed), which a serial filter has no use for."""
    return numba.get_num_threads() if parallel else 1


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
        kernel(_blocks(parallel), particles, t.ranges_m, self._grid, beam_dir, beams, self._norms, self._gauss, consts, out)


class LikelihoodFieldModel:
    """Likelihood-field log-likelihoods (Table 6.3): ``sum_b log(z_hit N(d_b; 0, sigma^2) + z_rand / z_max)``.

    ``d_b`` is the distance from the end point of beam ``b`` to the nearest wall, read from a
    grid over the map bounds plus 1 m at ``table_resolution_m``; end points off the grid
    score ``log(z_rand / z_max)``. Max-range beams are skipped (Table 6.3, line 3).

    Raises:
        ConfigError: a grid above ``max_table_mb`` (12 bytes a cell), before it is built.
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
        check_table_size(
            "the likelihood field (cells x cells)",
            shape,
            _FIELD_BYTES_PER_CELL,
            params.max_table_mb,
            f"a coarser table_resolution_m than {res!r} m (the campus's LIDAR reference uses 0.1 m) or a larger max_table_mb",
        )
        self.distance_m = wall_distance_field(landmarks.walls_m, self.origin_xy_m, res, shape, max_mb=params.max_table_mb)
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
        kernel(_blocks(parallel), particles, self.log_field(max_range_m), grid, ends, outside, out)
