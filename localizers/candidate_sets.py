"""The candidate-set localizer of the two-landmark bearings paper (docs/papers.md section A, method (5)).

1. *Generation*: with exactly 2 landmark bearings seen, N poses on the inscribed-angle arc
   (:func:`localizers.resection.inscribed_arc_poses`), spread over the part of the arc
   inside the map bounds (ours); with >= 3, the ok Cassini solutions of all C(L, 3)
   triples (:func:`localizers.resection.resect_all_triples`) inside the bounds. Every
   error starts at 0.
2. *Propagation*: each candidate moves by the odometry increment in its own frame.
3. *Evaluation*: eq. (1)-(2), accumulated per candidate.
4. *Pruning / determination*: candidates with Error > ``prune_error_rad`` are deleted; a
   set with fewer than ``determine_below`` candidates is determined, its pose the candidate
   of least Error (re-chosen at every frame).
5. *Abort*: a set whose least Error exceeds ``abort_error_rad`` (or that lost all its
   candidates) is discarded; a replacement is generated the next time >= 2 landmarks are seen.
6. *Multiple sets*: the first determination of a set triggers a new independent set from
   the same frame's bearings, up to ``max_sets`` live sets and ``max_live_candidates``.
7. *Fusion*: :func:`fuse_poses` over the determined sets' poses.

Implementation notes (ours):

* All candidates of all sets live in one ``(6, capacity)`` store, grouped by set in
  creation order; each step runs a few compiled (numba) kernels over it, so a frame costs
  no per-candidate Python work. Propagation is lazy: with ``O(t) = d_1 (+) ... (+) d_t``
  the running product of all odometry increments (the SE(2) product of
  ``geometry.compose``), a candidate is stored as ``X = P (+) O(t_gen)^-1`` and its pose
  is ``X (+) O(t)``; by associativity of SE(2) this equals composing every increment in
  the candidate's own frame, and ``predict`` is O(1).
  ``cos``/``sin`` of each ``X``'s heading are stored once, so an update needs one
  ``arctan2`` per candidate and landmark and no other transcendental function.
* Evaluation runs in float32 (bearing precision ~1e-7 rad; ``arctan2`` is a branch-free
  polynomial accurate to ~3 ulp, so the loops vectorize); accumulated errors and poses
  stay float64.
* At most one set is generated per frame (sets generated from one frame are identical);
  owed generations wait for the next frame with >= 2 landmarks. A set discarded at a frame
  is replaced from a later frame, never from the bearings that made it fail.
* Once a pose has been determined, the estimate stays valid: if every determined set is
  discarded, the last fused pose is dead-reckoned with odometry until a set determines
  again, its standard deviations growing by ``coast_growth_per_m`` per metre travelled
  (and per radian turned for the heading).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import (
    BearingMeasurement,
    LandmarkMap,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    checked_bearings,
    checked_dt,
    checked_odometry,
    require_reset,
)
from localizers.geometry import between, circular_std, compose
from localizers.motion import wrap_scalar
from localizers.resection import inscribed_arc_poses, solve_triples, triple_indices
from localizers.schema import check


@dataclass(frozen=True)
class CandidateSetParams:
    """Parameters of the candidate-set method (defaults: ``configs/localizers/candidate_sets.yaml``).

    Errors are eq. (2) sums of absolute angle differences in radians, accumulated once per
    update, so they grow with the frame rate and the number of landmarks seen (n bearing
    terms plus C(n, 2) pair terms per frame). The paper set its thresholds by hand and does
    not report them; the defaults (ours) assume the paper's 30 fps, ~1 deg bearing noise and
    2-4 landmarks in view.

    Attributes:
        candidates_per_arc: N, candidates on a two-landmark arc (count; paper sec. 5 (5): 360).
        max_sets: K, most live candidate sets (count; paper sec. 3, exp. 3: 10).
        prune_error_rad: a candidate whose accumulated Error exceeds this is deleted
            (rad; paper sec. 2, value ours).
        abort_error_rad: a set whose least Error exceeds this is discarded
            (rad; paper sec. 3, value ours).
        determine_below: a set with fewer candidates than this is determined
            (count; paper sec. 2, value ours).
        fusion_median_m: a determined pose is kept by the fusion when its median distance
            to the other determined poses is below this (m; paper sec. 3 (3), value ours).
        max_live_candidates: compute budget: no new set is generated if the live candidates
            would exceed this (count; paper sec. 3, value ours = K x N).
        bounds_margin_m: generated candidates farther than this outside the map bounds are
            dropped (m; ours).
        min_conditioning: smallest Cassini conditioning accepted for triple seeds
            (dimensionless; ours, see ``localizers.resection``).
        position_floor_m: floor of the position standard deviation per axis (m; ours, about
            half the paper's 10 cm candidate spacing).
        heading_floor_rad: floor of the heading standard deviation (rad; ours, the paper's
            0.7 deg mean heading error in exp. 1).
        coast_growth_per_m: while no set is determined after a first fix, the position
            standard deviation grows by this many metres per metre travelled and the heading
            one by this many radians per radian turned (dimensionless; ours).
    """

    candidates_per_arc: int = 360
    max_sets: int = 10
    prune_error_rad: float = 6.0
    abort_error_rad: float = 4.0
    determine_below: int = 60
    fusion_median_m: float = 0.5
    max_live_candidates: int = 3600
    bounds_margin_m: float = 0.1
    min_conditioning: float = 0.1
    position_floor_m: float = 0.05
    heading_floor_rad: float = 0.0125
    coast_growth_per_m: float = 0.1

    def __post_init__(self) -> None:
        for name in ("candidates_per_arc", "max_sets", "determine_below", "max_live_candidates"):
            value = getattr(self, name)
            check(value >= 1, f"CandidateSetParams.{name} must be an integer >= 1, got {value!r}")
        for name in ("prune_error_rad", "abort_error_rad", "fusion_median_m", "min_conditioning"):
            value = getattr(self, name)
            check(math.isfinite(value) and value > 0.0, f"CandidateSetParams.{name} must be a number > 0, got {value!r}")
        for name in ("bounds_margin_m", "position_floor_m", "heading_floor_rad", "coast_growth_per_m"):
            value = getattr(self, name)
            check(math.isfinite(value) and value >= 0.0, f"CandidateSetParams.{name} must be a number >= 0, got {value!r}")


_ARC_OVERSAMPLING = 8
"""Arc points computed per kept candidate before clipping to the bounds (ours)."""

# Rows of the candidate store (see CandidateSetLocalizer): base pose X, cos/sin of its heading, Error.
_X, _Y, _TH, _COS, _SIN, _ERR = range(6)
_ROWS = 6

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


# ----------------------------------------------------------------------------- kernels


@numba.njit(cache=True, inline="always")
def _se2(x: float, y: float, th: float, c: float, s: float, dx: float, dy: float, dth: float) -> tuple[float, float, float]:
    """``(x, y, th) (+) (dx, dy, dth)`` with ``c, s = cos th, sin th`` (:func:`geometry.compose` of one pose)."""
    return x + c * dx - s * dy, y + s * dx + c * dy, wrap_scalar(th + dth)


@numba.njit(cache=True)
def _compose_pose(pose: NDArray[np.float64], dx: float, dy: float, dth: float) -> tuple[float, float, float]:
    """``pose (+) d`` for one ``(3,)`` pose."""
    return _se2(pose[0], pose[1], pose[2], math.cos(pose[2]), math.sin(pose[2]), dx, dy, dth)


@numba.njit(cache=True)
def _accumulate(odo: NDArray[np.float64], dx: float, dy: float, dth: float) -> None:
    """``O <- O (+) d`` in place."""
    odo[0], odo[1], odo[2] = _compose_pose(odo, dx, dy, dth)


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
def _evaluate(
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
    bx, by, bt, bc, bs, err = store[_X], store[_Y], store[_TH], store[_COS], store[_SIN], store[_ERR]
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
    out[0], out[1], out[2] = _se2(store[_X, i], store[_Y, i], store[_TH, i], store[_COS, i], store[_SIN, i], ox, oy, ot)


@numba.njit(cache=True)
def _fuse(poses: NDArray[np.float64], median_threshold_m: float) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """:func:`fuse_poses` on validated ``(K, 3)`` poses, K >= 1."""
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
def _fused_output(
    store: NDArray[np.float64], counts: NDArray[np.int64], n_sets: int, determined: NDArray[np.bool_],
    ox: float, oy: float, ot: float, median_threshold_m: float, floors: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], bool]:  # fmt: skip
    """Fuse the determined sets' poses now: ``(pose (3,), covariance (3, 3), whether any set is determined)``."""
    err = store[_ERR]
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
    pose, kept = _fuse(best, median_threshold_m)
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
def _prune_abort_determine(
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
    err = store[_ERR]
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
        pose, cov, _ = _fused_output(store, counts, n_sets, determined, ox, oy, ot, median_threshold_m, floors)
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
                            for r in range(_ROWS):
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
def _append(store: NDArray[np.float64], m: int, poses: NDArray[np.float64], ox: float, oy: float, ot: float) -> None:
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
        store[_X, i] = x
        store[_Y, i] = y
        store[_TH, i] = th
        store[_COS, i] = math.cos(th)
        store[_SIN, i] = math.sin(th)
        store[_ERR, i] = 0.0


@numba.njit(cache=True)
def _inside(poses: NDArray[np.float64], xmin: float, ymin: float, xmax: float, ymax: float) -> NDArray[np.bool_]:
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
def _triple_seeds(
    observed_xy: NDArray[np.float64], bearings: NDArray[np.float64], triples: NDArray[np.int64],
    min_conditioning: float, xmin: float, ymin: float, xmax: float, ymax: float,
) -> NDArray[np.float64]:  # fmt: skip
    """The ok Cassini solutions of every triple that lie inside the (grown) bounds, in triple order."""
    poses, ok, _, _ = solve_triples(observed_xy, bearings, triples, min_conditioning)
    keep = ok & _inside(poses, xmin, ymin, xmax, ymax)
    return poses[keep]


@numba.njit(cache=True)
def _spread_sums(store: NDArray[np.float64], weights: NDArray[np.float64], ox: float, oy: float) -> tuple[float, float]:
    """``(weighted position variance, R)`` of the live candidates under their overlay ``weights``
    (NaNs without any weight): what ``wrappers.hypothesis_spread`` computes from
    :meth:`CandidateSetLocalizer.overlay`, without building the poses or any trig (the heading's
    resultant length ``R`` is the same for ``X`` and ``X (+) O``)."""
    sw = sx = sy = sxx = sc = ss = 0.0
    for i in range(weights.shape[0]):
        w = weights[i]
        c, s = store[_COS, i], store[_SIN, i]
        x = store[_X, i] + c * ox - s * oy
        y = store[_Y, i] + s * ox + c * oy
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


# ----------------------------------------------------------------------------- public helpers


def generate_candidates(
    landmarks: LandmarkMap,
    ids: ArrayLike,
    bearings: ArrayLike,
    *,
    candidates_per_arc: int,
    min_conditioning: float,
    bounds_margin_m: float,
) -> NDArray[np.float64]:
    """An initial candidate set from one frame's bearings (paper sec. 2).

    Two landmarks: ``candidates_per_arc`` poses on the inscribed-angle arc, spread over the
    part of the arc inside the bounds (ours; the paper spreads them over the whole arc,
    which lies mostly inside the field). Three or more: the ok Cassini solutions of every
    triple; if none is ok or inside (ours), the arc of the pair whose subtended angle is
    closest to 90 deg (the smallest, best-conditioned arc).

    Args:
        landmarks: the map (positions and bounds).
        ids: ``(n,)`` observed landmark ids, n >= 2.
        bearings: ``(n,)`` their bearings.
        candidates_per_arc: N.
        min_conditioning: Cassini acceptance threshold.
        bounds_margin_m: tolerance outside ``landmarks.bounds_m``.

    Returns:
        ``(m, 3)`` candidate poses (m may be 0), all finite and inside the bounds + margin.
    """
    idx = np.asarray(ids, dtype=np.int64)
    b = np.asarray(bearings, dtype=np.float64)
    pos = landmarks.positions_xy_m
    if idx.ndim != 1 or idx.shape != b.shape:
        raise ValueError(f"generate_candidates: ids and bearings must be 1-D of equal length, got {idx.shape} and {b.shape}")
    if idx.size < 2:
        return np.zeros((0, 3))
    xmin, ymin, xmax, ymax = landmarks.bounds_m
    box = (xmin - bounds_margin_m, ymin - bounds_margin_m, xmax + bounds_margin_m, ymax + bounds_margin_m)
    if idx.size >= 3:
        poses = _triple_seeds(pos[idx], b, triple_indices(idx.size), float(min_conditioning), *box)  # (indexing checks the ids)
        if poses.shape[0]:
            return poses
    i, j = np.triu_indices(idx.size, 1)
    best = int(np.argmax(np.abs(np.sin(b[j] - b[i]))))
    k, m = int(i[best]), int(j[best])
    # N candidates over the part of the arc inside the bounds (ours): oversample the arc,
    # keep the feasible positions and take N of them evenly by index.
    fine = inscribed_arc_poses(pos[idx[k]], pos[idx[m]], b[k], b[m], _ARC_OVERSAMPLING * candidates_per_arc)
    fine = fine[_inside(fine, *box)]
    if fine.shape[0] <= candidates_per_arc:
        return fine
    pick = np.round(np.linspace(0.0, fine.shape[0] - 1, candidates_per_arc)).astype(np.intp)
    return fine[pick]


def fuse_poses(poses: ArrayLike, median_threshold_m: float) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Fuse the determined poses of several candidate sets (paper sec. 3, steps (1)-(4)).

    For each pose, the median of its Euclidean distances to the other K - 1 positions;
    the poses whose median is below ``median_threshold_m`` are averaged (circular mean for
    the heading). A single pose is returned as is. If no pose passes (ours), the one with
    the smallest median is used (ties: the first, i.e. the earliest-generated set).

    Args:
        poses: ``(K, 3)`` determined poses, K >= 1.
        median_threshold_m: the median-distance gate in metres.

    Returns:
        ``(3,)`` fused pose (heading in ``[-pi, pi)``) and ``(K,)`` mask of the kept poses.
    """
    p = np.asarray(poses, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise ValueError(f"fuse_poses: poses must have shape (K, 3) with K >= 1, got {p.shape}")
    return _fuse(np.ascontiguousarray(p), float(median_threshold_m))


class CandidateSetLocalizer:
    """Multiple candidate sets pruned by accumulated bearing errors, fused (paper method (5)).

    The estimate is invalid until a set first determines. Its covariance is the sample
    covariance of the fused (kept) poses when there are >= 2, else that of the candidates
    of the one determined set, each diagonal entry floored by ``position_floor_m^2`` /
    ``heading_floor_rad^2``. :meth:`overlay` draws every live candidate, weighted by
    ``1 - Error / prune_error_rad``.
    """

    name: ClassVar[str] = "candidate_sets"

    def __init__(self, landmarks: LandmarkMap, params: CandidateSetParams, *, dt_s: float) -> None:
        self._dt = checked_dt("CandidateSetLocalizer", dt_s)
        self._map = landmarks
        self._params = params
        self._lx32 = landmarks.positions_xy_m[:, 0].astype(np.float32)
        self._ly32 = landmarks.positions_xy_m[:, 1].astype(np.float32)
        self._floors = np.array([params.position_floor_m**2] * 2 + [params.heading_floor_rad**2])
        # Candidates, grouped by set in creation order: column i holds candidate i's base pose
        # X (rows _X, _Y, _TH), cos/sin of its heading and its accumulated Error (row _ERR).
        # Only the first ``_m`` columns are live; the store grows up to max_live_candidates.
        self._store = np.zeros((_ROWS, 0))
        # Per live set (the first ``_n_sets`` entries), in creation order.
        self._counts = np.zeros(params.max_sets, dtype=np.int64)
        self._determined = np.zeros(params.max_sets, dtype=np.bool_)
        self._snapshot = np.zeros((4, 3))  # fused output kept by the kernel for coasting
        self._started = False
        self._clear()

    # ----------------------------------------------------------------------------- state

    def _clear(self) -> None:
        self._odo = np.zeros(3)  # O(t): running product of the odometry increments
        self._path_m = 0.0  # distance travelled since reset
        self._turn_rad = 0.0  # |rotation| accumulated since reset
        self._m = 0
        self._n_sets = 0
        self._pending = 1  # generations owed now (the first set is owed from the start)
        self._pending_next = 0  # generations owed from the next frame on (after an abort)
        # Last fused output, kept for coasting: base pose X, covariance, path/turn at the time.
        self._coast: tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None = None
        self._cached: PoseEstimate | None = None

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Forget every set. The method is deterministic and finds the pose itself, so
        ``rng`` and ``prior`` are not used."""
        del rng, prior
        self._started = True
        self._clear()

    def _require_reset(self) -> None:
        require_reset("CandidateSetLocalizer", self._started)

    def _ensure_capacity(self, m: int) -> None:
        """Grow the candidate store to hold ``m`` candidates (m <= max_live_candidates)."""
        cap = self._store.shape[1]
        if m <= cap:
            return
        grown = np.zeros((_ROWS, min(max(m, 2 * cap), self._params.max_live_candidates)))
        grown[:, : self._m] = self._store[:, : self._m]
        self._store = grown

    # ----------------------------------------------------------------------------- steps

    def predict(self, odometry: OdometryDelta) -> None:
        """Propagate every candidate by the increment (lazily: one SE(2) product)."""
        self._require_reset()
        dx, dy, dth = checked_odometry(self.name, odometry).tolist()
        _accumulate(self._odo, dx, dy, dth)
        self._path_m += math.hypot(dx, dy)
        self._turn_rad += abs(dth)
        self._cached = None

    def update(self, measurement: BearingMeasurement) -> None:
        """Evaluate, prune, abort, determine and generate with one frame's bearings."""
        self._require_reset()
        meas = checked_bearings(self.name, measurement, self._map.count)
        self._cached = None
        self._pending += self._pending_next
        self._pending_next = 0
        ids, bearings = meas.landmark_ids, meas.bearings_rad
        n = ids.size
        if n == 0:
            return
        p = self._params
        if self._m:
            ox, oy, ot = self._odo.tolist()
            _evaluate(self._store, self._m, ox, oy, ot, self._lx32, self._ly32, ids, bearings)
            self._m, self._n_sets, n_dead, n_new, snapped = _prune_abort_determine(
                self._store, self._m, self._counts, self._n_sets, self._determined,
                p.prune_error_rad, p.abort_error_rad, p.determine_below,
                ox, oy, ot, p.fusion_median_m, self._floors, self._snapshot,
            )  # fmt: skip
            if snapped:  # the last determined pose, before it was discarded
                pose, cov = self._snapshot[0].copy(), self._snapshot[1:].copy()
                self._coast = (compose(pose, between(self._odo, np.zeros(3))), cov, self._path_m, self._turn_rad)
            self._pending_next += n_dead  # replaced "the next time" (sec. 3), not from this frame
            self._pending += n_new
        self._pending = min(self._pending, p.max_sets - self._n_sets)
        if self._pending > 0 and n >= 2 and self._m < p.max_live_candidates:
            self._generate(ids, bearings)

    def _generate(self, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> None:
        """Append one new set built from this frame's bearings, if the budget allows."""
        p = self._params
        poses = generate_candidates(
            self._map, ids, bearings,
            candidates_per_arc=p.candidates_per_arc, min_conditioning=p.min_conditioning,
            bounds_margin_m=p.bounds_margin_m,
        )  # fmt: skip
        m = poses.shape[0]
        if m == 0 or self._m + m > p.max_live_candidates:
            return
        self._ensure_capacity(self._m + m)
        ox, oy, ot = self._odo.tolist()
        _append(self._store, self._m, poses, ox, oy, ot)
        self._m += m
        self._counts[self._n_sets] = m
        self._determined[self._n_sets] = False
        self._n_sets += 1
        self._pending -= 1

    # ----------------------------------------------------------------------------- output

    def _candidate_poses(self) -> NDArray[np.float64]:
        """``(m, 3)`` current poses of the live candidates."""
        return compose(self._store[_X : _TH + 1, : self._m].T, self._odo)

    @property
    def estimate(self) -> PoseEstimate:
        """Fused pose of the determined sets; invalid before the first determination."""
        if self._cached is None:
            self._cached = self._compute_estimate()
        e = self._cached
        return PoseEstimate(e.x_m, e.y_m, e.theta_rad, e.covariance.copy(), e.valid)

    def _compute_estimate(self) -> PoseEstimate:
        ox, oy, ot = self._odo.tolist()
        pose, cov, determined = _fused_output(
            self._store, self._counts, self._n_sets, self._determined, ox, oy, ot, self._params.fusion_median_m, self._floors
        )
        if determined:
            x, y, th = pose.tolist()
            return PoseEstimate(x, y, th, cov, True)
        if self._coast is None:
            return PoseEstimate.invalid()
        base, cov, path0, turn0 = self._coast
        g = self._params.coast_growth_per_m
        pos_sd = g * (self._path_m - path0)
        head_sd = g * (self._turn_rad - turn0)
        cov = cov.copy()
        cov[0, 0] = (math.sqrt(cov[0, 0]) + pos_sd) ** 2
        cov[1, 1] = (math.sqrt(cov[1, 1]) + pos_sd) ** 2
        cov[2, 2] = (math.sqrt(cov[2, 2]) + head_sd) ** 2
        x, y, th = _compose_pose(base, *self._odo.tolist())
        return PoseEstimate(x, y, th, cov, True)

    def overlay(self) -> Overlay:
        """Live candidates; weight ``1 - Error / prune_error_rad`` (low Error = high weight)."""
        if self._m == 0:
            return Overlay(label="candidate sets: none")
        label = f"candidate sets: {self._n_sets} sets, {int(self._determined[: self._n_sets].sum())} determined"
        return Overlay(poses=self._candidate_poses(), weights=self._candidate_weights(), label=label)

    def _candidate_weights(self) -> NDArray[np.float64]:
        """``(m,)`` overlay weights of the live candidates, ``clip(1 - Error / prune_error_rad, 0, 1)``."""
        return np.clip(1.0 - self._store[_ERR, : self._m] / self._params.prune_error_rad, 0.0, 1.0)

    def hypothesis_spread(self) -> tuple[float, float]:
        """``wrappers.hypothesis_spread(self.overlay())``, computed in one pass over the store."""
        ox, oy, _ = self._odo.tolist()
        variance, r = _spread_sums(self._store, self._candidate_weights(), ox, oy)
        if not math.isfinite(variance):
            return math.nan, math.nan
        return math.sqrt(variance), circular_std(r)

    @property
    def set_sizes(self) -> NDArray[np.intp]:
        """``(S,)`` live candidates per set, in creation order (for diagnostics and tests)."""
        return self._counts[: self._n_sets].astype(np.intp)

    @property
    def sets_determined(self) -> NDArray[np.bool_]:
        """``(S,)`` whether each live set has determined a pose."""
        return self._determined[: self._n_sets].copy()

    @property
    def candidate_errors(self) -> NDArray[np.float64]:
        """``(M,)`` accumulated Error of the live candidates, in the order of :meth:`overlay`."""
        return self._store[_ERR, : self._m].copy()
