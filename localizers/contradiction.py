"""Lost detection from bearings (ours, issue 19): a pose estimate that the bearings keep contradicting.

Each frame with at least two bearings is compared with the bearings the estimate predicts:
the median absolute residual (wrapped) above ``residual_rad`` contradicts it. Contradicted on
every such frame for ``after_s``, the localizer is lost: the robot is not where it thinks (it
was carried away, its odometry jumped, or it locked onto a wrong pose). The median makes one
misidentified landmark or one distractor harmless; frames with fewer than two bearings say
nothing either way. Used by ``candidate_sets`` (which restarts from the bearings) and
``mcl_bearing`` (which claims no pose while lost).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from localizers.motion import wrap_scalar


@numba.njit(cache=True)
def median_abs_residual(
    x: float,
    y: float,
    theta: float,
    landmark_x: NDArray[np.float64],
    landmark_y: NDArray[np.float64],
    ids: NDArray[np.int64],
    bearings: NDArray[np.float64],
) -> float:
    """Median over one frame of ``|bearing - predicted bearing|`` (wrapped) from the pose ``(x, y, theta)``."""
    n = ids.shape[0]
    residual = np.empty(n)
    for i in range(n):
        predicted = wrap_scalar(math.atan2(landmark_y[ids[i]] - y, landmark_x[ids[i]] - x) - theta)
        residual[i] = abs(wrap_scalar(bearings[i] - predicted))
    residual.sort()
    half = n // 2
    return float(residual[half]) if n % 2 else 0.5 * (residual[half - 1] + residual[half])


class Contradiction:
    """How long the bearings have contradicted a localizer's estimate (module docstring).

    Args:
        landmarks_xy: ``(L, 2)`` the map's landmarks.
        residual_rad: a frame's median absolute residual above this contradicts the estimate.
        after_s: contradicted on every frame (with >= 2 bearings) for this long: lost (inf: never).
        dt_s: the time between frames.
    """

    def __init__(self, landmarks_xy: NDArray[np.float64], residual_rad: float, after_s: float, dt_s: float) -> None:
        self._x = np.ascontiguousarray(landmarks_xy[:, 0], dtype=np.float64)
        self._y = np.ascontiguousarray(landmarks_xy[:, 1], dtype=np.float64)
        self.residual_rad, self.after_s, self._dt = residual_rad, after_s, dt_s
        self.contradicted_s = 0.0

    def reset(self) -> None:
        self.contradicted_s = 0.0

    @property
    def lost(self) -> bool:
        return self.contradicted_s >= self.after_s - 1e-9

    def observe(self, pose: tuple[float, float, float] | None, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> bool:
        """Fold in one frame seen from the estimate ``pose`` (None: no estimate, which nothing
        contradicts); returns :attr:`lost`. Frames with fewer than two bearings change nothing."""
        if pose is None:
            self.contradicted_s = 0.0
            return False
        if ids.size < 2:
            return self.lost
        residual = median_abs_residual(pose[0], pose[1], pose[2], self._x, self._y, ids, bearings)
        self.contradicted_s = self.contradicted_s + self._dt if residual > self.residual_rad else 0.0
        return self.lost
