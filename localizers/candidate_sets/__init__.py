"""The candidate-set localizer of the two-landmark bearings paper (docs/papers.md section A, method (5)).

1. *Generation*: with exactly 2 landmark bearings seen, N poses on the inscribed-angle arc
   (:func:`localizers.resection.inscribed_arc_poses`), spread over the part of the arc
   inside the map bounds (ours); with >= 3, the ok Cassini solutions of all C(L, 3)
   triples (:func:`localizers.resection.resect_all_triples`) inside the bounds. Every
   error starts at 0.
2. *Propagation*: each candidate moves by the odometry increment in its own frame.
3. *Evaluation*: eq. (1)-(2), accumulated per candidate (optionally with forgetting,
   ours and off by default: ``error_time_constant_s``, see below).
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
  the candidate's own frame, and ``predict`` is O(1). The kernels are in
  :mod:`localizers.candidate_sets.kernels`.
  ``cos``/``sin`` of each ``X``'s heading are stored once, so an update needs one
  ``arctan2`` per candidate and landmark and no other transcendental function.
* Evaluation runs in float32 (bearing precision ~1e-7 rad; ``arctan2`` is a branch-free
  polynomial accurate to ~3 ulp, so the loops vectorize); accumulated errors and poses
  stay float64.
* At most one set is generated per frame (sets generated from one frame are identical);
  owed generations wait for the next frame with >= 2 landmarks. A set discarded at a frame
  is replaced from a later frame, never from the bearings that made it fail.
* Forgetting (ours, not the paper's; off by default, ``error_time_constant_s = inf``): eq. (2)
  sums every frame's eq. (1) error since the set was generated, so a correct candidate's
  Error grows without bound (about 2.7 bearing sigmas per frame with two landmarks) and
  every set reaches the abort threshold after a fixed time, however well it fits. With a
  time constant ``tau``, each update first multiplies every Error by ``exp(-elapsed / tau)``
  (``elapsed``: the frames since the last evaluation times ``dt_s``), then adds eq. (1):
  ``Error <- lambda Error + AngleError`` with ``lambda = exp(-dt / tau)`` at every frame.
  An exponential factor keeps O(1) state per candidate (a sliding window would have to
  store each candidate's last ``tau / dt`` terms) and, written as a time constant, means
  the same at any frame rate. Multiplying every Error of the store by the same factor
  changes no ranking, so a set chooses the same least-Error pose as without it; what changes is
  the meaning of the thresholds: a candidate whose eq. (1) error is ``e`` per frame settles
  at ``e / (1 - lambda) ~ e tau / dt``, so ``prune_error_rad`` and ``abort_error_rad``
  become limits on the *recent* mean error per frame, ``threshold * (1 - lambda)``. For a
  correct candidate to survive, its steady state, ``mean eq. (1) error per frame * tau /
  dt``, must stay well below ``abort_error_rad`` (with two landmarks at 1 deg noise and
  30 fps, ~1.4 rad per second of ``tau``); ``tau`` also bounds how much evidence a set
  can use to separate candidates, so a short ``tau`` keeps sets from ever determining.
* Once a pose has been determined, the last fused pose is dead-reckoned with odometry if
  every determined set is discarded, until a set determines again, its standard deviations
  growing by ``coast_growth_per_m`` per metre travelled (and per radian turned for the
  heading).

Knowing when it is lost (ours, the paper says nothing of it):

* *Widening on empty frames.* A frame without bearings evaluates nothing, so the sets stay
  determined and their candidates move rigidly with the odometry: their spread would stay
  that of the last seen frame however far the robot drives blind (0.07 m after 333 s, 84 %
  of steps more than 3 sd off). The reported standard deviations grow by
  ``coast_growth_per_m`` per metre (and radian) driven since the last frame with a bearing,
  as when coasting.
* *Lost detection.* At each frame with >= 2 bearings, the median absolute bearing residual
  of the current estimate (determined or coasting); when it exceeds ``lost_residual_rad`` on
  every frame for ``lost_after_s``, the localizer declares itself lost: every set and the
  coast are dropped and it starts again from this frame's bearings, as after ``reset``
  (invalid until a new set determines). Measured recovery after a kidnap (>= 2 m, at 10 s):
  python -m tests.localizers.lost_figures gauss_kidnap.
* ``max_spread_m``: past this position spread the estimate is not claimed.

Consistency (measured, ``crowdloc reproduce bearing-candidates``, 20 seeds): cautious in Exp 1
(median 0.40, 95 % inside), about right in Exp 2 with K = 10 (1.34, 89 %); with fewer sets it
is overconfident (K = 1: 4.54, 59 %; K = 5: 1.89, 79 %): one set's best candidates spread less
than the error of the frame they came from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import between, circular_std, compose
from core.schema import check, check_at_most, check_ranges
from localizers.base import (
    DEFAULT_MAX_SPREAD_M,
    BearingMeasurement,
    ConsistencyPromise,
    LandmarkMap,
    LocalizerBase,
    OdometryDelta,
    Overlay,
    PoseEstimate,
    check_max_spread,
    checked_bearings,
    require_reset,
    within_spread,
)
from localizers.candidate_sets.kernels import (
    ROW_ERR,
    ROW_TH,
    ROW_X,
    ROWS,
    accumulate,
    append_candidates,
    compose_pose,
    evaluate,
    forget,
    fuse,
    fused_output,
    inside,
    prune_abort_determine,
    spread_sums,
    triple_seeds,
)
from localizers.contradiction import Contradiction
from localizers.particles import MAX_PARTICLES
from localizers.resection import inscribed_arc_poses, triple_indices


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
        error_time_constant_s: time constant ``tau`` of an exponential forgetting of the
            accumulated Error, ``Error <- exp(-dt / tau) Error + eq. (1)`` at each update
            (s; ours, not the paper's). ``inf`` (the default) is the paper's eq. (2)
            exactly, with no forgetting. With a finite ``tau`` the thresholds bound the
            recent mean error per frame (see the module docstring).
        lost_residual_rad: median absolute bearing residual of the estimate above which a
            frame contradicts it (rad; ours, 20 bearing sigmas at 1 deg).
        lost_after_s: contradicted on every frame with >= 2 bearings for this long, the
            localizer starts again from the bearings (s; ours; ``inf``: never).
        max_spread_m: past this position spread (m) the estimate is not claimed (ours).
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
    error_time_constant_s: float = math.inf
    lost_residual_rad: float = 0.35
    lost_after_s: float = 0.5
    max_spread_m: float = DEFAULT_MAX_SPREAD_M

    def __post_init__(self) -> None:
        check_max_spread("CandidateSetParams", self.max_spread_m)
        check(
            math.isfinite(self.lost_residual_rad) and 0.0 < self.lost_residual_rad <= math.pi,
            f"CandidateSetParams.lost_residual_rad must be in (0, pi] rad, got {self.lost_residual_rad!r}",
        )
        check(
            self.lost_after_s >= 0.0,  # false for NaN
            f"CandidateSetParams.lost_after_s must be a number of seconds >= 0 (inf: never), got {self.lost_after_s!r}",
        )
        for name in ("candidates_per_arc", "max_sets", "determine_below", "max_live_candidates"):
            value = getattr(self, name)
            check(value >= 1, f"CandidateSetParams.{name} must be an integer >= 1, got {value!r}")
        # each arc is computed at _ARC_OVERSAMPLING points per kept candidate; every set holds up to N candidates
        check_at_most(
            self,
            "CandidateSetParams",
            {"candidates_per_arc": MAX_PARTICLES // _ARC_OVERSAMPLING, "max_live_candidates": MAX_PARTICLES, "max_sets": 10_000},
            "memory: each candidate is a pose and its accumulated error, about 50 bytes, updated at every frame",
        )
        check_ranges(
            self,
            "CandidateSetParams",
            positive=("prune_error_rad", "abort_error_rad", "fusion_median_m", "min_conditioning"),
            non_negative=("bounds_margin_m", "position_floor_m", "heading_floor_rad", "coast_growth_per_m"),
        )
        check(
            self.abort_error_rad <= self.prune_error_rad,
            f"CandidateSetParams.abort_error_rad {self.abort_error_rad!r} must not be above prune_error_rad "
            f"{self.prune_error_rad!r}: above it, it has no effect (a set whose least Error exceeds prune_error_rad "
            "has lost all its candidates)",
        )
        tau = self.error_time_constant_s
        check(
            tau > 0.0,  # false for NaN
            f"CandidateSetParams.error_time_constant_s must be a number > 0 (s; inf: no forgetting, the paper's eq. (2)), got {tau!r}",
        )

    @property
    def forgets(self) -> bool:
        """Whether the accumulated Error is forgotten (a finite ``error_time_constant_s``)."""
        return math.isfinite(self.error_time_constant_s)


_ARC_OVERSAMPLING = 8
"""Arc points computed per kept candidate before clipping to the bounds (ours)."""


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
        poses = triple_seeds(pos[idx], b, triple_indices(idx.size), float(min_conditioning), *box)  # (indexing checks the ids)
        if poses.shape[0]:
            return poses
    i, j = np.triu_indices(idx.size, 1)
    best = int(np.argmax(np.abs(np.sin(b[j] - b[i]))))
    k, m = int(i[best]), int(j[best])
    # N candidates over the part of the arc inside the bounds (ours): oversample the arc,
    # keep the feasible positions and take N of them evenly by index.
    fine = inscribed_arc_poses(pos[idx[k]], pos[idx[m]], b[k], b[m], _ARC_OVERSAMPLING * candidates_per_arc)
    fine = fine[inside(fine, *box)]
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
    return fuse(np.ascontiguousarray(p), float(median_threshold_m))


class CandidateSetLocalizer(LocalizerBase[CandidateSetParams]):
    """Multiple candidate sets pruned by accumulated bearing errors, fused (paper method (5)).

    The estimate is invalid until a set first determines. Its covariance is the sample
    covariance of the fused (kept) poses when there are >= 2, else that of the candidates
    of the one determined set, each diagonal entry floored by ``position_floor_m^2`` /
    ``heading_floor_rad^2``. :meth:`overlay` draws every live candidate, weighted by
    ``1 - Error / prune_error_rad``.
    """

    name: ClassVar[str] = "candidate_sets"
    #: measured on this run: share 0.541, NEES median 2.8: the robot's true motion differs from its commands by
    #: 4.7 m over its 10.8 m path, 4.6 m of it on the 290 steps where the random walk drives it against the
    #: field's edge, and one set's best candidates spread less than the error of the frame they came from
    #: (module docstring)
    #: (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.5)

    def __init__(self, landmarks: LandmarkMap, params: CandidateSetParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s, owner="CandidateSetLocalizer")
        self._lx32 = landmarks.positions_xy_m[:, 0].astype(np.float32)
        self._ly32 = landmarks.positions_xy_m[:, 1].astype(np.float32)
        self._contradiction = Contradiction(landmarks.positions_xy_m, params.lost_residual_rad, params.lost_after_s, self._dt_s)
        self._floors = np.array([params.position_floor_m**2] * 2 + [params.heading_floor_rad**2])
        # Candidates, grouped by set in creation order: column i holds candidate i's base pose
        # X (rows ROW_X, ROW_Y, ROW_TH), cos/sin of its heading and its accumulated Error (row ROW_ERR).
        # Only the first ``_m`` columns are live; the store grows up to max_live_candidates.
        self._store = np.zeros((ROWS, 0))
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
        self._since_eval_s = 0.0  # time since the candidates' Errors were last evaluated (forgetting)
        self._pending = 1  # generations owed now (the first set is owed from the start)
        self._pending_next = 0  # generations owed from the next frame on (after an abort)
        # Last fused output, kept for coasting: base pose X, covariance, path/turn at the time.
        self._coast: tuple[NDArray[np.float64], NDArray[np.float64], float, float] | None = None
        self._cached: PoseEstimate | None = None
        self._seen = (0.0, 0.0)  # path and turn at the last frame with a bearing (widening, ours)
        self._contradiction.reset()  # how long every frame with >= 2 bearings contradicted the estimate (ours)

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
        grown = np.zeros((ROWS, min(max(m, 2 * cap), self._params.max_live_candidates)))
        grown[:, : self._m] = self._store[:, : self._m]
        self._store = grown

    # ----------------------------------------------------------------------------- steps

    def predict(self, odometry: OdometryDelta) -> None:
        """Propagate every candidate by the increment (lazily: one SE(2) product)."""
        self._require_reset()
        dx, dy, dth = self._checked_increment(odometry)
        accumulate(self._odo, dx, dy, dth)
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
        p = self._params
        self._since_eval_s += self._dt_s
        if n == 0:
            return
        self._seen = (self._path_m, self._turn_rad)
        if n >= 2 and self._contradicts(ids, bearings):  # lost (ours)
            if self._determined[: self._n_sets].any():  # start again from these bearings, as after reset
                odo, path, turn = self._odo, self._path_m, self._turn_rad
                self._clear()
                self._odo, self._path_m, self._turn_rad = odo, path, turn
                self._seen = (path, turn)
            else:  # only the coast is wrong: drop it, the sets being built go on
                self._coast = None
            self._contradiction.reset()
        if self._m:
            ox, oy, ot = self._odo.tolist()
            if p.forgets:  # (ours; off by default, so the paper's eq. (2) is untouched)
                forget(self._store, self._m, math.exp(-self._since_eval_s / p.error_time_constant_s))
            evaluate(self._store, self._m, ox, oy, ot, self._lx32, self._ly32, ids, bearings)
            self._m, self._n_sets, n_dead, n_new, snapped = prune_abort_determine(
                self._store, self._m, self._counts, self._n_sets, self._determined,
                p.prune_error_rad, p.abort_error_rad, p.determine_below,
                ox, oy, ot, p.fusion_median_m, self._floors, self._snapshot,
            )  # fmt: skip
            if snapped:  # the last determined pose, before it was discarded
                pose, cov = self._snapshot[0].copy(), self._snapshot[1:].copy()
                self._coast = (compose(pose, between(self._odo, np.zeros(3))), cov, self._path_m, self._turn_rad)
            self._since_eval_s = 0.0
            self._pending_next += n_dead  # replaced "the next time" (sec. 3), not from this frame
            self._pending += n_new
        self._pending = min(self._pending, p.max_sets - self._n_sets)
        if self._pending > 0 and n >= 2 and self._m < p.max_live_candidates:
            self._generate(ids, bearings)

    def _contradicts(self, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> bool:
        """Whether the estimate has been contradicted by the bearings (median absolute
        residual over ``lost_residual_rad``) on every frame for ``lost_after_s`` (ours)."""
        est = self._compute_estimate()  # before this frame's evaluation, which changes it
        has = est.valid or self._coast is not None or bool(self._determined[: self._n_sets].any())
        return self._contradiction.observe((est.x_m, est.y_m, est.theta_rad) if has else None, ids, bearings)

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
        append_candidates(self._store, self._m, poses, ox, oy, ot)
        self._m += m
        self._counts[self._n_sets] = m
        self._determined[self._n_sets] = False
        self._n_sets += 1
        self._pending -= 1

    # ----------------------------------------------------------------------------- output

    def _candidate_poses(self) -> NDArray[np.float64]:
        """``(m, 3)`` current poses of the live candidates."""
        return compose(self._store[ROW_X : ROW_TH + 1, : self._m].T, self._odo)

    @property
    def estimate(self) -> PoseEstimate:
        """Fused pose of the determined sets; invalid before the first determination."""
        if self._cached is None:
            self._cached = self._compute_estimate()
        e = self._cached
        return PoseEstimate(e.x_m, e.y_m, e.theta_rad, e.covariance.copy(), e.valid)

    def _compute_estimate(self) -> PoseEstimate:
        ox, oy, ot = self._odo.tolist()
        pose, cov, determined = fused_output(
            self._store, self._counts, self._n_sets, self._determined, ox, oy, ot, self._params.fusion_median_m, self._floors
        )
        if determined:
            x, y, th = pose.tolist()
            cov = self._grown(cov, *self._seen)  # (ours) blind since the last frame with a bearing
            return PoseEstimate(x, y, th, cov, within_spread(cov, self._params.max_spread_m))
        if self._coast is None:
            return PoseEstimate.invalid()
        base, cov, path0, turn0 = self._coast
        cov = self._grown(cov, path0, turn0)
        x, y, th = compose_pose(base, *self._odo.tolist())
        return PoseEstimate(x, y, th, cov, within_spread(cov, self._params.max_spread_m))

    def _grown(self, cov: NDArray[np.float64], path0: float, turn0: float) -> NDArray[np.float64]:
        """``cov`` with its standard deviations grown by ``coast_growth_per_m`` per metre
        driven (and radian turned) since ``path0`` (``turn0``)."""
        g = self._params.coast_growth_per_m
        pos_sd = g * (self._path_m - path0)
        head_sd = g * (self._turn_rad - turn0)
        if pos_sd == 0.0 and head_sd == 0.0:
            return cov
        cov = cov.copy()
        cov[0, 0] = (math.sqrt(cov[0, 0]) + pos_sd) ** 2
        cov[1, 1] = (math.sqrt(cov[1, 1]) + pos_sd) ** 2
        cov[2, 2] = (math.sqrt(cov[2, 2]) + head_sd) ** 2
        return cov

    def overlay(self) -> Overlay:
        """Live candidates; weight ``1 - Error / prune_error_rad`` (low Error = high weight)."""
        if self._m == 0:
            return Overlay(label="candidate sets: none")
        label = f"candidate sets: {self._n_sets} sets, {int(self._determined[: self._n_sets].sum())} determined"
        return Overlay(poses=self._candidate_poses(), weights=self._candidate_weights(), label=label)

    def _candidate_weights(self) -> NDArray[np.float64]:
        """``(m,)`` overlay weights of the live candidates, ``clip(1 - Error / prune_error_rad, 0, 1)``."""
        return np.clip(1.0 - self._store[ROW_ERR, : self._m] / self._params.prune_error_rad, 0.0, 1.0)

    def hypothesis_spread(self) -> tuple[float, float]:
        """``wrappers.hypothesis_spread(self.overlay())``, computed in one pass over the store."""
        ox, oy, _ = self._odo.tolist()
        variance, r = spread_sums(self._store, self._candidate_weights(), ox, oy)
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
        return self._store[ROW_ERR, : self._m].copy()
