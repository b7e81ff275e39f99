"""The candidate-set localizer of the two-landmark bearings paper (PAPERS.md A, method (5)).

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

* All candidates of all sets live in flat arrays, grouped by set in creation order.
  Propagation is lazy: with ``O(t) = d_1 (+) ... (+) d_t`` the running product of all
  odometry increments (``geometry.compose``), a candidate is stored as
  ``X = P (+) O(t_gen)^-1`` and its pose is ``X (+) O(t)``; by associativity of SE(2) this
  equals composing every increment in the candidate's own frame, and ``predict`` is O(1).
  ``cos``/``sin`` of each ``X``'s heading are stored once, so an update needs one
  ``arctan2`` per candidate and landmark and no other transcendental function.
* Evaluation runs in float32 on ``(landmarks, candidates)`` buffers (bearing precision
  ~1e-7 rad); accumulated errors and poses stay float64.
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

import numpy as np
from numpy.typing import ArrayLike, NDArray

from localizers.base import BearingMeasurement, LandmarkMap, MeasurementError, OdometryDelta, Overlay, PoseEstimate
from localizers.geometry import between, circular_mean, compose, wrap_angle
from localizers.resection import inscribed_arc_poses, resect_all_triples
from localizers.schema import check

_PI32 = np.float32(np.pi)
_TWO_PI32 = np.float32(2.0 * np.pi)
_INV_TWO_PI32 = np.float32(1.0 / (2.0 * np.pi))


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


def _inside(landmarks: LandmarkMap, poses: NDArray[np.float64], margin_m: float) -> NDArray[np.bool_]:
    """``(m,)`` finite poses within the map bounds grown by ``margin_m``."""
    xmin, ymin, xmax, ymax = landmarks.bounds_m
    return (
        np.isfinite(poses).all(axis=1)
        & (poses[:, 0] >= xmin - margin_m) & (poses[:, 0] <= xmax + margin_m)
        & (poses[:, 1] >= ymin - margin_m) & (poses[:, 1] <= ymax + margin_m)
    )  # fmt: skip


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
    if idx.size < 2:
        return np.zeros((0, 3))
    if idx.size >= 3:
        res = resect_all_triples(pos, idx, b, min_conditioning=min_conditioning, inlier_radius_m=np.inf)
        poses = res.poses[res.ok]
        poses = poses[_inside(landmarks, poses, bounds_margin_m)]
        if poses.shape[0]:
            return poses
    i, j = np.triu_indices(idx.size, 1)
    best = int(np.argmax(np.abs(np.sin(b[j] - b[i]))))
    k, m = int(i[best]), int(j[best])
    # N candidates over the part of the arc inside the bounds (ours): oversample the arc,
    # keep the feasible positions and take N of them evenly by index.
    fine = inscribed_arc_poses(pos[idx[k]], pos[idx[m]], b[k], b[m], _ARC_OVERSAMPLING * candidates_per_arc)
    fine = fine[_inside(landmarks, fine, bounds_margin_m)]
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
    k = p.shape[0]
    if k == 1:
        return np.array([p[0, 0], p[0, 1], wrap_angle(p[0, 2])]), np.ones(1, dtype=bool)
    diff = p[:, None, :2] - p[None, :, :2]
    dist = np.hypot(diff[..., 0], diff[..., 1])  # (K, K)
    others = np.sort(dist[~np.eye(k, dtype=bool)].reshape(k, k - 1), axis=1)
    median = 0.5 * (others[:, (k - 2) // 2] + others[:, (k - 1) // 2])  # of the K - 1 distances
    kept = median < median_threshold_m
    if not kept.any():
        kept = np.zeros(k, dtype=bool)
        kept[int(np.argmin(median))] = True
    xy = p[kept, :2].mean(axis=0)
    return np.array([xy[0], xy[1], float(circular_mean(p[kept, 2]))]), kept


def _pose_covariance(poses: NDArray[np.float64], centre: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sample covariance of ``(m, 3)`` poses about ``centre`` (heading deviations wrapped)."""
    if poses.shape[0] < 2:
        return np.zeros((3, 3))
    dev = np.column_stack([poses[:, :2] - centre[:2], wrap_angle(poses[:, 2] - centre[2])])
    return dev.T @ dev / (poses.shape[0] - 1)


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
        if not (math.isfinite(dt_s) and dt_s > 0.0):
            raise ValueError(f"CandidateSetLocalizer: dt_s must be a positive number of seconds, got {dt_s!r}")
        self._map = landmarks
        self._params = params
        self._dt = float(dt_s)
        self._lx32 = landmarks.positions_xy_m[:, 0].astype(np.float32)
        self._ly32 = landmarks.positions_xy_m[:, 1].astype(np.float32)
        self._weights: dict[int, NDArray[np.float32]] = {}
        self._capacity = 0
        self._started = False
        self._clear()

    # ----------------------------------------------------------------------------- state

    def _clear(self) -> None:
        self._odo = np.zeros(3)  # O(t): running product of the odometry increments
        self._path_m = 0.0  # distance travelled since reset
        self._turn_rad = 0.0  # |rotation| accumulated since reset
        # Candidates, grouped by set: base poses X (rows x, y, theta), their cos/sin/1, errors, set index.
        self._base = np.zeros((3, 0))
        self._trig = np.zeros((3, 0))
        self._err = np.zeros(0)
        self._set = np.zeros(0, dtype=np.intp)
        # Per live set, in creation order.
        self._counts = np.zeros(0, dtype=np.intp)
        self._starts = np.zeros(0, dtype=np.intp)
        self._determined = np.zeros(0, dtype=bool)
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
        if not self._started:
            raise RuntimeError("CandidateSetLocalizer: call reset() before predict() or update()")

    def _ensure_capacity(self, m: int) -> None:
        """Grow the scratch buffers (flat, viewed as ``(rows, m)`` blocks) to ``m`` candidates."""
        if m <= self._capacity:
            return
        self._capacity = cap = max(m, 2 * self._capacity)
        n_max = max(self._map.count, 1)
        self._buf_pose64 = np.empty(3 * cap)
        self._buf_pose32 = np.empty(3 * cap, dtype=np.float32)
        self._buf_dx = np.empty(n_max * cap, dtype=np.float32)
        self._buf_dy = np.empty(n_max * cap, dtype=np.float32)
        # Residuals e (n rows) followed by a cyclic copy of their first rows (see _evaluate).
        self._buf_e = np.empty((n_max + (n_max - 1) // 2) * cap, dtype=np.float32)
        # Error terms: theta_k (n rows) then |pi - |e_j - e_k|| (n (n - 1) / 2 rows).
        self._buf_terms = np.empty((n_max + n_max * (n_max - 1) // 2) * cap, dtype=np.float32)

    def _term_weights(self, n: int) -> NDArray[np.float32]:
        """``(n + n (n - 1) / 2,)`` weights turning the term rows into eq. (1) (minus a constant)."""
        w = self._weights.get(n)
        if w is None:
            w = np.concatenate([np.ones(n), -np.ones(n * (n - 1) // 2)]).astype(np.float32)
            self._weights[n] = w
        return w

    # ----------------------------------------------------------------------------- steps

    def predict(self, odometry: OdometryDelta) -> None:
        """Propagate every candidate by the increment (lazily: one SE(2) product)."""
        self._require_reset()
        d = odometry.as_array()
        if not np.isfinite(d).all():
            raise MeasurementError(f"candidate_sets: odometry increment {d.tolist()} is not finite")
        self._odo = compose(self._odo, d)
        self._path_m += math.hypot(d[0], d[1])
        self._turn_rad += abs(d[2])
        self._cached = None

    def update(self, measurement: BearingMeasurement) -> None:
        """Evaluate, prune, abort, determine and generate with one frame's bearings."""
        self._require_reset()
        if not isinstance(measurement, BearingMeasurement):
            raise MeasurementError(f"candidate_sets: expected a BearingMeasurement, got {type(measurement).__name__}")
        meas = measurement.validated(self._map.count, source="candidate_sets")
        self._cached = None
        self._pending += self._pending_next
        self._pending_next = 0
        ids, bearings = meas.landmark_ids, meas.bearings_rad
        n = ids.size
        if n == 0:
            return
        if self._err.size:
            self._evaluate(ids, bearings)
            self._prune_and_abort()
            newly = ~self._determined & (self._counts < self._params.determine_below)
            if newly.any():
                self._determined |= newly
                self._pending += int(newly.sum())
        self._pending = min(self._pending, self._params.max_sets - self._counts.size)
        if self._pending > 0 and n >= 2:
            self._generate(ids, bearings)

    def _evaluate(self, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> None:
        """Add eq. (1) to every candidate's Error (eq. (2))."""
        m, n = self._err.size, ids.size
        pairs = n * (n - 1) // 2
        self._ensure_capacity(m)
        ox, oy, ot = self._odo.tolist()
        # Current poses X (+) O of all candidates as one (3, 3) @ (3, m) product.
        lin = np.array([[ox, -oy, 0.0], [oy, ox, 0.0], [0.0, 0.0, ot]])
        pose64 = self._buf_pose64[: 3 * m].reshape(3, m)
        np.matmul(lin, self._trig, out=pose64)
        np.add(pose64, self._base, out=pose64)
        pose32 = self._buf_pose32[: 3 * m].reshape(3, m)
        np.copyto(pose32, pose64, casting="same_kind")
        dx = self._buf_dx[: n * m].reshape(n, m)
        dy = self._buf_dy[: n * m].reshape(n, m)
        e = self._buf_e[: n * m].reshape(n, m)
        terms = self._buf_terms[: (n + pairs) * m].reshape(n + pairs, m)
        np.subtract(self._lx32[ids][:, None], pose32[0], out=dx)
        np.subtract(self._ly32[ids][:, None], pose32[1], out=dy)
        # e_ik = l'_ik - l_k: predicted minus measured bearing, wrapped to [-pi, pi].
        np.arctan2(dy, dx, out=e)
        np.add(pose32[2], bearings.astype(np.float32)[:, None], out=dx)  # theta_i + l_k
        np.subtract(e, dx, out=e)
        np.multiply(e, _INV_TWO_PI32, out=dx)
        np.rint(dx, out=dx)
        np.multiply(dx, _TWO_PI32, out=dx)
        np.subtract(e, dx, out=e)
        # eq. (1), first sum: theta_k = |l_k - l'_ik|.
        np.abs(e, out=terms[:n])
        if pairs:
            # eq. (1), second sum: phi_kj = |psi_kj - psi'_kj| = |wrap(e_j - e_k)| over all pairs.
            # The pairs are the cyclic shifts (j, j + s mod n), s = 1..(n - 1) // 2 (n pairs
            # each), plus (j, j + n/2), j < n/2, for even n. With e's first rows copied after
            # it, shift s reads rows s..s+n-1, so all shifts are one strided (S, n, m) view.
            shifts = (n - 1) // 2
            d = terms[n:]
            if shifts:
                self._buf_e[n * m : (n + shifts) * m] = self._buf_e[: shifts * m]
                window = np.ndarray(
                    (shifts, n, m), dtype=np.float32, buffer=self._buf_e, offset=4 * m, strides=(4 * m, 4 * m, 4)
                )
                np.subtract(window, e, out=d[: shifts * n].reshape(shifts, n, m))
            if n % 2 == 0:
                np.subtract(e[n // 2 :], e[: n // 2], out=d[shifts * n :])
            # For |x| <= 2 pi, |wrap(x)| = pi - |pi - |x||: the pi's go into a constant.
            np.abs(d, out=d)
            np.subtract(_PI32, d, out=d)
            np.abs(d, out=d)
        self._err += self._term_weights(n) @ terms
        if pairs:
            self._err += pairs * np.pi

    def _prune_and_abort(self) -> None:
        """Delete candidates over the prune threshold and sets over the abort threshold."""
        p = self._params
        err = self._err
        mins = np.minimum.reduceat(err, self._starts)  # every live set is non-empty
        dead = (mins > p.abort_error_rad) | (mins > p.prune_error_rad)
        keep = err <= p.prune_error_rad
        if dead.any():
            if self._determined.any() and not (self._determined & ~dead).any():
                self._snapshot_for_coasting()  # the last determined pose, before it is discarded
            keep &= ~dead[self._set]
            self._pending_next += int(dead.sum())  # replaced "the next time" (sec. 3), not from this frame
        if keep.all():
            return
        alive = ~dead
        remap = np.cumsum(alive) - 1
        self._base = self._base[:, keep]
        self._trig = self._trig[:, keep]
        self._err = err[keep]
        self._set = remap[self._set[keep]]
        self._determined = self._determined[alive]
        self._set_counts(np.bincount(self._set, minlength=int(alive.sum())))

    def _set_counts(self, counts: NDArray[np.intp]) -> None:
        self._counts = counts.astype(np.intp)
        self._starts = np.concatenate(([0], np.cumsum(self._counts)[:-1])).astype(np.intp)

    def _generate(self, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> None:
        """Append one new set built from this frame's bearings, if the budget allows."""
        p = self._params
        poses = generate_candidates(
            self._map, ids, bearings,
            candidates_per_arc=p.candidates_per_arc, min_conditioning=p.min_conditioning,
            bounds_margin_m=p.bounds_margin_m,
        )  # fmt: skip
        m = poses.shape[0]
        if m == 0 or self._err.size + m > p.max_live_candidates:
            return
        base = compose(poses, between(self._odo, np.zeros(3)))  # X = P (+) O^-1
        trig = np.stack([np.cos(base[:, 2]), np.sin(base[:, 2]), np.ones(m)])
        self._base = np.concatenate([self._base, base.T], axis=1)
        self._trig = np.concatenate([self._trig, trig], axis=1)
        self._err = np.concatenate([self._err, np.zeros(m)])
        self._set = np.concatenate([self._set, np.full(m, self._counts.size, dtype=np.intp)])
        self._determined = np.append(self._determined, False)
        self._set_counts(np.append(self._counts, m))
        self._pending -= 1

    # ----------------------------------------------------------------------------- output

    def _candidate_poses(self, lo: int = 0, hi: int | None = None) -> NDArray[np.float64]:
        """``(m, 3)`` current poses of candidates ``lo:hi``."""
        return compose(self._base[:, lo:hi].T, self._odo)

    def _best_per_set(self) -> NDArray[np.intp]:
        """``(S,)`` index of each live set's least-Error candidate (the first one on ties)."""
        mins = np.minimum.reduceat(self._err, self._starts)
        hits = np.flatnonzero(self._err == np.repeat(mins, self._counts))
        first = np.ones(hits.size, dtype=bool)
        first[1:] = self._set[hits[1:]] != self._set[hits[:-1]]
        return hits[first]

    def _fused_output(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Fuse the determined sets' poses now: ``(pose (3,), covariance (3, 3))``."""
        p = self._params
        sets = np.flatnonzero(self._determined)
        best = compose(self._base[:, self._best_per_set()[sets]].T, self._odo)
        pose, kept = fuse_poses(best, p.fusion_median_m)
        if kept.sum() >= 2:
            cov = _pose_covariance(best[kept], pose)
        else:
            s = int(sets[int(np.argmax(kept))])
            lo = int(self._starts[s])
            cov = _pose_covariance(self._candidate_poses(lo, lo + int(self._counts[s])), pose)
        floor = np.array([p.position_floor_m**2] * 2 + [p.heading_floor_rad**2])
        cov[np.diag_indices(3)] = np.maximum(np.diag(cov), floor)
        return pose, cov

    def _snapshot_for_coasting(self) -> None:
        """Keep the current fused pose (as a base pose ``X = pose (+) O^-1``) for dead reckoning."""
        pose, cov = self._fused_output()
        self._coast = (compose(pose, between(self._odo, np.zeros(3))), cov, self._path_m, self._turn_rad)

    @property
    def estimate(self) -> PoseEstimate:
        """Fused pose of the determined sets; invalid before the first determination."""
        if self._cached is None:
            self._cached = self._compute_estimate()
        e = self._cached
        return PoseEstimate(e.x_m, e.y_m, e.theta_rad, e.covariance.copy(), e.valid)

    def _compute_estimate(self) -> PoseEstimate:
        if self._determined.any():
            (x, y, th), cov = self._fused_output()
            return PoseEstimate(float(x), float(y), float(th), cov, True)
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
        x, y, th = compose(base, self._odo)
        return PoseEstimate(float(x), float(y), float(th), cov, True)

    def overlay(self) -> Overlay:
        """Live candidates; weight ``1 - Error / prune_error_rad`` (low Error = high weight)."""
        if self._err.size == 0:
            return Overlay(label="candidate sets: none")
        weights = np.clip(1.0 - self._err / self._params.prune_error_rad, 0.0, 1.0)
        label = f"candidate sets: {self._counts.size} sets, {int(self._determined.sum())} determined"
        return Overlay(poses=self._candidate_poses(), weights=weights, label=label)

    @property
    def set_sizes(self) -> NDArray[np.intp]:
        """``(S,)`` live candidates per set, in creation order (for diagnostics and tests)."""
        return self._counts.copy()

    @property
    def sets_determined(self) -> NDArray[np.bool_]:
        """``(S,)`` whether each live set has determined a pose."""
        return self._determined.copy()

    @property
    def candidate_errors(self) -> NDArray[np.float64]:
        """``(M,)`` accumulated Error of the live candidates, in the order of :meth:`overlay`."""
        return self._err.copy()
