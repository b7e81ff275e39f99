"""Pure metric functions for localization runs (numpy only, no env, no localizer).

Conventions: estimates are ``(T, 3)`` poses with NaN rows where the localizer claimed no
pose; ``valid`` is the ``(T,)`` mask of the rows it did. Errors are NaN where invalid, so
statistics over "valid steps" are the ``nan``-aware ones. Statistics "from the first fix
on" follow the candidate-set paper: steps ``t >= t0`` where ``t0`` is the first step at
which the proposed method (5) had a pose; the same ``t0`` is used for every method.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import polyline_distance

Array = NDArray[np.float64]


def position_errors(estimates: ArrayLike, truth: ArrayLike) -> Array:
    """``(T,)`` Euclidean position errors (input units), NaN where the estimate is NaN."""
    e = np.asarray(estimates, dtype=np.float64)
    g = np.asarray(truth, dtype=np.float64)
    return np.hypot(e[:, 0] - g[:, 0], e[:, 1] - g[:, 1])


def path_distances(estimates: ArrayLike, path_xy: ArrayLike, *, closed: bool) -> Array:
    """``(T,)`` distance from each estimated position to a drawn path (input units), NaN where the
    estimate is NaN: the error the candidate-set paper reported for Exp 1, whose ground truth was
    the line the robot was pushed along (:func:`core.geometry.polyline_distance`). Unlike
    :func:`position_errors` it is blind to an error along the path."""
    return polyline_distance(np.asarray(estimates, dtype=np.float64)[:, :2], path_xy, closed=closed)


def heading_errors(estimates: ArrayLike, truth: ArrayLike) -> Array:
    """``(T,)`` absolute heading errors in radians, wrapped to ``[0, pi]``, NaN where invalid."""
    e = np.asarray(estimates, dtype=np.float64)
    g = np.asarray(truth, dtype=np.float64)
    d = np.mod(e[:, 2] - g[:, 2] + np.pi, 2.0 * np.pi) - np.pi
    return np.abs(d)


def first_fix(valid: ArrayLike) -> int | None:
    """Index of the first valid step, or ``None`` if the localizer never had a pose."""
    idx = np.flatnonzero(np.asarray(valid, dtype=bool))
    return int(idx[0]) if idx.size else None


def distinct_seen(visible: ArrayLike, count: int) -> int | None:
    """First step by which ``count`` distinct landmarks have been in view, or ``None``.

    ``visible`` is the ``(T, L)`` mask of the landmarks in sight at each step; a landmark
    counts from the first step it is in view, whether or not it still is.
    """
    if count < 1:
        raise ValueError(f"distinct_seen: count must be >= 1, got {count}")
    seen = np.logical_or.accumulate(np.asarray(visible, dtype=bool), axis=0).sum(axis=1)
    idx = np.flatnonzero(seen >= count)
    return int(idx[0]) if idx.size else None


def travelled(truth: ArrayLike) -> Array:
    """``(T,)`` distance travelled along the true path up to each step (0 at step 0)."""
    g = np.asarray(truth, dtype=np.float64)
    steps = np.hypot(np.diff(g[:, 0]), np.diff(g[:, 1]))
    return np.concatenate([[0.0], np.cumsum(steps)])


def availability(valid: ArrayLike, start: int = 0) -> float:
    """Share of steps ``t >= start`` with a valid estimate (NaN if there are none)."""
    v = np.asarray(valid, dtype=bool)[start:]
    return float(v.mean()) if v.size else float("nan")


def mean_sd(errors: ArrayLike, start: int | None = 0) -> tuple[float, float]:
    """Mean and standard deviation of the finite ``errors[start:]`` (NaN, NaN if none or ``start`` is None)."""
    if start is None:
        return float("nan"), float("nan")
    e = np.asarray(errors, dtype=np.float64)[start:]
    e = e[np.isfinite(e)]
    if e.size == 0:
        return float("nan"), float("nan")
    return float(e.mean()), float(e.std())


def failure_rate(errors: ArrayLike, start: int | None = 0, threshold: float = 1.0) -> float:
    """Share of finite ``errors[start:]`` at or above ``threshold`` (NaN if none)."""
    if start is None:
        return float("nan")
    e = np.asarray(errors, dtype=np.float64)[start:]
    e = e[np.isfinite(e)]
    return float(np.mean(e >= threshold)) if e.size else float("nan")


def failure_count(errors: ArrayLike, threshold: float = 1.0) -> int:
    """Number of finite ``errors`` at or above ``threshold`` (the far-point paper's failures: >= 1 m).

    NaN entries (no estimate) are not counted; count them separately where they can occur.
    """
    e = np.asarray(errors, dtype=np.float64)
    return int(np.count_nonzero(np.isfinite(e) & (e >= threshold)))


def beam_breakdown(
    ranges_m: ArrayLike, expected_m: ArrayLike, max_range_m: float, tol_m: float = 0.1
) -> tuple[int, int, int, int]:
    """Classify a scan's beams against the empty room's ranges ``expected_m``.

    Returns:
        Counts of beams that match the room (``|z - z*| < tol_m``), fall short of it (a
        person or another obstacle in front of the wall), reach past it (beyond ``tol_m``),
        and read the maximum range (nothing hit, or an empty far-point bin).
    """
    z = np.asarray(ranges_m, dtype=np.float64)
    zs = np.asarray(expected_m, dtype=np.float64)
    empty = z >= max_range_m
    match = ~empty & (np.abs(z - zs) < tol_m)
    short = ~empty & (z <= zs - tol_m)
    return int(match.sum()), int(short.sum()), int((~empty & ~match & ~short).sum()), int(empty.sum())


def rms(values: ArrayLike, start: int | None = 0, mask: ArrayLike | None = None) -> float:
    """Root mean square of the finite ``values[start:]`` (optionally only where ``mask``)."""
    if start is None:
        return float("nan")
    v = np.asarray(values, dtype=np.float64)
    keep = np.isfinite(v)
    if mask is not None:
        keep &= np.asarray(mask, dtype=bool)
    keep[:start] = False
    return float(np.sqrt(np.mean(v[keep] ** 2))) if keep.any() else float("nan")


def error_bound_ratio(errors: ArrayLike, bound_rmse: ArrayLike, start: int | None = 0) -> float:
    """RMS error over RMS bound on the same steps (valid steps from ``start``).

    The posterior Cramer-Rao bound limits the mean squared error, so the ratio of root mean
    squares is the honest comparison; a value near 1 means the method extracts about all the
    information in the data, below 1 is impossible for an unbiased estimator in expectation.
    """
    e = np.asarray(errors, dtype=np.float64)
    valid = np.isfinite(e)
    num = rms(e, start, valid)
    den = rms(bound_rmse, start, valid)
    return num / den if np.isfinite(num) and np.isfinite(den) and den > 0 else float("nan")


def time_to_recover(time_s: ArrayLike, errors: ArrayLike, event_time_s: float, threshold: float, hold_s: float = 1.0) -> float:
    """Seconds from an event until the error is below ``threshold`` for ``hold_s`` in a row.

    Invalid steps (NaN errors) count as not recovered. Returns ``inf`` if that never happens.
    """
    t = np.asarray(time_s, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    ok = np.isfinite(e) & (e < threshold)
    run_start = None
    for i in np.flatnonzero(t >= event_time_s):
        if ok[i]:
            if run_start is None:
                run_start = i
            if t[i] - t[run_start] >= hold_s - 1e-9:
                return float(t[run_start] - event_time_s)
        else:
            run_start = None
    return float("inf")


def speeds(truth: ArrayLike, dt_s: float) -> Array:
    """``(T - 1,)`` speeds along the true path."""
    g = np.asarray(truth, dtype=np.float64)
    return np.hypot(np.diff(g[:, 0]), np.diff(g[:, 1])) / dt_s


@dataclass(frozen=True)
class Spread:
    """A statistic over seeds: mean, standard deviation and how many seeds had a value."""

    mean: float
    sd: float
    n: int


def over_seeds(values: Sequence[float] | ArrayLike) -> Spread:
    """Mean and sample standard deviation over the finite per-seed values."""
    v = np.asarray(values, dtype=np.float64).reshape(-1)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return Spread(float("nan"), float("nan"), 0)
    return Spread(float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0, int(v.size))


# --------------------------------------------------------------------------- consistency (NEES)
def chi2_cdf(x: float, dof: int) -> float:
    """The chi-square CDF at ``x`` for ``dof`` in 1..3, in closed form (no scipy at run time).

    ``dof = 1``: ``erf(sqrt(x / 2))``; ``dof = 2``: ``1 - exp(-x / 2)``; ``dof = 3``:
    ``erf(sqrt(x / 2)) - sqrt(2 x / pi) exp(-x / 2)`` (the regularized lower incomplete gamma
    function ``P(dof / 2, x / 2)`` at half-integer and integer orders).
    """
    if dof not in (1, 2, 3):
        raise ValueError(f"chi2_cdf: dof must be 1, 2 or 3 (a pose has at most 3), got {dof}")
    if not x > 0.0:
        return 0.0
    if dof == 2:
        return -math.expm1(-0.5 * x)
    value = math.erf(math.sqrt(0.5 * x))
    return value - math.sqrt(2.0 * x / math.pi) * math.exp(-0.5 * x) if dof == 3 else value


@functools.cache
def chi2_quantile(p: float, dof: int) -> float:
    """The ``p`` quantile of the chi-square distribution with ``dof`` in 1..3 (bisection on :func:`chi2_cdf`).

    ``chi2_quantile(0.95, 3)`` = 7.8147, ``chi2_quantile(0.95, 2)`` = 5.9915 (the 95 % regions of a
    pose and of a position); exact to about 1e-12, checked against scipy in the tests.
    """
    if not 0.0 < p < 1.0:
        raise ValueError(f"chi2_quantile: p must be in (0, 1), got {p}")
    lo, hi = 0.0, 1.0
    while chi2_cdf(hi, dof) < p:  # raises for a bad dof
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if chi2_cdf(mid, dof) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-13 * hi:
            break
    return 0.5 * (lo + hi)


def pose_nees(estimates: ArrayLike, truth: ArrayLike, covariances: ArrayLike, dof: int = 3) -> Array:
    """``(T,)`` normalized estimation error squared ``e^T P^-1 e`` of each step's error ``e``.

    Args:
        estimates, truth: ``(T, 3)`` poses ``(x, y, theta)``; NaN estimate rows give NaN.
        covariances: ``(T, 3, 3)`` the reported covariances of ``(x, y, theta)``.
        dof: 3 for the pose (the heading error wrapped to ``[-pi, pi)``), 2 for the position
            only (the upper-left ``2 x 2`` block).

    Returns:
        The NEES per step; NaN where the estimate or the truth is not finite or the covariance
        (its block) is not usable: not finite, or with a negative eigenvalue (no covariance
        at all). A singular one (smallest eigenvalue within ``1e-12`` times the largest of
        zero: a particle set collapsed onto one pose, a zero matrix) claims certainty along
        some direction: its NEES is ``inf`` unless the error is exactly zero (then 0), so such
        steps count as outside every region rather than being left out. A consistent
        estimator's NEES is chi-square with ``dof`` degrees of freedom: mean ``dof``, inside
        :func:`chi2_quantile` (0.95) on 95 % of steps.
    """
    if dof not in (2, 3):
        raise ValueError(f"pose_nees: dof must be 3 (x, y, theta) or 2 (x, y), got {dof}")
    e = np.asarray(estimates, dtype=np.float64).reshape(-1, 3)
    g = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    cov = np.asarray(covariances, dtype=np.float64)
    if cov.shape != (e.shape[0], 3, 3) or g.shape != e.shape:
        raise ValueError(
            f"pose_nees: need (T, 3) estimates and truth and (T, 3, 3) covariances, got {e.shape}, {g.shape}, {cov.shape}"
        )
    err = np.column_stack([e[:, 0] - g[:, 0], e[:, 1] - g[:, 1], np.mod(e[:, 2] - g[:, 2] + np.pi, 2.0 * np.pi) - np.pi])[:, :dof]
    p = cov[:, :dof, :dof]
    p = 0.5 * (p + np.swapaxes(p, 1, 2))
    out = np.full(e.shape[0], np.nan)
    ok = np.isfinite(err).all(axis=1) & np.isfinite(p).all(axis=(1, 2))
    if ok.any():
        eig = np.linalg.eigvalsh(p[ok])
        tol = 1e-12 * np.maximum(eig[:, -1], 0.0)
        good = eig[:, 0] > tol
        idx = np.flatnonzero(ok)[good]
        if idx.size:
            out[idx] = _quadratic_over(p[idx], err[idx])
        singular = np.flatnonzero(ok)[~good & (eig[:, 0] >= -tol)]
        out[singular] = np.where(np.any(err[singular] != 0.0, axis=1), np.inf, 0.0)
    return out


def _quadratic_over(p: Array, x: Array) -> Array:
    """``(n,)`` ``x^T p^-1 x`` for symmetric positive definite ``p`` ``(n, k, k)``, ``k`` 2 or 3, by the
    adjugate in elementwise arithmetic: the same bits on every processor (LAPACK's solve picks
    processor-specific kernels, whose rounding shows in the NEES of a nearly collapsed
    particle set, condition number 1e10, at 1e-5 relative)."""
    if p.shape[1] == 2:
        a, b, d = p[:, 0, 0], p[:, 0, 1], p[:, 1, 1]
        x0, x1 = x[:, 0], x[:, 1]
        return (d * x0 * x0 - 2.0 * b * x0 * x1 + a * x1 * x1) / (a * d - b * b)
    a, b, c = p[:, 0, 0], p[:, 0, 1], p[:, 0, 2]
    d, e, f = p[:, 1, 1], p[:, 1, 2], p[:, 2, 2]
    adj00, adj01, adj02 = d * f - e * e, c * e - b * f, b * e - c * d
    adj11, adj12, adj22 = a * f - c * c, b * c - a * e, a * d - b * b
    det = a * adj00 + b * adj01 + c * adj02
    x0, x1, x2 = x[:, 0], x[:, 1], x[:, 2]
    quad = adj00 * x0 * x0 + adj11 * x1 * x1 + adj22 * x2 * x2 + 2.0 * (adj01 * x0 * x1 + adj02 * x0 * x2 + adj12 * x1 * x2)
    return quad / det


@dataclass(frozen=True)
class Consistency:
    """How a reported covariance matches the errors, over the steps that had one.

    Attributes:
        nees_mean, nees_median: of the NEES (``dof`` for a consistent estimator, and about
            ``dof - 2/3``); NaN without a usable step. The mean is ``inf`` as soon as one step
            is ``singular``: reports show the median, the share inside and ``singular`` (the
            mean stays here for the reproductions' ``results.json``, whose quick runs pin it).
        inside_95: share of those steps inside the reported 95 % region (NEES at most the
            chi-square 0.95 quantile; about 0.95 for a consistent estimator).
        steps: the steps with a usable covariance (a singular one included: its NEES is
            ``inf``, outside the region).
        excluded: the steps asked for whose NEES is NaN (covariance missing, not finite or
            with a negative eigenvalue; or no estimate).
        singular: those of ``steps`` whose NEES is ``inf``: a singular covariance (e.g. a
            particle set collapsed onto one pose) claiming certainty along a direction in
            which the estimate is off.
    """

    nees_mean: float
    nees_median: float
    inside_95: float
    steps: int
    excluded: int
    singular: int

    @property
    def singular_share(self) -> float:
        """``singular`` over ``steps`` (NaN without a usable step)."""
        return self.singular / self.steps if self.steps else math.nan


def consistency(nees: ArrayLike, dof: int = 3, mask: ArrayLike | None = None) -> Consistency:
    """Summarize per-step :func:`pose_nees` values (NaN: no usable covariance) over ``mask`` (default: all)."""
    v = np.asarray(nees, dtype=np.float64).reshape(-1)
    if mask is not None:
        v = v[np.asarray(mask, dtype=bool).reshape(-1)]
    usable = v[~np.isnan(v)]  # inf (a singular covariance with an error) counts: outside the region
    if usable.size == 0:
        return Consistency(math.nan, math.nan, math.nan, 0, int(v.size), 0)
    inside = float(np.mean(usable <= chi2_quantile(0.95, dof)))
    singular = int(np.count_nonzero(np.isinf(usable)))
    return Consistency(
        float(usable.mean()), float(np.median(usable)), inside, int(usable.size), int(v.size - usable.size), singular
    )
