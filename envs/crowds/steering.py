"""Steering kernels shared by the crowds: drive members to targets, braking on arrival.

The per-member logic runs in small numba kernels over arrays, so a 14-robot soccer crowd
costs a few microseconds a step.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

ARRIVE_RADIUS_M = 0.1  # a member within this distance of its target has arrived
_SLOWDOWN_S = 0.3  # members brake linearly over the last this-many seconds of travel
_TRANSIT_M = 0.5  # members farther than this from their target avoid each other
_AVOID_GAP_M = 0.4  # ... when closer than this, surface to surface
_KEEP_RIGHT_RAD = math.radians(45.0)  # the avoidance push is turned this far (pass on the right)


@numba.njit(cache=True)
def seek(
    pos: NDArray[np.float64],
    targets: NDArray[np.float64],
    max_speed: NDArray[np.float64],
    held: NDArray[np.bool_],
    radii: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Velocities ``(N, 2)`` that drive each member to its target, braking on arrival.

    A member in transit (farther than ``_TRANSIT_M`` from its target) also steers away from
    other members closer than ``_AVOID_GAP_M`` surface to surface; the push is turned by
    ``_KEEP_RIGHT_RAD`` so that two members meeting head-on pass each other instead of
    pressing nose to nose. Members settling into place (a queue moving up) do not avoid.
    """
    n = pos.shape[0]
    out = np.zeros((n, 2))
    cr = math.cos(_KEEP_RIGHT_RAD)
    sr = math.sin(_KEEP_RIGHT_RAD)
    for i in range(n):
        if held[i]:
            continue
        dx = targets[i, 0] - pos[i, 0]
        dy = targets[i, 1] - pos[i, 1]
        d = math.sqrt(dx * dx + dy * dy)
        if d < 1e-9:
            continue
        speed = min(max_speed[i], d / _SLOWDOWN_S)
        vx = dx / d * speed
        vy = dy / d * speed
        if d > _TRANSIT_M:
            for j in range(n):
                if j == i:
                    continue
                rx = pos[i, 0] - pos[j, 0]
                ry = pos[i, 1] - pos[j, 1]
                r = math.sqrt(rx * rx + ry * ry)
                reach = radii[i] + radii[j] + _AVOID_GAP_M
                if r < 1e-9 or r >= reach:
                    continue
                push = max_speed[i] * (reach - r) / reach / r
                vx += push * (cr * rx - sr * ry)
                vy += push * (sr * rx + cr * ry)
            v = math.sqrt(vx * vx + vy * vy)
            if v > max_speed[i]:
                vx *= max_speed[i] / v
                vy *= max_speed[i] / v
        out[i, 0] = vx
        out[i, 1] = vy
    return out
