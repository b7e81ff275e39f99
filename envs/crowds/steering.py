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
TRANSIT_M = 0.5  # members farther than this from their target avoid each other
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

    A member in transit (farther than ``TRANSIT_M`` from its target) also steers away from
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
        if d > TRANSIT_M:
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


@numba.njit(cache=True)
def give_way(
    pos: NDArray[np.float64],
    want: NDArray[np.float64],
    radii: NDArray[np.float64],
    active: NDArray[np.bool_],
    robot_xy: NDArray[np.float64],
    robot_v: NDArray[np.float64],
    robot_radius: float,
    margin: float,
    horizon_s: float,
) -> NDArray[np.float64]:
    """Velocities ``(N, 2)``: ``want`` turned so that each ``active`` member passes the robot.

    A member walking with velocity ``want`` relative to the ground moves at ``w = want -
    robot_v`` relative to the robot. When its closest approach within ``horizon_s`` would come
    nearer than the clearance ``c = radii + robot_radius + margin`` (surface gap ``margin``), ``w``
    is turned, at the same speed, to the tangent of the clearance circle around the robot on
    the side it was already passing (a velocity-obstacle step for one agent, the robot); a
    member already inside the clearance walks straight away from it. This is how pedestrians
    give way to a robot they see coming: they curve around it rather than walk into it.
    """
    n = pos.shape[0]
    out = want.copy()
    for i in range(n):
        if not active[i]:
            continue
        px = robot_xy[0] - pos[i, 0]
        py = robot_xy[1] - pos[i, 1]
        wx = want[i, 0] - robot_v[0]
        wy = want[i, 1] - robot_v[1]
        w2 = wx * wx + wy * wy
        dist = math.sqrt(px * px + py * py)
        clearance = radii[i] + robot_radius + margin
        speed = math.sqrt(want[i, 0] ** 2 + want[i, 1] ** 2)
        if dist <= clearance:
            if dist > 1e-9 and speed > 0.0:  # too close: step straight back from it
                out[i, 0] = -px / dist * speed
                out[i, 1] = -py / dist * speed
            continue
        if w2 < 1e-12:
            continue
        t = min(max((px * wx + py * wy) / w2, 0.0), horizon_s)
        mx = px - wx * t
        my = py - wy * t
        if mx * mx + my * my >= clearance * clearance:
            continue
        # turn w to the tangent of the clearance circle, on the side it passes now
        side = 1.0 if px * wy - py * wx >= 0.0 else -1.0  # w to the left (+) or right (-) of the robot
        tangent = math.asin(clearance / dist)
        base = math.atan2(py, px) + side * tangent
        w = math.sqrt(w2)
        vx = w * math.cos(base) + robot_v[0]
        vy = w * math.sin(base) + robot_v[1]
        v = math.sqrt(vx * vx + vy * vy)
        if v > speed:  # never faster than it wanted to walk
            vx *= speed / v
            vy *= speed / v
        out[i, 0] = vx
        out[i, 1] = vy
    return out
