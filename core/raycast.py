"""Vectorized 2-D ray casting against segments and circles (a leaf module; the sensing hot path).

Geometry comes in as plain arrays so that the same kernels serve the simulated sensors
(``envs.sensors``) and the static-map range tables of the LIDAR localizer:

- segments: ``seg_a``, ``seg_b`` of shape ``(S, 2)`` (end points);
- circles: ``centres`` ``(C, 2)`` and ``radii`` ``(C,)``.

The kernels are compiled with numba (cached on disk after the first call). Each has a
pure-numpy twin in the tests that checks it against closed-form distances.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

_EPS = 1e-12


@numba.njit(cache=True, inline="always")
def _ray_segment(ox: float, oy: float, dx: float, dy: float, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance along the unit ray (o, d) to segment ab, or inf."""
    ex = bx - ax
    ey = by - ay
    denom = dx * ey - dy * ex
    if abs(denom) < _EPS:
        return math.inf
    wx = ax - ox
    wy = ay - oy
    t = (wx * ey - wy * ex) / denom
    u = (wx * dy - wy * dx) / denom
    if t >= 0.0 and 0.0 <= u <= 1.0:
        return t
    return math.inf


@numba.njit(cache=True, inline="always")
def _ray_circle(ox: float, oy: float, dx: float, dy: float, cx: float, cy: float, r: float) -> float:
    """Distance along the unit ray (o, d) to the first crossing of a circle, or inf.

    A ray starting inside the circle hits it at distance 0 (the sensor is blinded).
    """
    wx = cx - ox
    wy = cy - oy
    proj = wx * dx + wy * dy
    dist2 = wx * wx + wy * wy
    r2 = r * r
    if dist2 <= r2:
        return 0.0
    if proj <= 0.0:
        return math.inf
    h2 = r2 - (dist2 - proj * proj)
    if h2 < 0.0:
        return math.inf
    return proj - math.sqrt(h2)


@numba.njit(cache=True, inline="always")
def _beam_spans(rel_angles: NDArray[np.float64], rel: float, half: float) -> NDArray[np.int64]:
    """``(3, 2)`` index ranges ``[lo, hi)`` of the beams within ``half`` of the direction ``rel``
    (radians past the first beam, in ``[0, 2 pi)``): the interval itself, and a turn lower and
    higher (an interval straddling the first beam shows up a turn lower, i.e. the beams just
    after it, and one a turn higher, the last beams of a full-turn scan). Widened by 1e-9 rad:
    an extra beam costs one exact test, a missed one a wrong range."""
    out = np.empty((3, 2), dtype=np.int64)
    two_pi = 2.0 * math.pi
    for k in range(3):
        centre = rel + (k - 1) * two_pi
        out[k, 0] = np.searchsorted(rel_angles, centre - half - 1e-9)
        out[k, 1] = np.searchsorted(rel_angles, centre + half + 1e-9, side="right")
    return out


