"""The campus walkers' steering: along the walkway network by a social force, yielding to cars.

:func:`walk_velocities` is the numba kernel the crowd calls every step for all its walkers
(the behaviour is described in :mod:`envs.crowds.campus`).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from envs.crowds.campus.config import EDGE_GAP_M
from envs.crowds.campus.polylines import point_at, project
from envs.crowds.steering import cap_speed
from envs.crowds.walkers import SPEED_CAP

_YIELD_MIN_SPEED_MPS = 0.3  # pedestrians yield only to cars moving faster than this
_YIELD_MARGIN_M = 0.3  # ... keeping this much clear of the car's stretched box, besides their radius


@numba.njit(cache=True)
def walk_velocities(
    pos: NDArray[np.float64],
    vel: NDArray[np.float64],
    desired: NDArray[np.float64],
    way: NDArray[np.int64],
    direction: NDArray[np.float64],
    keep: NDArray[np.float64],
    draw: NDArray[np.float64],
    pts: NDArray[np.float64],
    cum: NDArray[np.float64],
    first: NDArray[np.int64],
    npts: NDArray[np.int64],
    length: NDArray[np.float64],
    half_width: NDArray[np.float64],
    node: NDArray[np.int64],
    adj_start: NDArray[np.int64],
    adj_way: NDArray[np.int64],
    adj_end: NDArray[np.int64],
    others: NDArray[np.float64],
    others_r: NDArray[np.float64],
    gain: NDArray[np.float64],
    car_pos: NDArray[np.float64],
    car_angle: NDArray[np.float64],
    car_vel: NDArray[np.float64],
    car_half: NDArray[np.float64],
    radius: float,
    lookahead: float,
    end_m: float,
    tau: float,
    strength: float,
    range_b: float,
    cutoff: float,
    car_gain: float,
    yield_s: float,
    dt: float,
) -> NDArray[np.float64]:
    """The walkers' velocities ``(N, 2)`` for the next step; ``way`` and ``direction`` change in
    place where a walker reaches a walkway's end (``draw`` ``(N,)``: uniform numbers for its choice).

    Along its walkway toward a lane point ``lookahead`` ahead and right of the centre line by
    ``keep`` of the free half width; the social force with surface distances, cut at ``cutoff``:
    discs ``others`` (gain 0: not a disc, skipped; the walker itself: at distance 0, skipped)
    and the cars' boxes ``car_half`` (half length, half width) at ``car_pos``, ``car_angle``.
    A walker that would step into a moving car's box stretched over ``yield_s`` of its travel
    waits (its desired velocity is zero), unless it is in one already.
    """
    n = pos.shape[0]
    out = np.empty((n, 2))
    reach_pad = cutoff + radius
    for i in range(n):
        px = pos[i, 0]
        py = pos[i, 1]
        w = way[i]
        s = project(px, py, pts, cum, first[w], npts[w])
        length_w = length[w]
        e = min(end_m, 0.25 * length_w)
        if (direction[i] > 0 and s >= length_w - e) or (direction[i] < 0 and s <= e):
            nd = node[w, 1 if direction[i] > 0 else 0]
            k0 = adj_start[nd]
            k1 = adj_start[nd + 1]
            choices = k1 - k0 - 1  # every walkway end meeting there but this one
            if choices <= 0:
                direction[i] = -direction[i]
            else:
                pick = min(int(draw[i] * choices), choices - 1)
                here = 1 if direction[i] > 0 else 0
                for k in range(k0, k1):
                    if adj_way[k] == w and adj_end[k] == here:
                        continue
                    if pick == 0:
                        w = adj_way[k]
                        direction[i] = 1.0 if adj_end[k] == 0 else -1.0
                        break
                    pick -= 1
                way[i] = w
                length_w = length[w]
                s = project(px, py, pts, cum, first[w], npts[w])
        goal_s = min(max(s + direction[i] * lookahead, 0.0), length_w)
        gx, gy, tx, ty = point_at(goal_s, pts, cum, first[w], npts[w])
        tx *= direction[i]
        ty *= direction[i]
        off = keep[i] * max(0.0, half_width[w] - radius - EDGE_GAP_M)
        gx += ty * off  # the right of the travel direction (tx, ty) is (ty, -tx)
        gy -= tx * off
        ex = gx - px
        ey = gy - py
        d = math.sqrt(ex * ex + ey * ey)
        if d > 1e-9:
            ex /= d
            ey /= d
        # do not step into a moving car's path
        wait = False
        inside_now = False
        m = radius + _YIELD_MARGIN_M
        for c in range(car_pos.shape[0]):
            speed = math.sqrt(car_vel[c, 0] ** 2 + car_vel[c, 1] ** 2)
            if speed < _YIELD_MIN_SPEED_MPS:
                continue
            ca = math.cos(car_angle[c])
            sa = math.sin(car_angle[c])
            front = car_half[c, 0] + speed * yield_s + m
            for step in range(3):  # now, half way, at yield_s
                frac = 0.5 * step
                qx = px + ex * desired[i] * yield_s * frac - car_pos[c, 0]
                qy = py + ey * desired[i] * yield_s * frac - car_pos[c, 1]
                lx = qx * ca + qy * sa
                ly = -qx * sa + qy * ca
                if -car_half[c, 0] - m <= lx <= front and abs(ly) <= car_half[c, 1] + m:
                    if step == 0:
                        inside_now = True
                    else:
                        wait = True
        if wait and not inside_now:
            fx = -vel[i, 0] / tau
            fy = -vel[i, 1] / tau
        else:
            fx = (desired[i] * ex - vel[i, 0]) / tau
            fy = (desired[i] * ey - vel[i, 1]) / tau
        for j in range(others.shape[0]):
            if gain[j] == 0.0:
                continue
            rx = px - others[j, 0]
            ry = py - others[j, 1]
            reach = reach_pad + others_r[j]
            if rx > reach or rx < -reach or ry > reach or ry < -reach:
                continue
            r = math.sqrt(rx * rx + ry * ry)
            if r < 1e-9:
                continue  # itself
            gap = r - radius - others_r[j]
            if gap > cutoff:
                continue
            mag = strength * gain[j] * math.exp(-max(gap, 0.0) / range_b)
            fx += mag * rx / r
            fy += mag * ry / r
        for c in range(car_pos.shape[0]):
            qx = px - car_pos[c, 0]
            qy = py - car_pos[c, 1]
            hl = car_half[c, 0]
            hw = car_half[c, 1]
            if abs(qx) > reach_pad + hl + hw or abs(qy) > reach_pad + hl + hw:
                continue
            ca = math.cos(car_angle[c])
            sa = math.sin(car_angle[c])
            lx = qx * ca + qy * sa
            ly = -qx * sa + qy * ca
            dx = lx - min(max(lx, -hl), hl)
            dy = ly - min(max(ly, -hw), hw)
            dist = math.sqrt(dx * dx + dy * dy)
            if dist < 1e-9:  # inside the box: out by the nearer side
                if hl - abs(lx) < hw - abs(ly):
                    dx, dy, dist = (1.0 if lx >= 0 else -1.0), 0.0, 1.0
                else:
                    dx, dy, dist = 0.0, (1.0 if ly >= 0 else -1.0), 1.0
                gap = 0.0
            else:
                gap = dist - radius
                if gap > cutoff:
                    continue
            mag = strength * car_gain * math.exp(-max(gap, 0.0) / range_b) / dist
            fx += mag * (dx * ca - dy * sa)
            fy += mag * (dx * sa + dy * ca)
        vx = vel[i, 0] + dt * fx
        vy = vel[i, 1] + dt * fy
        vx, vy, _ = cap_speed(vx, vy, SPEED_CAP * desired[i])
        out[i, 0] = vx
        out[i, 1] = vy
    return out
