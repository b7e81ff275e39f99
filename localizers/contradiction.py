"""Lost detection (ours; the papers have none): a pose estimate that the measurements keep contradicting.

Each frame with at least two measurements is compared with what the estimate predicts: the
median of the measurements' residuals above a threshold contradicts it. Contradicted on every
such frame for ``after_s``, the localizer is lost: the robot is not where it thinks (it was
carried away, its odometry jumped, or it locked onto a wrong pose). The median makes one
misidentified landmark or one distractor harmless; frames with fewer than two measurements say
nothing either way.

:class:`ContradictionClock` keeps the time for any per-frame verdict or residual; :class:`Contradiction` is the
bearings' (the absolute wrapped bearing residual against ``residual_rad``), used by
``candidate_sets`` (which restarts from the bearings) and ``mcl_bearing`` (which claims no pose
while lost). ``far_landmark_pf`` folds in the median Mahalanobis distance of its stereo
detections to the scene map's landmarks.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from core.motion import wrap_scalar


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


class ContradictionClock:
    """How long the measurements have contradicted a localizer's estimate (module docstring):
    :meth:`tick` takes a frame's verdict, :meth:`fold` a frame's median residual against ``threshold``.

    Args:
        after_s: contradicted on every frame that says anything for this long: lost (inf: never).
        dt_s: the time between frames.
        threshold: a frame's median residual above this contradicts the estimate (:meth:`fold`).
    """

    def __init__(self, after_s: float, dt_s: float, threshold: float = math.inf) -> None:
        self.after_s, self._dt, self.threshold = after_s, dt_s, threshold
        self.contradicted_s = 0.0

    def reset(self) -> None:
        self.contradicted_s = 0.0

    @property
    def lost(self) -> bool:
        return self.contradicted_s >= self.after_s - 1e-9

    def tick(self, contradicted: bool | None) -> bool:
        """Fold in one frame that contradicts the estimate (True), agrees with it (False, which
        restarts the clock) or says nothing (None); returns :attr:`lost`."""
        if contradicted is not None:
            self.contradicted_s = self.contradicted_s + self._dt if contradicted else 0.0
        return self.lost

    def fold(self, residual: float | None) -> bool:
        """Fold in one frame's median residual (None: a frame that says nothing); returns :attr:`lost`."""
        return self.tick(None if residual is None else residual > self.threshold)


class Contradiction(ContradictionClock):
    """How long the bearings have contradicted a localizer's estimate (module docstring).

    Args:
        landmarks_xy: ``(L, 2)`` the map's landmarks.
        residual_rad: a frame's median absolute residual above this contradicts the estimate.
        after_s: contradicted on every frame (with >= 2 bearings) for this long: lost (inf: never).
        dt_s: the time between frames.
    """

    def __init__(self, landmarks_xy: NDArray[np.float64], residual_rad: float, after_s: float, dt_s: float) -> None:
        super().__init__(after_s, dt_s, threshold=residual_rad)
        self._x = np.ascontiguousarray(landmarks_xy[:, 0], dtype=np.float64)
        self._y = np.ascontiguousarray(landmarks_xy[:, 1], dtype=np.float64)
        self.residual_rad = residual_rad

    def observe(self, pose: tuple[float, float, float] | None, ids: NDArray[np.int64], bearings: NDArray[np.float64]) -> bool:
        """Fold in one frame seen from the estimate ``pose`` (None: no estimate, which nothing
        contradicts); returns :attr:`lost`. Frames with fewer than two bearings change nothing."""
        if pose is None:
            self.contradicted_s = 0.0
            return False
        if ids.size < 2:
            return self.lost
        return self.fold(median_abs_residual(pose[0], pose[1], pose[2], self._x, self._y, ids, bearings))
