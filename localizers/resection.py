"""Bearing-only resection: Cassini's three-point method, the two-landmark arc, and baseline (2).

Candidate-set paper (docs/papers.md section A): baseline (2) solves the pose by Cassini's method whenever
>= 3 landmark bearings are seen and gives no output otherwise; the proposed method seeds its
candidate sets from the inscribed-angle arc (2 landmarks) or from every Cassini triple
(>= 3 landmarks). The pure functions here serve both and the other localizers.

Conventions: bearings are robot-frame, counter-clockwise from the heading, in radians.

**Cassini's construction.** Let the robot R see L1, L2, L3 at bearings b1, b2, b3 and put
``a12 = b2 - b1``, ``a23 = b3 - b2``. R lies on the circle C1 through L1, L2 (chord L1L2
subtends a12) and on C3 through L2, L3 (chord L2L3 subtends a23). Let P1 and P3 be the
points of C1 and C3 diametrically opposite L2. Thales gives ``angle(L2 R P1) = 90 deg`` and
``angle(L2 R P3) = 90 deg``, so R is on the line P1P3 and is the foot of the perpendicular
from L2 to it. With ``J`` the +90 deg rotation, the directed-angle form of the inscribed-
angle theorem (angles between lines, mod pi) gives

    P1 = L1 - cot(a12) J (L1 - L2),    P3 = L3 + cot(a23) J (L3 - L2).

Because the construction works with lines, not rays, a solution may reproduce a bearing
only up to pi; such solutions are rejected by a residual check.

**Conditioning.** With ``F_i(R, theta) = atan2(L_i - R) - theta - b_i = 0``, the solution's
sensitivity to the bearings is ``d(R, theta)/db = A^-1`` where row i of ``A`` is
``((L_iy - R_y) / r_i^2, -(L_ix - R_x) / r_i^2, -1)``. ``det A = 0`` exactly on the danger
circle (through the three landmarks; a line for collinear landmarks). The scale-free
conditioning is

    c = d_rms / ||(A^-1)[:2, :]||_F

with ``d_rms`` the RMS robot-landmark distance: for independent bearing errors of standard
deviation ``s`` the RMS position error is ``s d_rms / c`` (linearized). ``c`` is 0 on the
danger circle and, when the robot is inside a landmark triangle whose angles are all
>= 10 deg, it is above 0.1 (checked on 100k random cases); the default
``min_conditioning = 0.1`` (ours) therefore accepts such geometries and rejects e.g. a robot
within ~1 % of the circle's radius from it, where a 1 deg bearing error would move the
solution by more than ~17 % of the distance to the landmarks.

Consistency of baseline (2) (measured, ``crowdloc reproduce bearing-candidates``, 20 seeds): in
Exp 2 NEES median 1.56, 84 % of fixes inside the 95 % region; in Exp 1 2401 and 14 %: where
L5 is out of range, its distractor is taken for it, and the fix from that wrong bearing is
metres off with the small covariance of a well-conditioned triple. The covariance knows the
bearing noise, not a misidentification.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from itertools import combinations
from typing import ClassVar

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import circular_mean, wrap_angle
from core.motion import wrap_scalar
from core.schema import check_ranges
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

DEFAULT_MIN_CONDITIONING = 0.1
"""Default lower bound on the conditioning ``c`` (ours; see the module docstring)."""

RESIDUAL_TOL_RAD = 1e-6
"""A Cassini solution must reproduce all three bearings to this tolerance (rejects the
solutions that match a bearing only up to pi). Exact solutions do so to ~1e-12 rad."""

# Landmark order putting the pivot in the middle, indexed by the excluded pair
# (0: pair (0, 1) -> pivot 2, 1: pair (1, 2) -> pivot 0, 2: pair (0, 2) -> pivot 1).
_PIVOT_ORDER = np.array([[0, 2, 1], [1, 0, 2], [0, 1, 2]], dtype=np.intp)


def _cassini(
    landmarks_xy: NDArray[np.float64], bearings_rad: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Raw Cassini solve: ``(poses (..., 3), conditioning (...,), rms_distance_m (...,))``.

    Degenerate inputs give NaN poses or conditioning (never an exception); a pose whose
    bearings do not reproduce the measurement gets conditioning NaN.
    """
    lm = np.ascontiguousarray(landmarks_xy, dtype=np.float64)
    b = np.ascontiguousarray(bearings_rad, dtype=np.float64)
    lead = b.shape[:-1]
    poses, cond, d_rms = _cassini_kernel(lm.reshape(-1, 3, 2), b.reshape(-1, 3), _PIVOT_ORDER, RESIDUAL_TOL_RAD)
    return poses.reshape(lead + (3,)), cond.reshape(lead), d_rms.reshape(lead)


