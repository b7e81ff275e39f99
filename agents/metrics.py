"""Pure metric functions for localization runs (numpy only, no env, no localizer).

Conventions: estimates are ``(T, 3)`` poses with NaN rows where the localizer claimed no
pose; ``valid`` is the ``(T,)`` mask of the rows it did. Errors are NaN where invalid, so
statistics over "valid steps" are the ``nan``-aware ones. Statistics "from the first fix
on" follow the candidate-set paper: steps ``t >= t0`` where ``t0`` is the first step at
which the proposed method (5) had a pose; the same ``t0`` is used for every method.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

Array = NDArray[np.float64]


def position_errors(estimates: ArrayLike, truth: ArrayLike) -> Array:
    """``(T,)`` Euclidean position errors (input units), NaN where the estimate is NaN."""
    e = np.asarray(estimates, dtype=np.float64)
    g = np.asarray(truth, dtype=np.float64)
    return np.hypot(e[:, 0] - g[:, 0], e[:, 1] - g[:, 1])


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
