"""The campus cars: driving along the lanes (a numba kernel) and the geometry of their boxes.

:func:`drive_velocities` steers and brakes every moving car each step (the behaviour is
described in :mod:`envs.crowds.campus`); :func:`boxes_overlap` and :func:`box_disc_gap` test a
car's footprint against another's and against a disc, for placing cars and letting them in.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

from envs.crowds.campus.polylines import point_at, project

CAR_FILL = (70, 110, 170)  # moving cars
PARKED_FILL = (120, 130, 140)  # parked cars
CAR_LEAVE_M = 1.0  # a car this close to its lane's end leaves the campus
CAR_SIDE_GAP_M = 0.2  # a car keeps behind another whose box comes within this of its own width
_CAR_MIN_COS = 0.25  # a car turning by more than its look-ahead angle slows to cos(angle) of its speed, at least this share
#: body kinds in the cars' view: a disc (the robot, people), a car's box, nothing (a car itself)
DISC, BOX, SKIP = 0, 1, 2


@numba.njit(cache=True)
def drive_velocities(
    car_pos: NDArray[np.float64],
    car_vel: NDArray[np.float64],
    car_angle: NDArray[np.float64],
    lane: NDArray[np.int64],
    held: NDArray[np.bool_],
    own_row: NDArray[np.int64],
    pts: NDArray[np.float64],
    cum: NDArray[np.float64],
    first: NDArray[np.int64],
    npts: NDArray[np.int64],
    length: NDArray[np.float64],
    all_pos: NDArray[np.float64],
    all_vel: NDArray[np.float64],
    all_r: NDArray[np.float64],
    all_angle: NDArray[np.float64],
    kind: NDArray[np.int64],
    half_length: float,
    half_width: float,
    speed: float,
    accel: float,
    brake: float,
    max_brake: float,
    car_gap: float,
    stop_gap: float,
    margin: float,
    watch_s: float,
    lookahead: float,
    dt: float,
) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
    """The moving cars' velocities ``(C, 2)`` and which are at their lane's end ``(C,)``.

    Each steers toward its lane's point ``lookahead`` ahead at up to ``speed`` (less in a
    turn), accelerating at ``accel``, braking to stop ``car_gap`` behind a car (``kind``
    ``BOX``: its box's extent along and across the car's way) or ``stop_gap`` before a disc
    (the robot, a person) in its corridor (its width and ``margin`` either side; a disc that
    will be in it within ``watch_s`` counts, unless it is beside the car already), along
    ``v = sqrt(2 brake room)`` and at most at ``max_brake``.
    """
    c_count = car_pos.shape[0]
    out = np.zeros((c_count, 2))
    at_end = np.zeros(c_count, dtype=np.bool_)
    horizon = half_length + speed * speed / (2.0 * brake) + max(car_gap, stop_gap) + 2.0 * (half_length + half_width) + 1.0
    for c in range(c_count):
        if held[c]:
            continue
        px = car_pos[c, 0]
        py = car_pos[c, 1]
        w = lane[c]
        s = project(px, py, pts, cum, first[w], npts[w])
        if s >= length[w] - CAR_LEAVE_M:
            at_end[c] = True
        gx, gy, _, _ = point_at(s + lookahead, pts, cum, first[w], npts[w])
        ux = gx - px
        uy = gy - py
        d = math.sqrt(ux * ux + uy * uy)
        if d < 1e-9:
            continue
        ux /= d
        uy /= d
        target = speed * max(_CAR_MIN_COS, math.cos(car_angle[c]) * ux + math.sin(car_angle[c]) * uy)
        way = math.atan2(uy, ux)
        for j in range(all_pos.shape[0]):
            k = kind[j]
            if k == SKIP or j == own_row[c]:
                continue
            rx = all_pos[j, 0] - px
            ry = all_pos[j, 1] - py
            ahead = rx * ux + ry * uy
            if ahead < -half_length or ahead > horizon:
                continue
            lateral = -rx * uy + ry * ux
            if k == BOX:
                cd = abs(math.cos(all_angle[j] - way))
                sd = abs(math.sin(all_angle[j] - way))
                along = half_length * cd + half_width * sd
                across = half_length * sd + half_width * cd
                if abs(lateral) >= half_width + across + CAR_SIDE_GAP_M:
                    continue
                room = ahead - half_length - along - car_gap
            else:
                r = all_r[j]
                reach = half_width + r + margin
                if abs(lateral) >= reach:
                    fx = rx + all_vel[j, 0] * watch_s
                    fy = ry + all_vel[j, 1] * watch_s
                    if ahead < half_length or abs(-fx * uy + fy * ux) >= reach or fx * ux + fy * uy < 0.0:
                        continue
                room = ahead - half_length - r - stop_gap
            target = min(target, math.sqrt(2.0 * brake * room) if room > 0.0 else 0.0)
        now = math.sqrt(car_vel[c, 0] ** 2 + car_vel[c, 1] ** 2)
        v = min(target, now + accel * dt)
        v = max(v, now - max_brake * dt, 0.0)
        out[c, 0] = v * ux
        out[c, 1] = v * uy
    return out, at_end


def boxes_overlap(a: NDArray[np.float64], b: NDArray[np.float64], gap: float) -> bool:
    """Whether two convex outlines ``(4, 2)`` come closer than ``gap`` (separating axes, each
    outline grown by ``gap / 2`` along every axis)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / np.hypot(*edges.T)[:, None]
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(axis=0) + gap <= pb.min(axis=0)) | (pb.max(axis=0) + gap <= pa.min(axis=0))):
            return False
    return True


def box_disc_gap(box: NDArray[np.float64], xy: NDArray[np.float64]) -> float:
    """Distance from ``xy`` to a convex outline ``box`` ``(K, 2)`` (counter-clockwise), 0 inside."""
    edges = np.roll(box, -1, axis=0) - box
    rel = xy - box
    if np.all(edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0] >= 0.0):
        return 0.0
    t = np.clip(np.einsum("ij,ij->i", rel, edges) / np.einsum("ij,ij->i", edges, edges), 0.0, 1.0)
    return float(np.min(np.hypot(*(box + t[:, None] * edges - xy).T)))