@numba.njit(cache=True, error_model="numpy")
def _cassini_kernel(  # 88 lines: one compiled loop over the triples, the docstring's construction step by step
    landmarks_xy: NDArray[np.float64], bearings_rad: NDArray[np.float64], pivot_order: NDArray[np.intp], residual_tol: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The construction of the module docstring for ``(T, 3, 2)`` landmarks and ``(T, 3)`` bearings.

    Compiled: frames with 8 landmarks solve all 56 triples at once, and candidate sets,
    the Kalman filter and MCL re-seeding do this often.
    """
    n = bearings_rad.shape[0]
    poses = np.empty((n, 3))
    cond = np.empty(n)
    d_rms = np.empty(n)
    lx = np.empty(3)
    ly = np.empty(3)
    bb = np.empty(3)
    world_dir = np.empty(3)
    r2 = np.empty(3)
    rows = np.empty((3, 3))
    cof = np.empty((3, 3))
    for t in range(n):
        b0, b1, b2 = bearings_rad[t, 0], bearings_rad[t, 1], bearings_rad[t, 2]
        # Pivot (the construction's L2) on the landmark outside the pair seen most nearly
        # (anti)parallel: a robot on the line through two landmarks makes their angle 0 or
        # pi and cot() infinite, but the pose is still defined unless all three are on one line.
        s01 = abs(math.sin(b1 - b0))
        s12 = abs(math.sin(b2 - b1))
        s02 = abs(math.sin(b2 - b0))
        k = 0
        if s12 < s01:
            k = 1
        if s02 < min(s01, s12):
            k = 2
        for j in range(3):
            src = pivot_order[k, j]
            lx[j] = landmarks_xy[t, src, 0]
            ly[j] = landmarks_xy[t, src, 1]
            bb[j] = bearings_rad[t, src]
        a12 = bb[1] - bb[0]
        a23 = bb[2] - bb[1]
        cot12 = math.cos(a12) / math.sin(a12)
        cot23 = math.cos(a23) / math.sin(a23)
        # P1 = L1 - cot(a12) J (L1 - L2), P3 = L3 + cot(a23) J (L3 - L2), with J (x, y) = (-y, x)
        p1x = lx[0] + cot12 * (ly[0] - ly[1])
        p1y = ly[0] - cot12 * (lx[0] - lx[1])
        p3x = lx[2] - cot23 * (ly[2] - ly[1])
        p3y = ly[2] + cot23 * (lx[2] - lx[1])
        # foot of the perpendicular from L2 on the line P1P3
        ex = p3x - p1x
        ey = p3y - p1y
        u = ((lx[1] - p1x) * ex + (ly[1] - p1y) * ey) / (ex * ex + ey * ey)
        rx = p1x + u * ex
        ry = p1y + u * ey
        sin_sum = 0.0
        cos_sum = 0.0
        for j in range(3):
            dx = lx[j] - rx
            dy = ly[j] - ry
            world_dir[j] = math.atan2(dy, dx)
            sin_sum += math.sin(world_dir[j] - bb[j])
            cos_sum += math.cos(world_dir[j] - bb[j])
            r2[j] = dx * dx + dy * dy
            rows[j, 0] = dy / r2[j]
            rows[j, 1] = -dx / r2[j]
            rows[j, 2] = -1.0
        heading = wrap_scalar(math.atan2(sin_sum, cos_sum))
        residual = 0.0
        for j in range(3):
            e = wrap_scalar(world_dir[j] - heading - bb[j])
            # NaN-propagating maximum, like np.max
            if abs(e) > residual or e != e:
                residual = abs(e)
        # conditioning from the adjugate of A (rows a0, a1, a2): A^-1 = [a1 x a2, a2 x a0, a0 x a1] / det
        for j in range(3):
            p = rows[(j + 1) % 3]
            q = rows[(j + 2) % 3]
            cof[j, 0] = p[1] * q[2] - p[2] * q[1]
            cof[j, 1] = p[2] * q[0] - p[0] * q[2]
            cof[j, 2] = p[0] * q[1] - p[1] * q[0]
        det = rows[0, 0] * cof[0, 0] + rows[0, 1] * cof[0, 1] + rows[0, 2] * cof[0, 2]
        sens_num = math.sqrt(sum_sq_xy(cof))
        rms = math.sqrt((r2[0] + r2[1] + r2[2]) / 3.0)
        c = rms * abs(det) / sens_num
        poses[t, 0] = rx
        poses[t, 1] = ry
        poses[t, 2] = heading
        cond[t] = c if residual <= residual_tol else math.nan
        d_rms[t] = rms
    return poses, cond, d_rms


@numba.njit(cache=True)
def _accept(poses: NDArray[np.float64], cond: NDArray[np.float64], min_conditioning: float) -> NDArray[np.bool_]:
    """``(T,)`` ok flags of raw ``(T, 3)`` solutions: finite and conditioning >= ``min_conditioning``
    (NaN conditioning fails). Sets the poses that are not ok to NaN, in place."""
    ok = np.empty(cond.shape[0], dtype=np.bool_)
    for t in range(cond.shape[0]):
        good = cond[t] >= min_conditioning
        for j in range(3):
            good = good and math.isfinite(poses[t, j])
        ok[t] = good
        if not good:
            poses[t, 0] = math.nan
            poses[t, 1] = math.nan
            poses[t, 2] = math.nan
    return ok


@numba.njit(cache=True, error_model="numpy")
def solve_triples(
    observed_xy: NDArray[np.float64], bearings: NDArray[np.float64], triples: NDArray[np.int64], min_conditioning: float
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]:
    """Cassini solutions of the given triples of one frame (compiled; callable from other kernels).

    Args:
        observed_xy: ``(n, 2)`` positions of the observed landmarks; bearings: ``(n,)`` theirs.
        triples: ``(T, 3)`` indices into them (:func:`triple_indices`).
        min_conditioning: see :func:`cassini_resection`.

    Returns:
        ``poses (T, 3)`` (NaN where not ok), ``ok (T,)``, conditioning and RMS distance ``(T,)``.
    """
    count = triples.shape[0]
    lm = np.empty((count, 3, 2))
    b = np.empty((count, 3))
    for t in range(count):
        for j in range(3):
            k = triples[t, j]
            lm[t, j, 0] = observed_xy[k, 0]
            lm[t, j, 1] = observed_xy[k, 1]
            b[t, j] = bearings[k]
    poses, cond, d_rms = _cassini_kernel(lm, b, _PIVOT_ORDER, RESIDUAL_TOL_RAD)
    ok = _accept(poses, cond, min_conditioning)
    return poses, ok, cond, d_rms


@functools.lru_cache(maxsize=32)
def triple_indices(n: int) -> NDArray[np.int64]:
    """``(C(n, 3), 3)`` index triples, read-only and cached per landmark count."""
    out = np.array(list(combinations(range(n), 3)), dtype=np.int64)
    out.setflags(write=False)
    return out


@numba.njit(cache=True, inline="always")
def sum_sq_xy(cof: NDArray[np.float64]) -> float:
    """Sum of squares of the x and y components of three vectors ``(3, 3)`` (``||adj[:2, :]||_F^2``)."""
    total = 0.0
    for j in range(3):
        total += cof[j, 0] * cof[j, 0] + cof[j, 1] * cof[j, 1]
    return total


def cassini_resection(
    landmarks_xy: ArrayLike, bearings_rad: ArrayLike, min_conditioning: float = DEFAULT_MIN_CONDITIONING
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """Cassini's three-point resection, vectorized over leading axes.

    Args:
        landmarks_xy: ``(..., 3, 2)`` world positions of the three landmarks.
        bearings_rad: ``(..., 3)`` robot-frame bearings to them.
        min_conditioning: smallest accepted conditioning ``c`` (module docstring), > 0.

    Returns:
        ``poses (..., 3)`` as ``(x, y, theta)`` with theta in ``[-pi, pi)``, NaN where not ok;
        ``ok (...,)`` False near the danger circle, for degenerate geometry (robot on the
        line of collinear landmarks, on a landmark) or inconsistent bearings.
    """
    lm = np.asarray(landmarks_xy, dtype=np.float64)
    b = np.asarray(bearings_rad, dtype=np.float64)
    if lm.shape[-2:] != (3, 2) or b.shape[-1:] != (3,) or lm.shape[:-2] != b.shape[:-1]:
        raise ValueError(
            f"cassini_resection: need landmarks_xy (..., 3, 2) and bearings_rad (..., 3), got {lm.shape} and {b.shape}"
        )
    if not min_conditioning > 0.0:
        raise ValueError(f"cassini_resection: min_conditioning must be > 0, got {min_conditioning!r}")
    poses, cond, _ = _cassini(lm, b)
    ok = _accept(poses.reshape(-1, 3), cond.reshape(-1), min_conditioning).reshape(cond.shape)[()]  # NaN-ed in place
    return poses, ok


def inscribed_arc_poses(
    l1_xy: ArrayLike, l2_xy: ArrayLike, bearing1_rad: float, bearing2_rad: float, n: int
) -> NDArray[np.float64]:
    """Poses from which L1 and L2 appear at the given bearings (inscribed-angle arc).

    The chord L1L2 subtends ``psi = wrap(bearing2 - bearing1)``; the positions seeing it
    under that directed angle form one circular arc (on the left of L1->L2 for psi > 0, on
    the right for psi < 0). Its circle has centre ``m + cot(psi)/2 J (L2 - L1)`` (m the
    chord midpoint) and the arc spans ``2 pi - 2 |psi|`` of it. Heading:
    ``theta = atan2(L1 - p) - bearing1`` (candidate-set paper, sec. 2).

    Args:
        l1_xy, l2_xy: ``(2,)`` landmark positions.
        bearing1_rad, bearing2_rad: their robot-frame bearings.
        n: number of positions, evenly spaced along the arc, endpoints L1 and L2 excluded.

    Returns:
        ``(n, 3)`` poses. All NaN when the arc degenerates (|sin psi| < 1e-9: the robot is
        on the line through L1, L2) or the landmarks coincide.
    """
    if n < 1:
        raise ValueError(f"inscribed_arc_poses: n must be >= 1, got {n!r}")
    a = np.asarray(l1_xy, dtype=np.float64).reshape(2)
    b = np.asarray(l2_xy, dtype=np.float64).reshape(2)
    return _arc_kernel(float(a[0]), float(a[1]), float(b[0]), float(b[1]), float(bearing1_rad), float(bearing2_rad), int(n))


@numba.njit(cache=True, error_model="numpy")
def _arc_kernel(ax: float, ay: float, bx: float, by: float, bearing1: float, bearing2: float, n: int) -> NDArray[np.float64]:
    """:func:`inscribed_arc_poses` for checked arguments (compiled: candidate sets oversample arcs 8x)."""
    out = np.empty((n, 3))
    psi = wrap_scalar(bearing2 - bearing1)
    chord_x = bx - ax
    chord_y = by - ay
    length = math.hypot(chord_x, chord_y)
    if abs(math.sin(psi)) < 1e-9 or length == 0.0:
        out[:, :] = math.nan
        return out
    # centre m + cot(psi)/2 J (L2 - L1), with J (x, y) = (-y, x)
    half_cot = 0.5 / math.tan(psi)
    cx = 0.5 * (ax + bx) + half_cot * -chord_y
    cy = 0.5 * (ay + by) + half_cot * chord_x
    radius = 0.5 * length / abs(math.sin(psi))
    start = math.atan2(by - cy, bx - cx)
    # From L2 the arc runs counter-clockwise to L1 for psi > 0, clockwise for psi < 0.
    sweep = math.copysign(2.0 * math.pi - 2.0 * abs(psi), psi)
    for i in range(n):
        ang = start + sweep * (i + 1) / (n + 1)
        px = cx + radius * math.cos(ang)
        py = cy + radius * math.sin(ang)
        out[i, 0] = px
        out[i, 1] = py
        out[i, 2] = wrap_scalar(math.atan2(ay - py, ax - px) - bearing1)
    return out


@dataclass(frozen=True)
class TripleResection:
    """All Cassini triple solutions of one frame and their robust combination.

    Attributes:
        triples: ``(T, 3)`` landmark ids of each triple (T = C(n, 3)).
        poses: ``(T, 3)`` triple solutions, NaN where not ok.
        ok: ``(T,)`` whether each triple is well conditioned.
        sensitivity_m_per_rad: ``(T,)`` linearized RMS position error per radian of
            independent bearing noise (``d_rms / c``), NaN where not ok.
        inliers: ``(T,)`` ok solutions within the inlier radius of the combined position.
        pose: ``(3,)`` combined pose (NaN when ``valid`` is False).
        valid: whether at least one inlier exists.
    """

    triples: NDArray[np.int64]
    poses: NDArray[np.float64]
    ok: NDArray[np.bool_]
    sensitivity_m_per_rad: NDArray[np.float64]
    inliers: NDArray[np.bool_]
    pose: NDArray[np.float64]
    valid: bool


def resect_all_triples(
    landmarks_xy: ArrayLike,
    ids: ArrayLike,
    bearings: ArrayLike,
    *,
    min_conditioning: float = DEFAULT_MIN_CONDITIONING,
    inlier_radius_m: float = 0.5,
) -> TripleResection:
    """Solve every triple of the observed landmarks and combine the solutions robustly.

    Position: coordinate-wise median of the ok solutions; inliers: ok solutions within
    ``inlier_radius_m`` of it; heading: circular mean of the inliers' headings. No inlier
    (e.g. two ok solutions far apart) means no combined pose.

    Args:
        landmarks_xy: ``(L, 2)`` map positions.
        ids: ``(n,)`` observed landmark ids (indices into ``landmarks_xy``).
        bearings: ``(n,)`` their bearings.
        min_conditioning: see :func:`cassini_resection`.
        inlier_radius_m: gate around the median position.

    Returns:
        A :class:`TripleResection` (empty arrays and ``valid=False`` when n < 3).
    """
    lm = np.asarray(landmarks_xy, dtype=np.float64)
    idx = np.asarray(ids, dtype=np.int64).reshape(-1)
    b = np.asarray(bearings, dtype=np.float64).reshape(-1)
    if idx.shape != b.shape:
        raise ValueError(f"resect_all_triples: ids and bearings must have equal length, got {idx.shape} and {b.shape}")
    if idx.size < 3:
        return TripleResection(
            np.zeros((0, 3), np.int64), np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0), np.zeros(0, bool),
            np.full(3, np.nan), False,
        )  # fmt: skip
    local = triple_indices(idx.size)  # (T, 3)
    poses, ok, cond, d_rms = solve_triples(lm[idx], b, local, min_conditioning)  # (numpy indexing checks the ids)
    with np.errstate(all="ignore"):
        sens = np.where(ok, d_rms / cond, np.nan)
    inliers = np.zeros(ok.shape, dtype=bool)
    pose = np.full(3, np.nan)
    if ok.any():
        centre = np.median(poses[ok, :2], axis=0)
        inliers = ok & (np.hypot(poses[:, 0] - centre[0], poses[:, 1] - centre[1]) <= inlier_radius_m)
        if inliers.any():
            pose = np.array([centre[0], centre[1], float(circular_mean(poses[inliers, 2]))])
    return TripleResection(idx[local], poses, ok, sens, inliers, pose, bool(inliers.any()))


def fix_covariance(res: TripleResection, bearing_std_rad: float) -> NDArray[np.float64]:
    """``(3, 3)`` covariance of a valid combined fix: the sample covariance of the inlier triple
    solutions (heading deviations about the circular mean), each diagonal entry floored by the
    linearized noise of the best inlier triple: position variance ``(bearing_std_rad *
    sensitivity)^2 / 2`` per axis, heading variance ``bearing_std_rad^2``."""
    if not res.valid:
        raise ValueError("fix_covariance: the resection has no valid combined pose")
    inl = res.poses[res.inliers]
    cov = np.zeros((3, 3))
    if inl.shape[0] >= 2:
        dev = np.column_stack([inl[:, :2] - res.pose[:2], wrap_angle(inl[:, 2] - res.pose[2])])
        cov = dev.T @ dev / (inl.shape[0] - 1)
    sens = float(np.nanmin(res.sensitivity_m_per_rad[res.inliers]))
    floor = np.array([0.5 * (bearing_std_rad * sens) ** 2] * 2 + [bearing_std_rad**2])
    cov[np.diag_indices(3)] = np.maximum(np.diag(cov), floor)
    return cov


@dataclass(frozen=True)
class ResectionParams:
    """Parameters of baseline (2) (defaults: ``configs/localizers/resection.yaml``).

    Attributes:
        min_conditioning: smallest accepted Cassini conditioning ``c`` (dimensionless; ours).
        inlier_radius_m: triple solutions farther than this from the median position are
            outliers (metres; ours).
        bearing_std_rad: assumed bearing noise for the covariance floor (radians; ours, 1 deg).
        max_spread_m: a fix whose position spread exceeds this (m) is not claimed (ours; near
            the danger circle). The method is single-shot: every ``predict`` drops the
            estimate, so it never claims a stale pose (a kidnapped robot is found again at the
            first frame with a valid fix).
    """

    min_conditioning: float = DEFAULT_MIN_CONDITIONING
    inlier_radius_m: float = 0.5
    bearing_std_rad: float = 0.0175
    max_spread_m: float = DEFAULT_MAX_SPREAD_M

    def __post_init__(self) -> None:
        check_max_spread("ResectionParams", self.max_spread_m)
        check_ranges(self, "ResectionParams", positive=("min_conditioning", "inlier_radius_m", "bearing_std_rad"))


class ResectionLocalizer(LocalizerBase[ResectionParams]):
    """Baseline (2): Cassini resection whenever >= 3 bearings are seen, no output otherwise.

    With more than 3 landmarks every triple is solved and combined by
    :func:`resect_all_triples`. The estimate belongs to the latest update only: ``predict``
    invalidates it (the method has no motion model).

    Covariance: :func:`fix_covariance`; a fix with a position spread over ``max_spread_m``
    is not claimed.
    """

    name: ClassVar[str] = "resection"
    #: measured on this run: share 0.987, NEES median 0.78 (tests/localizers/test_consistency_promises.py)
    consistency: ClassVar[ConsistencyPromise] = ConsistencyPromise("crowdloc/RoboCupCrowded-v0", "random_walk", 400, 0.95)

    def __init__(self, landmarks: LandmarkMap, params: ResectionParams, *, dt_s: float) -> None:
        super().__init__(landmarks, params, dt_s=dt_s, owner="ResectionLocalizer")
        self._started = False
        self._estimate = PoseEstimate.invalid()
        self._last: TripleResection | None = None

    def reset(self, rng: np.random.Generator, prior: PoseEstimate | None = None) -> None:
        """Forget everything. The method is deterministic and needs no prior (both ignored)."""
        del rng, prior
        self._started = True
        self._estimate = PoseEstimate.invalid()
        self._last = None

    def _require_reset(self) -> None:
        require_reset("ResectionLocalizer", self._started)

    def predict(self, odometry: OdometryDelta) -> None:
        """Check the increment and drop the estimate (no motion model in this baseline)."""
        self._require_reset()
        self._checked_odometry(odometry)
        self._estimate = PoseEstimate.invalid()
        self._last = None

    def update(self, measurement: BearingMeasurement) -> None:
        """Resect from this frame's bearings (>= 3 needed, else the estimate is invalid)."""
        self._require_reset()
        m = checked_bearings(self.name, measurement, self._map.count)
        p = self._params
        res = resect_all_triples(
            self._map.positions_xy_m, m.landmark_ids, m.bearings_rad,
            min_conditioning=p.min_conditioning, inlier_radius_m=p.inlier_radius_m,
        )  # fmt: skip
        self._last = res if res.ok.any() else None
        if not res.valid:
            self._estimate = PoseEstimate.invalid()
            return
        cov = fix_covariance(res, p.bearing_std_rad)
        x, y, th = res.pose
        self._estimate = PoseEstimate(float(x), float(y), float(th), cov, within_spread(cov, p.max_spread_m))

    @property
    def estimate(self) -> PoseEstimate:
        e = self._estimate
        return PoseEstimate(e.x_m, e.y_m, e.theta_rad, e.covariance.copy(), e.valid)

    def overlay(self) -> Overlay:
        """The ok triple solutions of the latest update; outliers drawn faint."""
        if self._last is None:
            return Overlay(label="resection: no solution")
        ok = self._last.ok
        weights = np.where(self._last.inliers[ok], 1.0, 0.25)
        return Overlay(poses=self._last.poses[ok].copy(), weights=weights, label="resection")
