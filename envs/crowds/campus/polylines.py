"""Polylines packed for the campus crowd's numba kernels: the walkways and the lanes.

:class:`Polylines` packs several lines into flat arrays with their arc lengths;
:func:`project` and :func:`point_at` go from a point to its arc length on a line and back.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray


class Polylines:
    """Polylines packed for the kernels: points ``pts`` ``(P, 2)``, arc length ``cum`` ``(P,)``
    from each line's start, and per line its ``first`` point, point count ``n`` and ``length``."""

    def __init__(self, lines: list[NDArray[np.float64]]) -> None:
        self.pts = np.concatenate(lines).reshape(-1, 2) if lines else np.zeros((0, 2))
        self.n = np.array([len(line) for line in lines], dtype=np.int64)
        self.first = np.concatenate([[0], np.cumsum(self.n)[:-1]]).astype(np.int64) if lines else np.zeros(0, np.int64)
        cums = [np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line, axis=0).T))]) for line in lines]
        self.cum = np.concatenate(cums) if cums else np.zeros(0)
        self.length = np.array([c[-1] for c in cums], dtype=np.float64)

    def line(self, k: int) -> NDArray[np.float64]:
        return self.pts[self.first[k] : self.first[k] + self.n[k]]

    def at(self, k: int, s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The point ``(2,)`` at arc length ``s`` of line ``k`` and the unit tangent there."""
        x, y, tx, ty = point_at(s, self.pts, self.cum, int(self.first[k]), int(self.n[k]))
        return np.array([x, y]), np.array([tx, ty])


@numba.njit(cache=True)
def project(px: float, py: float, pts: NDArray[np.float64], cum: NDArray[np.float64], first: int, n: int) -> float:
    """Arc length of the point of a polyline nearest to ``(px, py)``."""
    best = math.inf
    s = 0.0
    for k in range(first, first + n - 1):
        ax = pts[k, 0]
        ay = pts[k, 1]
        wx = pts[k + 1, 0] - ax
        wy = pts[k + 1, 1] - ay
        l2 = wx * wx + wy * wy
        t = min(1.0, max(0.0, ((px - ax) * wx + (py - ay) * wy) / l2))
        dx = ax + t * wx - px
        dy = ay + t * wy - py
        d2 = dx * dx + dy * dy
        if d2 < best:
            best = d2
            s = cum[k] + t * (cum[k + 1] - cum[k])
    return s


@numba.njit(cache=True)
def point_at(
    s: float, pts: NDArray[np.float64], cum: NDArray[np.float64], first: int, n: int
) -> tuple[float, float, float, float]:
    """``(x, y, tx, ty)``: the point at arc length ``s`` of a polyline and its unit tangent
    (beyond the ends, along the end segments' lines)."""
    k = first
    while k < first + n - 2 and cum[k + 1] < s:
        k += 1
    seg = cum[k + 1] - cum[k]
    tx = (pts[k + 1, 0] - pts[k, 0]) / seg
    ty = (pts[k + 1, 1] - pts[k, 1]) / seg
    u = s - cum[k]
    return pts[k, 0] + u * tx, pts[k, 1] + u * ty, tx, ty
