"""``WorldState``: a frozen snapshot of what stands where, read by sensors, crowds and the renderer.

The world exports one snapshot per step (:meth:`envs.world.World.snapshot`). Its arrays
are never written after the snapshot is taken (the world makes fresh arrays every step and
marks the static ones read-only), so a snapshot handed out earlier keeps describing its
own step. Nothing here touches pymunk.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from core.geometry import spanning
from envs.figures import Figures, Section

#: body rows: a slice where they are consecutive (views), else an index array
Rows = slice | NDArray[np.int64]


def robot_pose(positions: NDArray[np.float64], angles: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(3,)`` our robot's pose (row 0) from body positions ``(B, 2)`` and angles ``(B,)``, heading wrapped to ``[-pi, pi)``."""
    # in Python floats (the same IEEE operations as numpy's scalars, a third of the time: once a step for the info)
    x, y = positions[0].tolist()
    theta = (float(angles[0]) + math.pi) % (2 * math.pi) - math.pi
    return np.array([x, y, theta])


class WorldState(NamedTuple):
    """The world at one step (immutable; a named tuple, so that making one per step is cheap).

    Attributes:
        time_s: simulated time; ``step``: steps since the reset.
        positions: ``(B, 2)`` body centres; row 0 is our robot, then the crowd's bodies.
        angles: ``(B,)`` body headings (unwrapped); ``velocities``: ``(B, 2)``.
        radii_m: ``(B,)`` body footprint radii.
        crowd_rows: rows of the crowd's members (robots, people).
        ball_row: the ball's row, or -1 without a ball.
        seg_a, seg_b: ``(S, 2)`` wall segments (static; they occlude and collide);
            ``seg_bottom_m``, ``seg_top_m``: ``(S,)`` the heights they span.
        figures: every body's parts by height (:mod:`envs.bodies`); :meth:`section` cuts them.
        landmark_xy: ``(L, 2)``, ``landmark_radius_m`` and ``landmark_max_range_m``: ``(L,)``;
            ``landmark_names``: ``L`` names.
        robot_start: ``(3,)`` our robot's position and heading (unwrapped) at the start of the
            step that led here, where a sensor that takes time finds the poses within the step
            (:func:`core.geometry.poses_along_step`); the current ones after a reset or a
            teleport (no motion).
    """

    time_s: float
    step: int
    positions: NDArray[np.float64]
    angles: NDArray[np.float64]
    velocities: NDArray[np.float64]
    radii_m: NDArray[np.float64]
    crowd_rows: Rows
    ball_row: int
    seg_a: NDArray[np.float64]
    seg_b: NDArray[np.float64]
    seg_bottom_m: NDArray[np.float64]
    seg_top_m: NDArray[np.float64]
    figures: Figures
    landmark_xy: NDArray[np.float64]
    landmark_radius_m: NDArray[np.float64]
    landmark_max_range_m: NDArray[np.float64]
    landmark_names: tuple[str, ...]
    robot_start: NDArray[np.float64]

    @property
    def body_count(self) -> int:
        return int(self.positions.shape[0])

    @property
    def robot_xy(self) -> NDArray[np.float64]:
        """``(2,)`` our robot's position."""
        return self.positions[0]

    @property
    def robot_heading_rad(self) -> float:
        """Our robot's heading as pymunk integrates it (not wrapped)."""
        return float(self.angles[0])

    @property
    def robot_pose(self) -> NDArray[np.float64]:
        """``(3,)`` true pose of our robot, heading wrapped to ``[-pi, pi)``."""
        return robot_pose(self.positions, self.angles)

    @property
    def robot_radius_m(self) -> float:
        return float(self.radii_m[0])

    def section(self, height_m: float) -> Section:
        """The discs and box sides of every body (not our robot) cut by the horizontal plane at ``height_m``."""
        return self.figures.section(height_m)

    def occluders(self, height_m: float) -> Section:
        """The discs and box sides at ``height_m`` that block a camera's sight lines."""
        return self.figures.occluders(height_m)

    def walls_at(self, height_m: float) -> NDArray[np.bool_]:
        """``(S,)`` the static segments a sensor at ``height_m`` sees: those spanning it (``bottom <= h < top``)."""
        return spanning(self.seg_bottom_m, self.seg_top_m, height_m)
