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


@numba.njit(cache=True, inline="always")
def cap_speed(vx: float, vy: float, cap: float) -> tuple[float, float, float]:
    """``(vx, vy)`` scaled down to speed ``cap`` when faster, and the speed it then has."""
    speed = math.sqrt(vx * vx + vy * vy)
    if speed > cap:
        return vx * (cap / speed), vy * (cap / speed), cap
    return vx, vy, speed


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
            vx, vy, _ = cap_speed(vx, vy, max_speed[i])
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
        out[i, 0], out[i, 1] = _pass_tangent(px, py, wx, wy, w2, dist, clearance, speed, robot_v[0], robot_v[1])
    return out


@numba.njit(cache=True)
def _pass_tangent(
    px: float, py: float, wx: float, wy: float, w2: float, dist: float, clearance: float, speed: float, rvx: float, rvy: float
) -> tuple[float, float]:
    """The ground velocity that turns the relative velocity ``(wx, wy)`` (``w2``: its square) of a
    member ``(px, py)`` short of the robot (``dist`` away, moving at ``(rvx, rvy)``) to the tangent
    of the clearance circle, on the side it passes now, at the same relative speed and never
    faster than ``speed`` over the ground (:func:`give_way`, :func:`see_robot`)."""
    side = 1.0 if px * wy - py * wx >= 0.0 else -1.0  # w to the left (+) or right (-) of the robot
    tangent = math.asin(clearance / dist)
    base = math.atan2(py, px) + side * tangent
    w = math.sqrt(w2)
    vx = w * math.cos(base) + rvx
    vy = w * math.sin(base) + rvy
    vx, vy, _ = cap_speed(vx, vy, speed)  # never faster than it wanted to walk
    return vx, vy


# People who see the robot (:func:`see_robot`; the people crowds' ``sees_robot`` share,
# :class:`envs.crowds.base.PeopleConfig`). The social force has Helbing and Molnar's form with
# the body surfaces' distance and a weight for what lies behind (Helbing, Farkas and Vicsek 2000,
# with the anisotropy of Helbing and Johansson's "circular specification"); its parameters are
# those fitted to video tracking of pedestrians:
SEE_FORCE_MPS2 = 0.42  # A: Johansson, Helbing and Shukla 2007 (Adv. Complex Syst. 10, 271), circular specification
SEE_RANGE_M = 1.65  # B: the same fit
SEE_BEHIND = 0.12  # lambda: the same fit (a robot behind weighs 0.12 of one ahead)
SEE_HORIZON_S = 3.0  # people react to a contact this soon: Karamouzas, Skinner and Guy 2014 (PRL 113, 238701), tau0 ~ 3 s
SEE_GAP_M = 0.45  # ... passing with this much between the bodies: Hall 1966 (The Hidden Dimension), intimate distance 18 in
SEEK_RELAXATION_S = 0.5  # tau of the social-force model (Helbing and Molnar 1995): see_robot's force_s for seeking crowds


def draw_seers(rng: np.random.Generator, count: int, share: float) -> NDArray[np.bool_]:
    """``(count,)`` which members see the robot this episode: each with probability ``share``.

    Drawn from a child of ``rng`` (:meth:`numpy.random.Generator.spawn`), which leaves ``rng``'s
    own draws as they were, and only for a share strictly between 0 and 1: 0 (nobody, the
    invisible robot) and 1 (everyone) draw nothing. A member who sees at one share also sees at
    any larger share with the same seed (one uniform number per member, compared with the share).
    """
    if share <= 0.0:
        return np.zeros(count, dtype=np.bool_)
    if share >= 1.0:
        return np.ones(count, dtype=np.bool_)
    return rng.spawn(1)[0].random(count) < share


@numba.njit(cache=True)
def _contact_time(px: float, py: float, wx: float, wy: float, clearance: float) -> float:
    """Seconds until a member ``(px, py)`` short of the robot, moving at ``(wx, wy)`` relative to
    it, comes within ``clearance`` of its centre (inf: never)."""
    w2 = wx * wx + wy * wy
    closing = px * wx + py * wy
    if w2 < 1e-12 or closing <= 0.0:
        return math.inf
    disc = closing * closing - w2 * (px * px + py * py - clearance * clearance)
    if disc <= 0.0:
        return math.inf
    return max((closing - math.sqrt(disc)) / w2, 0.0)


