"""The floor the robot can reach: which free places connect to the world's main floor.

A pose can clear every wall and piece of furniture and still be somewhere the robot can never
be: behind the corridor's wall, between it and the field's edge, a pocket that walls close on
every side. :class:`FloorGrid` rasterizes what stands on the floor (the arena's edge, the
interior walls, box furniture and floor-standing solids, as lines and filled polygons) at
``cell_m``, keeps the cells whose distance to all of it leaves room for the robot's disc
(OpenCV's distance transform), and labels the connected free regions (4-connected, so no path
squeezes diagonally between two cells). The **main floor** is the largest region: every
shipped world has one floor and at most small closed pockets. :meth:`FloorGrid.reachable`
answers for a point; :meth:`envs.config.WorldConfig.robot_placement_problem` refuses a pose
off the main floor, so a reset's ``robot_pose``, the world's start and a kidnap follow one rule.

The grid is a little generous (the clearance is lowered by 1.5 cells) so that every pose the
exact checks accept lies on a free cell; a gap narrower than the robot by less than that may
therefore count as open, never the other way round.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import NDArray

#: the grid's cell (m): fine against every shipped robot's radius (0.09-0.3 m)
CELL_M = 0.05
#: the largest grid made (cells): a 150 m x 100 m campus at 5 cm is 6 million
MAX_CELLS = 8_000_000


class FloorGrid:
    """Free cells of an arena and their connected regions (module docstring).

    Args:
        arena_m: ``(xmin, ymin, xmax, ymax)`` the robot's disc must stay inside.
        segments: ``(S, 4)`` floor-standing segments ``(x1, y1, x2, y2)``, each ``wall_radius_m`` thick.
        polygons: convex floor-standing footprints (boxes, buildings, poles) whose inside is blocked.
        clearance_m: the robot's radius.
        wall_radius_m: a wall's half thickness.
        cell_m: the grid's cell, coarsened (saying nothing) where the arena would take more than
            :data:`MAX_CELLS`.
    """

    def __init__(
        self,
        arena_m: tuple[float, float, float, float],
        segments: NDArray[np.float64],
        polygons: Sequence[NDArray[np.float64]],
        clearance_m: float,
        wall_radius_m: float,
        cell_m: float = CELL_M,
    ) -> None:
        xmin, ymin, xmax, ymax = arena_m
        cell = max(cell_m, math.sqrt((xmax - xmin) * (ymax - ymin) / MAX_CELLS))
        # one blocked ring of cells wall_radius_m outside the arena: the edge then needs the same
        # clearance as a wall (radius + wall_radius_m from its line), i.e. the radius from the edge
        pad = wall_radius_m
        self._x0, self._y0, self.cell_m = xmin - pad, ymin - pad, cell
        nx = math.ceil((xmax - xmin + 2 * pad) / cell) + 1
        ny = math.ceil((ymax - ymin + 2 * pad) / cell) + 1
        free = np.full((ny, nx), 255, dtype=np.uint8)
        free[0, :] = free[-1, :] = free[:, 0] = free[:, -1] = 0
        for x1, y1, x2, y2 in np.asarray(segments, dtype=np.float64).reshape(-1, 4):
            cv2.line(free, self._pixel(x1, y1), self._pixel(x2, y2), 0, 1)
        for corners in polygons:
            points = np.array([self._pixel(x, y) for x, y in np.asarray(corners, dtype=np.float64)], dtype=np.int32)
            cv2.fillConvexPoly(free, points, 0)
        distance_m = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * cell
        room = (distance_m >= clearance_m + wall_radius_m - 1.5 * cell).astype(np.uint8)
        count, labels = cv2.connectedComponents(room, connectivity=4)
        areas = np.bincount(labels.ravel(), minlength=count)
        areas[0] = 0  # label 0: no room
        main = int(np.argmax(areas))
        #: the main floor's cells (kept alone: a config that holds the grid stays small to pickle)
        self._main = labels == main if areas[main] > 0 else np.zeros_like(room, dtype=bool)
        #: the main floor's area (m^2): where the robot's centre may be
        self.main_area_m2 = float(areas[main]) * cell * cell

    def _pixel(self, x: float, y: float) -> tuple[int, int]:
        return int(round((x - self._x0) / self.cell_m)), int(round((y - self._y0) / self.cell_m))

    def reachable(self, x: float, y: float) -> bool:
        """Whether ``(x, y)`` lies on the main floor: its cell or, for a pose the exact checks
        accept that rounds onto a blocked cell, one of the eight around it."""
        col, row = self._pixel(x, y)
        ny, nx = self._main.shape
        return bool(np.any(self._main[max(row - 1, 0) : min(row + 2, ny), max(col - 1, 0) : min(col + 2, nx)]))


def floor_grid(
    arena_m: tuple[float, float, float, float],
    segments: NDArray[np.float64],
    polygons: Sequence[NDArray[np.float64]],
    clearance_m: float,
    wall_radius_m: float,
) -> FloorGrid:
    """The :class:`FloorGrid` of this geometry, made once a process: every ``gym.make`` builds its
    world's config anew (a benchmark, one env per episode), and the grid is the same each time."""
    return _floor_grid(
        tuple(float(v) for v in arena_m),
        tuple(tuple(row) for row in np.asarray(segments, dtype=np.float64).reshape(-1, 4).tolist()),
        tuple(tuple(tuple(corner) for corner in np.asarray(p, dtype=np.float64).tolist()) for p in polygons),
        float(clearance_m),
        float(wall_radius_m),
    )


@functools.lru_cache(maxsize=16)
def _floor_grid(
    arena_m: tuple[float, ...],
    segments: tuple[tuple[float, ...], ...],
    polygons: tuple[tuple[tuple[float, ...], ...], ...],
    clearance_m: float,
    wall_radius_m: float,
) -> FloorGrid:
    xmin, ymin, xmax, ymax = arena_m
    rows = np.array(segments, dtype=np.float64).reshape(-1, 4)
    return FloorGrid(
        (xmin, ymin, xmax, ymax), rows, [np.array(p, dtype=np.float64) for p in polygons], clearance_m, wall_radius_m
    )
