"""Compiled (numba) kernels of the candidate-set localizer (:mod:`localizers.candidate_sets`).

They work on the candidate store, one ``(ROWS, capacity)`` float64 array whose column ``i``
holds candidate ``i``'s base pose ``X``, the cos/sin of its heading and its accumulated
Error, grouped by set in creation order (see the implementation notes of
:mod:`localizers.candidate_sets`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from core.motion import wrap_scalar
from localizers.resection import solve_triples

# Rows of the candidate store (see candidate_sets.CandidateSetLocalizer): base pose X, cos/sin of its heading, Error.
ROW_X, ROW_Y, ROW_TH, ROW_COS, ROW_SIN, ROW_ERR = range(6)
ROWS = 6

_PI32 = np.float32(np.pi)
_HALF_PI32 = np.float32(0.5 * np.pi)
_QUARTER_PI32 = np.float32(0.25 * np.pi)
_TWO_PI32 = np.float32(2.0 * np.pi)
_INV_TWO_PI32 = np.float32(1.0 / (2.0 * np.pi))
_TAN_PI_8_32 = np.float32(math.tan(math.pi / 8.0))
# Cephes' atanf polynomial on [-tan(pi/8), tan(pi/8)] (relative error ~2e-7).
_ATAN_C = tuple(np.float32(c) for c in (8.05374449538e-2, -1.38776856032e-1, 1.99777106478e-1, -3.33329491539e-1))
_ONE32 = np.float32(1.0)
_ZERO32 = np.float32(0.0)


@numba.njit(cache=True, inline="always")
def _se2(x: float, y: float, th: float, c: float, s: float, dx: float, dy: float, dth: float) -> tuple[float, float, float]:
    """``(x, y, th) (+) (dx, dy, dth)`` with ``c, s = cos th, sin th`` (:func:`geometry.compose` of one pose)."""
    return x + c * dx - s * dy, y + s * dx + c * dy, wrap_scalar(th + dth)


@numba.njit(cache=True)
def compose_pose(pose: NDArray[np.float64], dx: float, dy: float, dth: float) -> tuple[float, float, float]:
    """``pose (+) d`` for one ``(3,)`` pose."""
    return _se2(pose[0], pose[1], pose[2], math.cos(pose[2]), math.sin(pose[2]), dx, dy, dth)


@numba.njit(cache=True)
def accumulate(odo: NDArray[np.float64], dx: float, dy: float, dth: float) -> None:
    """``O <- O (+) d`` in place."""
    odo[0], odo[1], odo[2] = compose_pose(odo, dx, dy, dth)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _atan2_f32(y: np.float32, x: np.float32) -> np.float32:
    """float32 ``atan2`` (within ~3 ulp, like numpy's SIMD one), branch-free so that loops over it vectorize."""
    ax = abs(x)
    ay = abs(y)
    hi = max(ax, ay)
    lo = min(ax, ay)
    a = lo / hi if hi > _ZERO32 else _ZERO32  # in [0, 1]
    big = a > _TAN_PI_8_32
    t = (a - _ONE32) / (a + _ONE32) if big else a  # atan(a) = pi/4 + atan(t)
    z = t * t
    r = (((_ATAN_C[0] * z + _ATAN_C[1]) * z + _ATAN_C[2]) * z + _ATAN_C[3]) * z * t + t
    if big:
        r = r + _QUARTER_PI32
    if ay > ax:
        r = _HALF_PI32 - r
    if x < _ZERO32:
        r = _PI32 - r
    return np.float32(math.copysign(r, y))  # a no-op in numba (float32 in, float32 out); a float in Python


@numba.njit(cache=True, error_model="numpy")
def evaluate(
    store: NDArray[np.float64], m: int, ox: float, oy: float, ot: float,
    lx32: NDArray[np.float32], ly32: NDArray[np.float32], ids: NDArray[np.int64], bearings: NDArray[np.float64],
) -> None:  # fmt: skip
    """Add eq. (1) to the Error of the first ``m`` candidates (eq. (2)).

    The current pose of a candidate is ``X (+) O``. Residuals ``e_k`` (predicted minus
    measured bearing, wrapped) are computed in float32, landmark by landmark over all
    candidates (loops that vectorize); the terms are ``|e_k|`` and, per pair,
    ``|wrap(e_j - e_k)| = pi - |pi - |e_j - e_k||`` (valid for ``|e_j - e_k| <= 2 pi``).
    """
    n = ids.size
    px = np.empty(m, dtype=np.float32)
    py = np.empty(m, dtype=np.float32)
    pt = np.empty(m, dtype=np.float32)
    bx, by, bt, bc, bs, err = store[ROW_X], store[ROW_Y], store[ROW_TH], store[ROW_COS], store[ROW_SIN], store[ROW_ERR]
    for i in range(m):
        px[i] = np.float32(bx[i] + (ox * bc[i] - oy * bs[i]))
        py[i] = np.float32(by[i] + (oy * bc[i] + ox * bs[i]))
        pt[i] = np.float32(bt[i] + ot)
    e = np.empty((n, m), dtype=np.float32)
    for k in range(n):
        lxk = lx32[ids[k]]
        lyk = ly32[ids[k]]
        bk = np.float32(bearings[k])
        ek = e[k]
        for i in range(m):
            r = _atan2_f32(lyk - py[i], lxk - px[i]) - (pt[i] + bk)
            r = r - np.rint(r * _INV_TWO_PI32) * _TWO_PI32
            ek[i] = r
            err[i] += abs(r)
    for j in range(n):
        ej = e[j]
        for k in range(j + 1, n):
            ek = e[k]
            for i in range(m):
                err[i] += _PI32 - abs(_PI32 - abs(ej[i] - ek[i]))


@numba.njit(cache=True)
def forget(store: NDArray[np.float64], m: int, factor: float) -> None:
    """Multiply the Error of the first ``m`` candidates by ``factor`` (the forgetting option, ours)."""
    err = store[ROW_ERR]
    for i in range(m):
        err[i] *= factor


@numba.njit(cache=True)
def _best_of_set(err: NDArray[np.float64], lo: int, hi: int) -> int:
    """Index of the least Error in ``lo:hi`` (the first one on ties)."""
    best = lo
    for i in range(lo + 1, hi):
        if err[i] < err[best]:
            best = i
    return best


@numba.njit(cache=True)
def _current_pose(store: NDArray[np.float64], i: int, ox: float, oy: float, ot: float, out: NDArray[np.float64]) -> None:
    """``X_i (+) O`` into ``out[:3]``."""
    out[0], out[1], out[2] = _se2(
        store[ROW_X, i], store[ROW_Y, i], store[ROW_TH, i], store[ROW_COS, i], store[ROW_SIN, i], ox, oy, ot
    )


@numba.njit(cache=True)
def fuse(poses: NDArray[np.float64], median_threshold_m: float) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`localizers.candidate_sets.fuse_poses` on validated ``(K, 3)`` poses, K >= 1."""
    k = poses.shape[0]
    pose = np.empty(3)
    kept = np.ones(k, dtype=np.bool_)
    if k == 1:
        pose[0] = poses[0, 0]
        pose[1] = poses[0, 1]
        pose[2] = wrap_scalar(poses[0, 2])
        return pose, kept
    median = np.empty(k)
    others = np.empty(k - 1)
    for a in range(k):
        c = 0
        for b in range(k):
            if b != a:
                others[c] = math.hypot(poses[a, 0] - poses[b, 0], poses[a, 1] - poses[b, 1])
                c += 1
        others.sort()
        median[a] = 0.5 * (others[(k - 2) // 2] + others[(k - 1) // 2])  # of the K - 1 distances
    n_kept = 0
    for a in range(k):
        kept[a] = median[a] < median_threshold_m
        if kept[a]:
            n_kept += 1
    if n_kept == 0:
        kept[np.argmin(median)] = True
        n_kept = 1
    sx = sy = ss = sc = 0.0
    for a in range(k):
        if kept[a]:
            sx += poses[a, 0]
            sy += poses[a, 1]
            ss += math.sin(poses[a, 2])
            sc += math.cos(poses[a, 2])
    pose[0] = sx / n_kept
    pose[1] = sy / n_kept
    pose[2] = wrap_scalar(math.atan2(ss, sc))  # circular mean of the kept headings
    return pose, kept


@numba.njit(cache=True)
def _add_deviation(
    cov: NDArray[np.float64], dev: NDArray[np.float64], pose: NDArray[np.float64], centre: NDArray[np.float64]
) -> None:
    """Add the outer product of ``pose - centre`` (heading wrapped) to ``cov``; ``dev`` is scratch."""
    dev[0] = pose[0] - centre[0]
    dev[1] = pose[1] - centre[1]
    dev[2] = wrap_scalar(pose[2] - centre[2])
    for a in range(3):
        for b in range(3):
            cov[a, b] += dev[a] * dev[b]


@numba.njit(cache=True)
def fused_output(
    store: NDArray[np.float64], counts: NDArray[np.int64], n_sets: int, determined: NDArray[np.bool_],
    ox: float, oy: float, ot: float, median_threshold_m: float, floors: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:  # fmt: skip
    """Fuse the determined sets' poses now: ``(pose (3,), covariance (3, 3), whether any set is determined)``."""
    err = store[ROW_ERR]
    n_det = 0
    for s in range(n_sets):
        if determined[s]:
            n_det += 1
    if n_det == 0:
        return np.full(3, np.nan), np.full((3, 3), np.nan), False
    best = np.empty((n_det, 3))
    spans = np.empty((n_det, 2), dtype=np.int64)
    lo = 0
    d = 0
    for s in range(n_sets):
        hi = lo + counts[s]
        if determined[s]:
            _current_pose(store, _best_of_set(err, lo, hi), ox, oy, ot, best[d])
            spans[d, 0] = lo
            spans[d, 1] = hi
            d += 1
        lo = hi
    pose, kept = fuse(best, median_threshold_m)
    cov = np.zeros((3, 3))
    dev = np.empty(3)
    n_kept = 0
    for a in range(n_det):
        if kept[a]:
            n_kept += 1
    if n_kept >= 2:  # sample covariance of the kept poses
        for a in range(n_det):
            if kept[a]:
                _add_deviation(cov, dev, best[a], pose)
        samples = n_kept
    else:  # that of the candidates of the one kept set
        a = int(np.argmax(kept))
        p = np.empty(3)
        for i in range(spans[a, 0], spans[a, 1]):
            _current_pose(store, i, ox, oy, ot, p)
            _add_deviation(cov, dev, p, pose)
        samples = spans[a, 1] - spans[a, 0]
    if samples >= 2:
        for a in range(3):
            for b in range(3):
                cov[a, b] /= samples - 1
    else:
        cov[:, :] = 0.0
    for a in range(3):
        if cov[a, a] < floors[a]:  # (NaN stays NaN, like np.maximum)
            cov[a, a] = floors[a]
    return pose, cov, True


@numba.njit(cache=True)
def prune_abort_determine(
    store: NDArray[np.float64], m: int, counts: NDArray[np.int64], n_sets: int, determined: NDArray[np.bool_],
    prune_error: float, abort_error: float, determine_below: int,
    ox: float, oy: float, ot: float, median_threshold_m: float, floors: NDArray[np.float64],
    snapshot: NDArray[np.float64],
) -> tuple[int, int, int, int, bool]:  # fmt: skip
    """After an evaluation: delete candidates over the prune threshold and sets over the
    abort threshold (or that lost all their candidates), then determine the small sets.

    When the last determined sets are discarded, the fused output computed just before
    goes to ``snapshot`` (rows: pose, then the covariance) for coasting.

    Returns:
        ``(m, n_sets, sets discarded, sets newly determined, snapshot taken)``.
    """
    err = store[ROW_ERR]
    dead = np.zeros(n_sets, dtype=np.bool_)
    n_dead = 0
    any_pruned = False
    live_determined = False
    any_determined = False
    lo = 0
    for s in range(n_sets):
        hi = lo + counts[s]
        least = err[lo]
        for i in range(lo + 1, hi):
            v = err[i]
            if v < least or v != v:  # NaN-propagating minimum, like np.minimum
                least = v
        dead[s] = least > abort_error or least > prune_error
        if determined[s]:
            any_determined = True
            if not dead[s]:
                live_determined = True
        if dead[s]:
            n_dead += 1
            any_pruned = True
        else:
            for i in range(lo, hi):
                if not err[i] <= prune_error:
                    any_pruned = True
                    break
        lo = hi
    snapped = False
    if n_dead and any_determined and not live_determined:
        pose, cov, _ = fused_output(store, counts, n_sets, determined, ox, oy, ot, median_threshold_m, floors)
        snapshot[0] = pose
        snapshot[1:] = cov
        snapped = True
    if any_pruned:
        w = 0
        lo = 0
        live = 0
        for s in range(n_sets):
            hi = lo + counts[s]
            if not dead[s]:
                kept = 0
                for i in range(lo, hi):
                    if err[i] <= prune_error:
                        if w != i:
                            for r in range(ROWS):
                                store[r, w] = store[r, i]
                        w += 1
                        kept += 1
                counts[live] = kept  # >= 1: the least Error is within both thresholds
                determined[live] = determined[s]
                live += 1
            lo = hi
        m = w
        n_sets = live
    n_new = 0
    for s in range(n_sets):
        if not determined[s] and counts[s] < determine_below:
            determined[s] = True
            n_new += 1
    return m, n_sets, n_dead, n_new, snapped


@numba.njit(cache=True)
def append_candidates(store: NDArray[np.float64], m: int, poses: NDArray[np.float64], ox: float, oy: float, ot: float) -> None:
    """Store ``(k, 3)`` current poses P as candidates ``m:m + k`` with base ``X = P (+) O^-1`` and Error 0."""
    c = math.cos(ot)  # O^-1 = between(O, 0) (geometry.between)
    s = math.sin(ot)
    dx = -ox
    dy = -oy
    ix = c * dx + s * dy
    iy = -s * dx + c * dy
    it = wrap_scalar(0.0 - ot)
    for j in range(poses.shape[0]):
        i = m + j
        px, py, pt = poses[j, 0], poses[j, 1], poses[j, 2]
        x, y, th = _se2(px, py, pt, math.cos(pt), math.sin(pt), ix, iy, it)
        store[ROW_X, i] = x
        store[ROW_Y, i] = y
        store[ROW_TH, i] = th
        store[ROW_COS, i] = math.cos(th)
        store[ROW_SIN, i] = math.sin(th)
        store[ROW_ERR, i] = 0.0


@numba.njit(cache=True)
def inside(poses: NDArray[np.float64], xmin: float, ymin: float, xmax: float, ymax: float) -> NDArray[np.bool_]:
    """``(m,)`` finite poses within ``[xmin, xmax] x [ymin, ymax]`` (the bounds grown by the margin)."""
    out = np.empty(poses.shape[0], dtype=np.bool_)
    for i in range(poses.shape[0]):
        x, y, th = poses[i, 0], poses[i, 1], poses[i, 2]
        out[i] = (
            math.isfinite(x) and math.isfinite(y) and math.isfinite(th)
            and x >= xmin and x <= xmax and y >= ymin and y <= ymax
        )  # fmt: skip
    return out


@numba.njit(cache=True)
def triple_seeds(
    observed_xy: NDArray[np.float64], bearings: NDArray[np.float64], triples: NDArray[np.int64],
    min_conditioning: float, xmin: float, ymin: float, xmax: float, ymax: float,
) -> NDArray[np.float64]:  # fmt: skip
    """The ok Cassini solutions of every triple that lie inside the (grown) bounds, in triple order."""
    poses, ok, _, _ = solve_triples(observed_xy, bearings, triples, min_conditioning)
    keep = ok & inside(poses, xmin, ymin, xmax, ymax)
    return poses[keep]


@numba.njit(cache=True)
def spread_sums(store: NDArray[np.float64], weights: NDArray[np.float64], ox: float, oy: float) -> tuple[float, float]:
    """``(weighted position variance, R)`` of the live candidates under their overlay ``weights``
    (NaNs without any weight): what ``wrappers.hypothesis_spread`` computes from
    :meth:`localizers.candidate_sets.CandidateSetLocalizer.overlay`, without building the poses or any trig (the heading's
    resultant length ``R`` is the same for ``X`` and ``X (+) O``)."""
    sw = sx = sy = sxx = sc = ss = 0.0
    for i in range(weights.shape[0]):
        w = weights[i]
        c, s = store[ROW_COS, i], store[ROW_SIN, i]
        x = store[ROW_X, i] + c * ox - s * oy
        y = store[ROW_Y, i] + s * ox + c * oy
        sw += w
        sx += w * x
        sy += w * y
        sxx += w * (x * x + y * y)
        sc += w * c
        ss += w * s
    if not sw > 0.0:
        return math.nan, math.nan
    mx, my = sx / sw, sy / sw
    return max(sxx / sw - mx * mx - my * my, 0.0), math.hypot(sc, ss) / sw
