"""SE(2) helpers shared by the worlds and the localizers (a leaf module: numpy only).

Poses are ``(x, y, theta)`` in metres and radians. All functions broadcast over leading
axes, so the same call serves one pose, 1000 particles or 3600 candidates.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike, NDArray

TWO_PI = 2.0 * np.pi


def wrap_angle(angle: ArrayLike) -> NDArray[np.float64] | float:
    """Wrap angles to ``[-pi, pi)``.

    Args:
        angle: any array of angles in radians.

    Returns:
        The wrapped angles, same shape (a Python float for a scalar input).
    """
    wrapped = np.mod(np.asarray(angle, dtype=np.float64) + np.pi, TWO_PI) - np.pi
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def circular_std(resultant_length: float) -> float:
    """Circular standard deviation ``sqrt(-2 ln R)`` of angles whose mean resultant length is
    ``R`` (``R`` above 1 by rounding counts as 1; inf for ``R = 0``, angles that cancel out)."""
    r = min(resultant_length, 1.0)
    return math.sqrt(-2.0 * math.log(r)) if r > 0.0 else math.inf


def compose(pose: ArrayLike, delta: ArrayLike) -> NDArray[np.float64]:
    """Apply a motion ``delta`` expressed in the frame of ``pose`` (the SE(2) product).

    Args:
        pose: ``(..., 3)`` world poses.
        delta: ``(..., 3)`` increments ``(dx, dy, dtheta)`` in each pose's own frame.

    Returns:
        ``(..., 3)`` world poses after the motion, heading wrapped to ``[-pi, pi)``.
    """
    p = np.asarray(pose, dtype=np.float64)
    d = np.asarray(delta, dtype=np.float64)
    c, s = np.cos(p[..., 2]), np.sin(p[..., 2])
    out = np.empty(np.broadcast_shapes(p.shape, d.shape), dtype=np.float64)
    out[..., 0] = p[..., 0] + c * d[..., 0] - s * d[..., 1]
    out[..., 1] = p[..., 1] + s * d[..., 0] + c * d[..., 1]
    out[..., 2] = wrap_angle(p[..., 2] + d[..., 2])
    return out


def between(pose_a: ArrayLike, pose_b: ArrayLike) -> NDArray[np.float64]:
    """The increment that takes ``pose_a`` to ``pose_b``, in ``pose_a``'s frame.

    The inverse of :func:`compose`: ``compose(a, between(a, b)) == b``.

    Args:
        pose_a: ``(..., 3)`` start poses.
        pose_b: ``(..., 3)`` end poses.

    Returns:
        ``(..., 3)`` increments ``(dx, dy, dtheta)``.
    """
    a = np.asarray(pose_a, dtype=np.float64)
    b = np.asarray(pose_b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx = b[..., 0] - a[..., 0]
    dy = b[..., 1] - a[..., 1]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape), dtype=np.float64)
    out[..., 0] = c * dx + s * dy
    out[..., 1] = -s * dx + c * dy
    out[..., 2] = wrap_angle(b[..., 2] - a[..., 2])
    return out


def bearings_to(pose: ArrayLike, points_xy: ArrayLike) -> NDArray[np.float64]:
    """Bearings of world points seen from poses, in the robot frame.

    Args:
        pose: ``(..., 3)`` poses.
        points_xy: ``(L, 2)`` world points.

    Returns:
        ``(..., L)`` bearings in ``[-pi, pi)``, counter-clockwise from the heading.
    """
    p = np.asarray(pose, dtype=np.float64)
    q = np.asarray(points_xy, dtype=np.float64)
    dx = q[:, 0] - p[..., 0, None]
    dy = q[:, 1] - p[..., 1, None]
    return np.asarray(wrap_angle(np.arctan2(dy, dx) - p[..., 2, None]))


def circular_mean(angles: ArrayLike, weights: ArrayLike | None = None, axis: int = -1) -> NDArray[np.float64] | float:
    """Weighted circular mean of angles along ``axis``.

    Args:
        angles: angles in radians.
        weights: optional non-negative weights broadcastable to ``angles``.
        axis: the axis to average over.

    Returns:
        The mean direction in ``[-pi, pi)``.
    """
    a = np.asarray(angles, dtype=np.float64)
    w = np.ones_like(a) if weights is None else np.broadcast_to(np.asarray(weights, dtype=np.float64), a.shape)
    mean = np.arctan2(np.sum(w * np.sin(a), axis=axis), np.sum(w * np.cos(a), axis=axis))
    return wrap_angle(mean)


def in_field_of_view(
    origin: NDArray[np.float64], heading: float | NDArray[np.float64], points_xy: NDArray[np.float64], fov_rad: float
) -> NDArray[np.bool_]:
    """Whether each point lies within ``fov_rad / 2`` of the heading as seen from ``origin``.

    ``origin`` ``(..., 2)`` and ``heading`` ``(...)`` broadcast against ``points_xy`` ``(L, 2)``:
    one pose gives ``(L,)``, ``C`` poses (``origin[:, None, :]``, ``heading[:, None]``) give ``(C, L)``.
    """
    offsets = points_xy - origin
    bearing = np.arctan2(offsets[..., 1], offsets[..., 0]) - heading
    return np.abs(wrap_angle(bearing)) <= 0.5 * fov_rad


def spanning(bottom: ArrayLike, top: ArrayLike, height_m: float) -> NDArray[np.bool_]:
    """Which of the height intervals ``[bottom, top)`` contain ``height_m``: the walls, furniture
    and body parts a horizontal plane at that height cuts (a sensor mounted there sees them)."""
    return np.asarray((np.asarray(bottom) <= height_m) & (height_m < np.asarray(top)))


def ring_directions(count: int) -> NDArray[np.float64]:
    """``(count,)`` directions spread evenly around a full turn, from 0 counter-clockwise: the
    layout of a sensor ring (the sonar's cone centres, relative to the heading)."""
    return np.arange(count, dtype=np.float64) * (TWO_PI / count)


def poses_along_step(start: ArrayLike, end: ArrayLike, lag_fractions: ArrayLike) -> NDArray[np.float64]:
    """``(K, 3)`` the poses a robot held ``lag_fractions`` ``(K,)`` of a step before it reached
    ``end`` from ``start`` (0: at ``end``, 1: at ``start``), moving as the simulation moves a body
    within one step: its position along the straight line, its heading along the shorter arc,
    both at a constant rate. The one model of motion within a step: the swept LIDAR takes each
    beam from it (:mod:`envs.sensors.ranging`) and the localizers' ``deskew`` undoes it
    (:func:`deskewed_scan`)."""
    s = np.asarray(start, dtype=np.float64)
    e = np.asarray(end, dtype=np.float64)
    turn = float(wrap_angle(e[2] - s[2]))
    return _along_step(float(s[0]), float(s[1]), float(e[0]), float(e[1]), float(e[2]), turn,
                       np.asarray(lag_fractions, dtype=np.float64))  # fmt: skip


@numba.njit(cache=True)
def _along_step(
    sx: float, sy: float, ex: float, ey: float, eth: float, turn: float, f: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The loop of :func:`poses_along_step` (one pass, as the swept LIDAR calls it every step)."""
    out = np.empty((f.shape[0], 3), dtype=np.float64)
    dx, dy = ex - sx, ey - sy
    for k in range(f.shape[0]):
        out[k, 0] = ex - f[k] * dx
        out[k, 1] = ey - f[k] * dy
        out[k, 2] = eth - f[k] * turn
    return out


def deskewed_scan(
    ranges: ArrayLike, angles: ArrayLike, max_range: float, delta: ArrayLike, lag_fractions: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """A swept scan as if every beam had been taken at the end of the step: ``(ranges, angles)``.

    Beam ``k`` (``ranges[k]`` along ``angles[k]``, robot frame) was taken ``lag_fractions[k]`` of
    the step before its end, from the pose :func:`poses_along_step` gives for the step's motion
    ``delta`` (``(dx, dy, dtheta)`` in the frame of the step's start: the odometry increment; a
    constant velocity across the step is assumed). Each hit is moved to the frame of the step's
    end pose and given as the range and direction from there (clipped to ``max_range``); a beam
    that hit nothing keeps ``max_range`` and is turned by the heading it lagged. The angles no
    longer ascend in general (the likelihood models do not need them to).
    """
    r = np.asarray(ranges, dtype=np.float64)
    a = np.asarray(angles, dtype=np.float64)
    d = np.asarray(delta, dtype=np.float64)
    beam = between(d, poses_along_step(np.zeros(3), d, lag_fractions))  # each beam's pose in the end frame
    direction = a + beam[:, 2]
    px = beam[:, 0] + r * np.cos(direction)
    py = beam[:, 1] + r * np.sin(direction)
    hit = r < max_range
    out_r = np.where(hit, np.minimum(np.hypot(px, py), max_range), max_range)
    out_a = np.where(hit, np.arctan2(py, px), direction)
    return out_r, out_a


def polyline_distance(points_xy: ArrayLike, vertices_xy: ArrayLike, *, closed: bool) -> NDArray[np.float64]:
    """``(...)`` the distance from each point ``(..., 2)`` to the polyline through ``vertices_xy``
    ``(V, 2)`` (with the segment from the last vertex back to the first when ``closed``): the
    least over its segments of the distance to the segment's nearest point, found by the
    projection onto the segment's line clipped to its ends (a zero-length segment: its point).
    A NaN point gives NaN. The candidate-set paper scored Exp 1 this way: the distance from each
    estimate to the path drawn on the floor (``agents.papers.bearing_candidates``).
    """
    p = np.asarray(points_xy, dtype=np.float64)[..., None, :]  # (..., 1, 2)
    a = np.asarray(vertices_xy, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 2 or a.shape[0] < 1:
        raise ValueError(f"polyline_distance: vertices_xy must be (V >= 1, 2), got shape {a.shape}")
    b = np.roll(a, -1, axis=0) if closed else a[1:]
    a = a if closed else a[:-1]
    if a.shape[0] == 0:  # one vertex, open: the point itself
        a = b = np.asarray(vertices_xy, dtype=np.float64)
    edge = b - a  # (S, 2)
    length2 = np.einsum("sk,sk->s", edge, edge)
    t = np.einsum("...sk,sk->...s", p - a, edge) / np.where(length2 > 0.0, length2, 1.0)
    nearest = a + np.clip(t, 0.0, 1.0)[..., None] * edge  # (..., S, 2)
    d = np.hypot(p[..., 0] - nearest[..., 0], p[..., 1] - nearest[..., 1])
    return np.asarray(np.min(d, axis=-1), dtype=np.float64)


def polyline_point(vertices_xy: NDArray[np.float64], arc_m: NDArray[np.float64], s_m: float) -> NDArray[np.float64]:
    """``(2,)`` the point at arc length ``s_m`` along the polyline through ``vertices_xy`` ``(V >= 2, 2)``,
    whose vertices lie at the arc lengths ``arc_m`` ``(V,)`` (0 first, non-decreasing), clamped to its
    ends; on a zero-length segment, its vertex. The one walk along a route: ``route_follower``'s
    pure-pursuit point and a task's look-ahead point (``agents.rl.observation``)."""
    s = min(max(float(s_m), 0.0), float(arc_m[-1]))
    k = int(np.clip(np.searchsorted(arc_m, s, side="right") - 1, 0, vertices_xy.shape[0] - 2))
    length = arc_m[k + 1] - arc_m[k]
    t = (s - arc_m[k]) / length if length > 0.0 else 0.0
    return np.asarray(vertices_xy[k] + t * (vertices_xy[k + 1] - vertices_xy[k]), dtype=np.float64)


def undistort(xd: NDArray[np.float64], yd: NDArray[np.float64], k1: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Invert the radial lens model ``x_d = x_u (1 + k1 r_u^2)`` (normalized coordinates) by
    fixed-point iteration: the camera's renderer and the pipeline share this one inverse."""
    xu, yu = np.array(xd, dtype=np.float64), np.array(yd, dtype=np.float64)
    for _ in range(20):
        scale = 1.0 + k1 * (xu * xu + yu * yu)
        xu, yu = xd / scale, yd / scale
    return xu, yu
