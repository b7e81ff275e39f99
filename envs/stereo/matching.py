"""The stereo paper's rig side (paper D): the three cameras' edges matched, then triangulated.

1. :func:`match_trinocular`: left/right pairs of one edge type, each confirmed by the middle camera;
2. :func:`triangulate`, :func:`paper_range_bearing`: the paper's eqs. (2)-(5);
   :func:`rig_range_bearing`: the same point in the robot frame, in crowdloc's convention
   (the one place the paper's bearing convention is converted);
3. :class:`TrinocularRig` bundles the rig's numbers.

The edges come from :mod:`envs.stereo.edges` (whose pixel convention holds here);
:mod:`envs.stereo.vision` gathers both.

**Frames.** The paper's stereo frame has its origin at the LEFT camera, ``x`` to the right
and ``y`` forward; its bearing ``theta = atan(x / y)`` is measured from the forward axis,
positive to the right. crowdloc's robot frame has ``x`` forward and ``y`` to the left, with
bearings counter-clockwise from the heading (left positive). Only
:func:`rig_range_bearing` converts between the two.

**Errors.** As in :mod:`envs.stereo.edges`: ValueError naming a bad argument,
:class:`~localizers.base.MeasurementError` a malformed edge list,
:class:`~core.schema.ConfigError` a bad :class:`TrinocularRig`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, NamedTuple

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

from core.geometry import wrap_angle
from core.schema import check, is_real
from envs.stereo.edges import EdgeList, check_edges, finite_array, shown

# ---------------------------------------------------------------------------------------
# Trinocular matching
# ---------------------------------------------------------------------------------------


class Matches(NamedTuple):
    """Edges matched in the three cameras, sorted by ``(type, u_left)``.

    Attributes:
        u_left, u_middle, u_right: ``(M,)`` float64 the edge's column in each camera.
        type: ``(M,)`` int64 edge type.
        strength: ``(M,)`` float32 the least of the three edges' strengths.
    """

    u_left: NDArray[np.float64]
    u_middle: NDArray[np.float64]
    u_right: NDArray[np.float64]
    type: NDArray[np.int64]
    strength: NDArray[np.float32]


def empty_matches() -> Matches:
    """:class:`Matches` without matches."""
    e = np.empty(0, np.float64)
    return Matches(e, e.copy(), e.copy(), np.empty(0, np.int64), np.empty(0, np.float32))


def _positive(value: Any, name: str) -> float:
    if not is_real(value):
        raise ValueError(f"{name} must be a number, got {shown(value)!r}")
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {shown(value)!r}")
    return float(value)


def _finite(value: Any, name: str) -> float:
    if not is_real(value, finite=True):
        raise ValueError(f"{name} must be a finite number, got {shown(value)!r}")
    return float(value)


@numba.njit(cache=True)
def _lower_bound(a: NDArray[np.float64], lo: int, hi: int, x: float) -> int:
    """The first index in ``lo:hi`` of the sorted ``a`` with ``a[i] >= x`` (``hi`` if none)."""
    while lo < hi:
        mid = (lo + hi) // 2
        if a[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    return lo


@numba.njit(cache=True)
def _type_starts(t: NDArray[np.int64]) -> NDArray[np.int64]:
    """``starts[k]:starts[k + 1]`` is the slice of type ``k`` in the type-sorted ``t``."""
    starts = np.empty(31, dtype=np.int64)
    i = 0
    for k in range(31):
        while i < t.shape[0] and t[i] < k:
            i += 1
        starts[k] = i
    return starts


@numba.njit(cache=True)
def _candidates(
    tl: NDArray[np.int64], ul: NDArray[np.float64], tm: NDArray[np.int64], um: NDArray[np.float64],
    tr: NDArray[np.int64], ur: NDArray[np.float64], d_min: float, d_max: float, tol: float,
    fill: bool, res: NDArray[np.float64], idx: NDArray[np.int64],
) -> int:  # fmt: skip
    """Every (left, right, middle) triple of one type whose disparity is in the window and whose
    middle edge is within ``tol`` of the pair's midpoint; all counted, and written when ``fill``
    as long as ``res`` has room."""
    sl, sm, sr = _type_starts(tl), _type_starts(tm), _type_starts(tr)
    n = 0
    for t in range(30):
        if sl[t] == sl[t + 1] or sm[t] == sm[t + 1] or sr[t] == sr[t + 1]:
            continue
        for i in range(sl[t], sl[t + 1]):
            j = _lower_bound(ur, sr[t], sr[t + 1], ul[i] - d_max)
            while j < sr[t + 1] and ur[j] <= ul[i] - d_min:
                mid = 0.5 * (ul[i] + ur[j])
                k = _lower_bound(um, sm[t], sm[t + 1], mid - tol)
                while k < sm[t + 1] and um[k] <= mid + tol:
                    if fill and n < res.shape[0]:
                        res[n] = abs(um[k] - mid)
                        idx[3 * n] = i
                        idx[3 * n + 1] = j
                        idx[3 * n + 2] = k
                    n += 1
                    k += 1
                j += 1
    return n


@numba.njit(cache=True)
def _greedy(res: NDArray[np.float64], idx: NDArray[np.int64], nl: int, nm: int, nr: int) -> NDArray[np.bool_]:
    """Accept candidates by increasing residual (ties: in generation order), each edge at most once."""
    order = np.argsort(res, kind="mergesort")
    used_l = np.zeros(nl, dtype=np.bool_)
    used_m = np.zeros(nm, dtype=np.bool_)
    used_r = np.zeros(nr, dtype=np.bool_)
    keep = np.zeros(res.shape[0], dtype=np.bool_)
    for q in order:
        i, j, k = idx[3 * q], idx[3 * q + 1], idx[3 * q + 2]
        if used_l[i] or used_r[j] or used_m[k]:
            continue
        used_l[i] = True
        used_r[j] = True
        used_m[k] = True
        keep[q] = True
    return keep


def disparity_window(focal_px: float, baseline_m: float, min_range_m: float, max_range_m: float) -> tuple[float, float]:
    """``(d_min, d_max)``: the outer pair's disparities ``2 f b / max_range .. 2 f b / min_range`` (px).

    ``baseline_m`` is the NEIGHBOUR baseline (the outer pair's is twice it); the ranges are
    depths (forward distances from the rig), which is what a disparity measures.
    """
    f = _positive(focal_px, "focal_px")
    b = _positive(baseline_m, "baseline_m")
    r_min = _positive(min_range_m, "min_range_m")
    r_max = _positive(max_range_m, "max_range_m")
    if r_min >= r_max:
        raise ValueError(f"min_range_m must be below max_range_m, got {shown(min_range_m)!r} >= {shown(max_range_m)!r}")
    return 2.0 * f * b / r_max, 2.0 * f * b / r_min


def match_trinocular(
    left: EdgeList,
    middle: EdgeList,
    right: EdgeList,
    focal_px: float,
    baseline_m: float,
    min_range_m: float,
    max_range_m: float,
    tolerance_px: float,
) -> Matches:
    """Edges seen by all three cameras of the rig, matched by type and confirmed by the middle camera.

    A left and a right edge of one type pair up when their disparity ``d = uL - uR`` lies in
    ``[2 f b / max_range, 2 f b / min_range]`` (:func:`disparity_window`); the middle camera
    confirms the pair when it has an edge of that type within ``tolerance_px`` of
    ``(uL + uR) / 2`` (where the point appears in it for rectified, parallel, identical
    cameras equally spaced). Conflicts are resolved greedily by the smallest middle
    residual (ties in the order of type, left, right and middle edge): each edge of each
    camera is used at most once.

    Note that equal spacing leaves one ambiguity the middle camera cannot resolve: in a
    pattern of period ``p`` (in px) the pairs shifted by ``2 p`` also meet at a middle edge;
    only the disparity window tells them apart.

    Args:
        left, middle, right: each camera's :class:`EdgeList`.
        focal_px: the cameras' focal length (px), > 0.
        baseline_m: the NEIGHBOUR baseline (0.19 m in the paper), > 0.
        min_range_m, max_range_m: the depth window (m), ``0 < min < max < inf``.
        tolerance_px: the largest middle residual (px), > 0.

    Returns:
        :class:`Matches`, sorted by ``(type, u_left)``.
    """
    d_min, d_max = disparity_window(focal_px, baseline_m, min_range_m, max_range_m)
    tol = _positive(tolerance_px, "tolerance_px")
    el = check_edges(left, "match_trinocular: left")
    em = check_edges(middle, "match_trinocular: middle")
    er = check_edges(right, "match_trinocular: right")
    return match_checked(el, em, er, d_min, d_max, tol)


def match_checked(el: EdgeList, em: EdgeList, er: EdgeList, d_min: float, d_max: float, tol: float) -> Matches:
    """:func:`match_trinocular` on lists already checked and sorted by ``(type, u)`` (:func:`check_edges`)
    with the disparity window ``[d_min, d_max]`` (:func:`disparity_window`) and a positive ``tol``:
    for callers whose lists come from this module's kernels or the simulator's, every step."""
    if el.u.size == 0 or em.u.size == 0 or er.u.size == 0:
        return empty_matches()
    args = (el.type, el.u, em.type, em.u, er.type, er.u, d_min, d_max, tol)
    cap = 4 * (el.u.size + er.u.size) + 64
    res = np.empty(cap, np.float64)
    idx = np.empty(3 * cap, np.int64)
    n = _candidates(*args, True, res, idx)
    if n == 0:
        return empty_matches()
    if n > cap:  # more candidates than the first guess: count them all, again
        res = np.empty(n, np.float64)
        idx = np.empty(3 * n, np.int64)
        _candidates(*args, True, res, idx)
    res, idx = res[:n], idx[: 3 * n]
    keep = _greedy(res, idx, el.u.size, em.u.size, er.u.size)
    triples = idx.reshape(n, 3)[keep]  # in generation order: by (type, left edge)
    i, j, k = triples[:, 0], triples[:, 1], triples[:, 2]
    strength = np.minimum(np.minimum(el.strength[i], em.strength[k]), er.strength[j])
    return Matches(el.u[i], em.u[k], er.u[j], el.type[i], strength.astype(np.float32))


# ---------------------------------------------------------------------------------------
# Triangulation: the paper's eqs. (2)-(5)
# ---------------------------------------------------------------------------------------


def triangulate(
    u_left: ArrayLike, u_right: ArrayLike, focal_px: float, baseline_m: float, cx_px: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The point seen at ``u_left`` and ``u_right`` in the paper's stereo frame, eqs. (2)-(3).

    Args:
        u_left, u_right: the point's columns in the two cameras (broadcast).
        focal_px: focal length (px), > 0.
        baseline_m: the baseline between THESE two cameras (the outer pair: 2 x 0.19 m), > 0.
        cx_px: the principal point's column (``ox``; ``W / 2`` for a centred axis).

    Returns:
        ``(x, y)`` float64 arrays of the broadcast shape: origin at the left camera, ``x`` to
        the right, ``y`` forward (m).

    Raises:
        ValueError: a non-positive disparity ``u_left - u_right``, naming it; a non-finite column.
    """
    ul = finite_array(u_left, "triangulate: u_left")
    ur = finite_array(u_right, "triangulate: u_right")
    f = _positive(focal_px, "triangulate: focal_px")
    b = _positive(baseline_m, "triangulate: baseline_m")
    ox = _finite(cx_px, "triangulate: cx_px")
    d = ul - ur
    if (d <= 0).any():
        raise ValueError(
            f"triangulate: the disparity u_left - u_right must be > 0, got {shown(np.asarray(d)[d <= 0].ravel()[0])!r}"
        )
    x = b * (ul - ox) / d  # eq. (2)
    y = f * b / d  # eq. (3)
    return x, y


def paper_range_bearing(x: ArrayLike, y: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Range and bearing of stereo-frame points, eqs. (4)-(5), in the PAPER's convention.

    ``r = sqrt(x^2 + y^2)`` (eq. (4)); ``theta = atan(x / y)`` (eq. (5)): from the forward
    (``y``) axis, positive to the right (computed as ``atan2(x, y)``, equal for ``y > 0``).
    """
    xa = np.asarray(x, dtype=np.float64)
    ya = np.asarray(y, dtype=np.float64)
    return np.hypot(xa, ya), np.arctan2(xa, ya)  # eqs. (4), (5)


def rig_range_bearing(
    u_left: ArrayLike,
    u_right: ArrayLike,
    focal_px: float,
    neighbour_baseline_m: float,
    cx_px: float,
    rig_forward_m: float = 0.0,
    rig_left_m: float = 0.0,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The point seen by the outer cameras, as range and bearing from the ROBOT centre (crowdloc's convention).

    The rig's middle camera sits ``rig_forward_m`` ahead of the robot centre and
    ``rig_left_m`` to its left; the left camera ``neighbour_baseline_m`` to the left of the
    middle one and the right camera as far to its right. The point is triangulated with the
    outer pair (baseline ``2 neighbour_baseline_m``, :func:`triangulate`) and converted here,
    the only place, from the paper's frame (``x`` right, ``y`` forward, bearings positive to
    the right) to the robot's (forward, left; bearings counter-clockwise from the heading).

    Returns:
        ``(range_m, bearing_rad)`` float64 arrays of the broadcast shape; bearings in ``[-pi, pi)``.
    """
    b = _positive(neighbour_baseline_m, "rig_range_bearing: neighbour_baseline_m")
    fwd = _finite(rig_forward_m, "rig_range_bearing: rig_forward_m")
    lft = _finite(rig_left_m, "rig_range_bearing: rig_left_m")
    x, y = triangulate(u_left, u_right, focal_px, 2.0 * b, cx_px)
    forward = fwd + y  # the left camera is at (fwd, lft + b) in the robot frame
    left = lft + b - x  # the paper's x points right: the robot's -left
    return np.hypot(forward, left), np.asarray(wrap_angle(np.arctan2(left, forward)), dtype=np.float64)


def range_std_m(range_m: ArrayLike, focal_px: float, baseline_m: float, disparity_std_px: float) -> NDArray[np.float64]:
    """First-order range sd ``r^2 sigma_d / (f b)`` of a triangulated point.

    ``baseline_m`` is the triangulation's (the outer pair: 2 x 0.19 m). The formula is the
    depth's sd (``y = f b / d``) exactly to first order; for the range it holds on the left
    camera's axis (the paper's case) and is the depth's value elsewhere.
    """
    r = finite_array(range_m, "range_std_m: range_m")
    f = _positive(focal_px, "range_std_m: focal_px")
    b = _positive(baseline_m, "range_std_m: baseline_m")
    sd = _positive(disparity_std_px, "range_std_m: disparity_std_px")
    return r * r * sd / (f * b)


def inverse_range_std(focal_px: float, baseline_m: float, disparity_std_px: float) -> float:
    """The sd of ``1 / r``: ``sigma_d / (f b)``, the same at every range (1/r is linear in d)."""
    f = _positive(focal_px, "inverse_range_std: focal_px")
    b = _positive(baseline_m, "inverse_range_std: baseline_m")
    return _positive(disparity_std_px, "inverse_range_std: disparity_std_px") / (f * b)


# ---------------------------------------------------------------------------------------
# The rig
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class TrinocularRig:
    """The three-camera rig: identical, rectified, parallel cameras ``neighbour_baseline_m`` apart.

    ``rig_forward_m``, ``rig_left_m``: the middle camera's place in the robot frame;
    ``min_range_m``, ``max_range_m``, ``tolerance_px``: the matching window
    (:func:`match_trinocular`).
    """

    focal_px: float
    cx_px: float
    neighbour_baseline_m: float = 0.19
    min_range_m: float = 1.0
    max_range_m: float = 50.0
    tolerance_px: float = 1.0
    rig_forward_m: float = 0.0
    rig_left_m: float = 0.0

    def __post_init__(self) -> None:
        for name in ("focal_px", "neighbour_baseline_m", "min_range_m", "max_range_m", "tolerance_px"):
            value = getattr(self, name)
            check(
                is_real(value, finite=True) and value > 0,
                f"TrinocularRig.{name} must be finite and > 0, got {shown(value)!r}",
            )
        for name in ("cx_px", "rig_forward_m", "rig_left_m"):
            value = getattr(self, name)
            check(
                is_real(value, finite=True),
                f"TrinocularRig.{name} must be finite, got {shown(value)!r}",
            )
        check(
            self.min_range_m < self.max_range_m,
            f"TrinocularRig.min_range_m must be below max_range_m, got {self.min_range_m} >= {self.max_range_m}",
        )

    def match(self, left: EdgeList, middle: EdgeList, right: EdgeList) -> Matches:
        """:func:`match_trinocular` with this rig's numbers."""
        return match_trinocular(
            left, middle, right, self.focal_px, self.neighbour_baseline_m, self.min_range_m, self.max_range_m, self.tolerance_px
        )

    def range_bearing(self, matches: Matches) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(range_m, bearing_rad)`` ``(M,)`` of matches from the robot centre (:func:`rig_range_bearing`)."""
        return rig_range_bearing(
            matches.u_left,
            matches.u_right,
            self.focal_px,
            self.neighbour_baseline_m,
            self.cx_px,
            self.rig_forward_m,
            self.rig_left_m,
        )