@numba.njit(cache=True)
def see_robot(
    pos: NDArray[np.float64],
    want: NDArray[np.float64],
    radii: NDArray[np.float64],
    sees: NDArray[np.bool_],
    top_speed: NDArray[np.float64],
    robot_xy: NDArray[np.float64],
    robot_v: NDArray[np.float64],
    robot_radius: float,
    force_s: float,
) -> NDArray[np.float64]:
    """Velocities ``(N, 2)``: ``want`` for members who do not see the robot, and for those who do
    (``sees``) how a pedestrian reacts to a robot it sees (CrowdNav's "visible robot").

    1. A social force from the robot's disc (Helbing and Molnar's form),
       ``F = A exp(-g / B) (lambda + (1 - lambda)(1 + cos phi) / 2) n``, ``g`` the gap between
       the bodies, ``n`` the unit vector from the robot to the member, ``phi`` the angle between
       where the member walks and the robot (``SEE_FORCE_MPS2``, ``SEE_RANGE_M``,
       ``SEE_BEHIND``). It changes the velocity by ``force_s F``: the step ``dt`` for a crowd
       whose ``want`` already integrates a social force (the force acts every step), the
       relaxation time ``SEEK_RELAXATION_S`` for one that seeks a target afresh every step (the
       velocity the relaxation settles at under ``F``). Speeds stay within ``top_speed``.
    2. When contact would come within ``SEE_HORIZON_S`` (closer than the clearance, the bodies'
       radii and ``SEE_GAP_M``), the member steps aside: its velocity relative to the robot
       turns to the tangent of the clearance circle (as :func:`give_way`); if it would still touch
       the robot that soon (a robot coming at it faster than it walks), it slows in proportion to
       the time left to contact, down to waiting. One already inside the clearance stops closing in.
    """
    n = pos.shape[0]
    out = want.copy()
    lam = SEE_BEHIND
    for i in range(n):
        if not sees[i]:
            continue
        px = robot_xy[0] - pos[i, 0]
        py = robot_xy[1] - pos[i, 1]
        dist = math.sqrt(px * px + py * py)
        if dist < 1e-9:
            continue
        vx = want[i, 0]
        vy = want[i, 1]
        speed = math.sqrt(vx * vx + vy * vy)
        cos_phi = (px * vx + py * vy) / (dist * speed) if speed > 1e-9 else 1.0
        gap = max(dist - radii[i] - robot_radius, 0.0)
        push = force_s * SEE_FORCE_MPS2 * math.exp(-gap / SEE_RANGE_M) * (lam + (1.0 - lam) * 0.5 * (1.0 + cos_phi))
        vx -= push * px / dist
        vy -= push * py / dist
        vx, vy, speed = cap_speed(vx, vy, top_speed[i])
        clearance = radii[i] + robot_radius + SEE_GAP_M
        wx = vx - robot_v[0]
        wy = vy - robot_v[1]
        if dist <= clearance:
            closing = (px * wx + py * wy) / (dist * dist)
            if closing > 0.0:  # inside the clearance: no nearer (it backs off from a robot driving at it)
                vx -= closing * px
                vy -= closing * py
                vx, vy, _ = cap_speed(vx, vy, top_speed[i])
        elif _contact_time(px, py, wx, wy, clearance) < SEE_HORIZON_S:
            vx, vy = _pass_tangent(px, py, wx, wy, wx * wx + wy * wy, dist, clearance, speed, robot_v[0], robot_v[1])
            left = _contact_time(px, py, vx - robot_v[0], vy - robot_v[1], radii[i] + robot_radius)
            if left < SEE_HORIZON_S:  # stepping aside does not avoid touching it: slow down, or wait
                vx *= left / SEE_HORIZON_S
                vy *= left / SEE_HORIZON_S
        out[i, 0] = vx
        out[i, 1] = vy
    return out