@numba.njit(cache=True, inline="always")
def _cast(
    origins: NDArray[np.float64],
    per_ray: bool,
    angles: NDArray[np.float64],
    max_range: float,
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> NDArray[np.float64]:
    """The kernel of :func:`cast_rays` (``per_ray`` False: every ray from ``origins[0]``) and
    :func:`cast_rays_from` (``per_ray`` True: ray ``i`` from ``origins[i]``). Inlined into both
    with ``per_ray`` a constant, so that each compiles to its own loop.

    Culling: every segment and circle covers an angular interval seen from a centre ``c``;
    only the beams inside it are tested. With one origin ``c`` is that origin (the interval is
    exact). With per-ray origins ``c`` is the middle of their bounding box and ``rho`` the
    farthest origin from it: a point ``p`` at least ``g > rho`` from ``c`` is seen from any origin
    within ``asin(rho / g)`` of its direction from ``c``, so each interval is widened by that;
    an obstacle within ``rho`` of ``c`` is tested against every beam, and so is everything when
    the beam directions do not ascend or span 3 pi or more (the interval search needs them sorted,
    and finds a direction's copies a turn lower and higher only).
    """
    n = angles.shape[0]
    out = np.full(n, max_range)
    if n == 0:
        return out
    two_pi = 2.0 * math.pi
    rho = 0.0
    cull = True
    if per_ray:
        xlo = xhi = origins[0, 0]
        ylo = yhi = origins[0, 1]
        for i in range(1, n):
            xlo = min(xlo, origins[i, 0])
            xhi = max(xhi, origins[i, 0])
            ylo = min(ylo, origins[i, 1])
            yhi = max(yhi, origins[i, 1])
            if not angles[i] > angles[i - 1]:
                cull = False
        if angles[n - 1] - angles[0] >= 1.5 * two_pi:
            cull = False
        ox = 0.5 * (xlo + xhi)
        oy = 0.5 * (ylo + yhi)
        for i in range(n):
            rho = max(rho, math.hypot(origins[i, 0] - ox, origins[i, 1] - oy))
    else:
        ox = origins[0, 0]
        oy = origins[0, 1]
    step = 1 if per_ray else 0  # the row of ray i's origin: i * step
    dirx = np.cos(angles)
    diry = np.sin(angles)
    a0 = angles[0]
    rel_angles = angles - a0
    for s in range(seg_a.shape[0]):
        ax = seg_a[s, 0] - ox
        ay = seg_a[s, 1] - oy
        bx = seg_b[s, 0] - ox
        by = seg_b[s, 1] - oy
        # out of reach (the end points first: a cheap necessary condition of the gap test)
        if (
            min(math.sqrt(ax * ax + ay * ay), math.sqrt(bx * bx + by * by)) - rho >= max_range
            and _segment_gap(ax, ay, bx, by) - rho >= max_range
        ):
            continue
        cross = ax * by - ay * bx
        widen = 0.0
        every_beam = abs(cross) < _EPS and ax * bx + ay * by <= 0.0  # the origin lies on the segment
        if per_ray and not every_beam:
            gap = _segment_gap(ax, ay, bx, by)
            every_beam = not cull or gap <= rho
            if not every_beam:
                widen = math.asin(rho / gap)
        if every_beam:
            for i in range(n):
                j = i * step
                t = _ray_segment(
                    origins[j, 0], origins[j, 1], dirx[i], diry[i], seg_a[s, 0], seg_a[s, 1], seg_b[s, 0], seg_b[s, 1]
                )
                if t < out[i]:
                    out[i] = t
            continue
        first = math.atan2(ay, ax)
        span = (math.atan2(by, bx) - first + math.pi) % two_pi - math.pi  # from a to b, within half a turn
        rel = (first + 0.5 * span - a0) % two_pi
        spans = _beam_spans(rel_angles, rel, 0.5 * abs(span) + widen if per_ray else 0.5 * abs(span))
        for k in range(3):
            for i in range(spans[k, 0], spans[k, 1]):
                j = i * step
                t = _ray_segment(
                    origins[j, 0], origins[j, 1], dirx[i], diry[i], seg_a[s, 0], seg_a[s, 1], seg_b[s, 0], seg_b[s, 1]
                )
                if t < out[i]:
                    out[i] = t
    for c in range(centres.shape[0]):
        wx = centres[c, 0] - ox
        wy = centres[c, 1] - oy
        d = math.sqrt(wx * wx + wy * wy)
        r = radii[c]
        if d - r - rho >= max_range:
            continue
        if per_ray:
            if not cull or d - r <= rho:  # (_ray_circle gives 0 to a ray from inside the circle)
                for i in range(n):
                    t = _ray_circle(origins[i, 0], origins[i, 1], dirx[i], diry[i], centres[c, 0], centres[c, 1], r)
                    if t < out[i]:
                        out[i] = t
                continue
            half = math.asin(r / d) + math.asin(rho / (d - r))
        else:
            if d <= r:
                for i in range(n):
                    out[i] = 0.0
                continue
            half = math.asin(r / d)
        rel = (math.atan2(wy, wx) - a0) % two_pi
        spans = _beam_spans(rel_angles, rel, half)
        for k in range(3):
            for i in range(spans[k, 0], spans[k, 1]):
                j = i * step
                t = _ray_circle(origins[j, 0], origins[j, 1], dirx[i], diry[i], centres[c, 0], centres[c, 1], r)
                if t < out[i]:
                    out[i] = t
    return out


@numba.njit(cache=True)
def cast_rays(
    origin: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> NDArray[np.float64]:
    """First-hit range of each ray, ``max_range`` where nothing is hit within it.

    Every segment and circle covers an angular interval seen from the origin; only the beams
    inside it are tested (found by binary search over the beam angles relative to the first,
    so uneven spacing works too), so the cost grows with the beams each obstacle covers rather
    than beams times obstacles. A segment through the origin is tested against every beam.

    Args:
        origin: ``(2,)`` ray origin (world frame).
        angles: ``(B,)`` world-frame ray directions in radians, sorted ascending and spanning
            less than one full turn past ``angles[0]`` (as a LIDAR's beams are).
        max_range: maximum range in metres.
        seg_a, seg_b: ``(S, 2)`` segment end points.
        centres, radii: ``(C, 2)`` and ``(C,)`` circles.

    Returns:
        ``(B,)`` ranges in ``[0, max_range]``.
    """
    origins = np.empty((1, 2))
    origins[0, 0] = origin[0]
    origins[0, 1] = origin[1]
    return _cast(origins, False, angles, max_range, seg_a, seg_b, centres, radii)


@numba.njit(cache=True)
def cast_rays_from(
    origins: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> NDArray[np.float64]:
    """:func:`cast_rays` with an origin per ray: ray ``i`` starts at ``origins[i]`` (a swept
    scan, each beam taken from where the robot was at its time: :mod:`envs.sensors.ranging`).

    The origins should lie close together (within centimetres of each other, as a robot's path
    during one sweep does): the beams an obstacle may cover are found from the middle of their
    bounding box, widened by the parallax of the farthest origin (:func:`_cast`), so the cost
    is close to :func:`cast_rays`' while the ranges are exact for every origin. Angles
    should ascend; where they do not (or span 3 pi or more), every beam is tested against every
    obstacle (correct, slower).

    Args:
        origins: ``(B, 2)`` each ray's origin (world frame); more columns are ignored (a ``(B, 3)`` pose array).
        angles, max_range, seg_a, seg_b, centres, radii: as for :func:`cast_rays`.

    Returns:
        ``(B,)`` ranges in ``[0, max_range]``.
    """
    return _cast(origins, True, angles, max_range, seg_a, seg_b, centres, radii)


@numba.njit(cache=True, inline="always")
def _segment_gap(ax: float, ay: float, bx: float, by: float) -> float:
    """Distance from the origin to the segment from ``(ax, ay)`` to ``(bx, by)`` (origin-relative)."""
    ex = bx - ax
    ey = by - ay
    l2 = ex * ex + ey * ey
    t = 0.0 if l2 <= 0.0 else min(1.0, max(0.0, -(ax * ex + ay * ey) / l2))
    px = ax + t * ex
    py = ay + t * ey
    return math.sqrt(px * px + py * py)


@numba.njit(cache=True)
def sight_lines_clear(
    origin: NDArray[np.float64],
    targets: NDArray[np.float64],
    target_radii: NDArray[np.float64],
    max_range: NDArray[np.float64],
    seg_a: NDArray[np.float64],
    seg_b: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """Whether each target (a pole of given radius) is visible from ``origin``.

    A target is hidden when it is farther than its ``max_range`` or when a segment or circle
    crosses the line of sight before the near side of the pole.

    Args:
        origin: ``(2,)`` viewpoint.
        targets: ``(n, 2)`` pole centres; ``target_radii``: ``(n,)``.
        max_range: ``(n,)`` detection range of each target (``inf`` for none).
        seg_a, seg_b: ``(S, 2)`` occluding segments.
        centres, radii: ``(C, 2)`` and ``(C,)`` occluding circles.

    Returns:
        ``(n,)`` booleans, True where the line of sight is clear.
    """
    n = targets.shape[0]
    clear = np.ones(n, dtype=np.bool_)
    ox = origin[0]
    oy = origin[1]
    for j in range(n):
        tx = targets[j, 0] - ox
        ty = targets[j, 1] - oy
        dist = math.sqrt(tx * tx + ty * ty)
        if dist > max_range[j]:
            clear[j] = False
            continue
        if dist < _EPS:
            continue
        dx = tx / dist
        dy = ty / dist
        reach = dist - target_radii[j]
        for s in range(seg_a.shape[0]):
            if _ray_segment(ox, oy, dx, dy, seg_a[s, 0], seg_a[s, 1], seg_b[s, 0], seg_b[s, 1]) < reach:
                clear[j] = False
                break
        if not clear[j]:
            continue
        for c in range(centres.shape[0]):
            if _ray_circle(ox, oy, dx, dy, centres[c, 0], centres[c, 1], radii[c]) < reach:
                clear[j] = False
                break
    return clear
