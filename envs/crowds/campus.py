"""A university campus: pedestrians on a walkway network, groups by the doors, cars on the road.

One crowd holds every moving obstacle of an outdoor campus, so that ``crowd_size`` (this
crowd's ``count``) is the number of pedestrians and cars together; ``car_share`` of it are
cars (rounded half up), ``group_share`` of the pedestrians stand in conversation groups near
the buildings' doors and the rest walk. Parked cars (``parked``) come on top of ``count``, at
every count but 0: ``crowd_size=0`` is the empty campus, as it means no crowd in every world.

**Members**, in body order: walkers, standing people (group by group), moving cars, parked cars.

**Walkers** follow a network of walkways (:class:`WalkwayConfig`: polylines with a width;
walkways whose end points lie within ``join_m`` of each other meet there). Each walks along
its walkway at its own desired speed (drawn per walker from N(``walk_speed_mps``), clipped to
``walk_speed_range_mps``), keeping to the right of the centre line by its own share of the
free half width (``keep_right``), heading for a point ``lookahead_m`` ahead on its lane. At a
walkway's end it goes on along another walkway meeting there (one drawn at random) or, at a
dead end, turns back. A social force (Helbing and Molnar 1995, with the bodies' surfaces'
distance and a cutoff at ``cutoff_ranges`` times the range, beyond which exp(-d/B) is below
5e-5 of its contact value) keeps walkers off each other, the robot (stronger:
``robot_repulsion_gain``) and the cars' boxes (``car_repulsion_gain``); walls and buildings
are not in it (walkers stay on their walkways; a collision is the physics' job). They give way
to the robot (:func:`envs.crowds.steering.give_way`, as the crowded room's queue heads do) and
do not step into a moving car's path (the car's box stretched over ``yield_s`` of its travel):
one about to wait at the kerb; one already in the road walks on, clearing it.

**Standing people** stand in rings (2-4 people, ``group_sizes`` in turn) facing their group's
centre, ``door_distance_m`` out from a door of a building (the world's ``buildings`` features,
:meth:`~envs.features.scenery.BuildingConfig.door_points`) and ``door_side_m`` to one side of
it, so that the door stays free; they fidget around their spots and walk back when pushed
(as the corridor crowd's groups). Without doors, groups stand beside the walkways.

**Cars** drive along directed lanes (:class:`LaneConfig`, polylines) at ``car_speed_mps``,
steering toward the lane point ``car_lookahead_m`` ahead, accelerating at ``car_accel_mps2``
and braking along the curve ``v = sqrt(2 car_brake_mps2 room)`` (at most
``car_max_brake_mps2``) so as to stop ``car_gap_m`` behind the car ahead and
``car_stop_gap_m`` before a pedestrian or the robot in the corridor ahead of them (the car's
width plus ``car_watch_margin_m`` either side; a pedestrian or robot that will be in it within
``car_watch_s`` at its present velocity counts too). A car within 1 m of its lane's end leaves
the campus (through a gate in the fence) and comes back in at the start of a lane drawn at
random among those whose way in is free, where it could stop ``car_gap_m`` short of anything
at its speed: a teleport (``Commands.teleports``) that turns it along the new lane
(``Commands.headings``) and keeps its speed, so the number of cars stays ``count``'s share and
traffic flows through. While no way in is free it brakes and waits at the end. Between
teleports the world turns cars to face their travel.

**Parked cars** (``parked``: ``(x_m, y_m, heading_rad)`` spots) never move: a parked car the
robot pushes is drawn back to its spot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from numpy.typing import NDArray

from envs.crowds.base import BodySpec, Commands, Crowd, CrowdConfig, Taken, register_crowd
from envs.crowds.corridor import STANDING_FILL, group_ring
from envs.crowds.queues import PEOPLE_FILL
from envs.crowds.steering import give_way, seek
from envs.crowds.walkers import SPEED_CAP
from envs.state import Rows, WorldState
from localizers.schema import ConfigError, check, check_ranges

if TYPE_CHECKING:
    from envs.config import WorldConfig

CAR_FILL = (70, 110, 170)  # moving cars
PARKED_FILL = (120, 130, 140)  # parked cars
_PLACE_GAP_M = 0.05  # free space left between bodies placed at a reset
_PLACE_TRIES = 1000  # random spots tried per walker or group before giving up
_CAR_LEAVE_M = 1.0  # a car this close to its lane's end leaves the campus
_CAR_SIDE_GAP_M = 0.2  # a car keeps behind another whose box comes within this of its own width
_CAR_MIN_COS = 0.25  # a car turning by more than its look-ahead angle slows to cos(angle) of its speed, at least this share
_YIELD_MIN_SPEED_MPS = 0.3  # pedestrians yield only to cars moving faster than this
_YIELD_MARGIN_M = 0.3  # ... keeping this much clear of the car's stretched box, besides their radius
_PARKED_RETURN_MPS = 0.2  # a pushed parked car is drawn back to its spot at most this fast
_EDGE_GAP_M = 0.1  # walkers keep this far inside a walkway's edge
#: body kinds in the cars' view: a disc (the robot, people), a car's box, nothing (a car itself)
_DISC, _BOX, _SKIP = 0, 1, 2


def _round_half_up(x: float) -> int:
    return int(math.floor(x + 0.5))


def _check_polyline(points: tuple[tuple[float, float], ...], where: str) -> None:
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2) if len(points) else np.zeros((0, 2))
    check(pts.shape[0] >= 2, f"{where}.points_m needs at least two points (x, y), got {list(points)!r}")
    check(bool(np.all(np.isfinite(pts))), f"{where}.points_m must be finite, got {list(points)!r}")
    steps = np.hypot(*np.diff(pts, axis=0).T)
    check(bool(np.all(steps > 1e-6)), f"{where}.points_m: consecutive points must differ, got {list(points)!r}")


@dataclass(frozen=True)
class WalkwayConfig:
    """A walkway: its centre line ``points_m`` ``(x, y)`` and its width; walked both ways."""

    points_m: tuple[tuple[float, float], ...]
    width_m: float = 3.0
    name: str = ""

    def __post_init__(self) -> None:
        where = f"walkway {self.name or self.points_m[:1]!r}"
        _check_polyline(self.points_m, where)
        check(
            math.isfinite(self.width_m) and self.width_m > 0,
            f"{where}: width_m must be finite and > 0, got {self.width_m}",
        )


@dataclass(frozen=True)
class LaneConfig:
    """A road lane: its centre line ``points_m`` ``(x, y)`` in driving order."""

    points_m: tuple[tuple[float, float], ...]
    name: str = ""

    def __post_init__(self) -> None:
        _check_polyline(self.points_m, f"lane {self.name or self.points_m[:1]!r}")


@dataclass(frozen=True)
class CampusConfig(CrowdConfig):
    """Pedestrians and cars of a campus (module docstring).

    Attributes:
        count: pedestrians and cars together (``crowd_size``: the moving obstacles); up to
            ``max_count`` (200: sweeps go to 150).
        radius_m, mass_kg: a pedestrian's footprint disc (0.25 m: shoulder half-width, Fruin's
            body ellipse) and weight (70 kg).
        speed_mps: the standing people's top speed, walking back to their spots when pushed.
        car_share: the share of ``count`` that are cars (0.1: a campus road is quiet).
        group_share: the share of the pedestrians standing in groups (0.2: ours; Moussaid et
            al. 2010 find most pedestrians walking in groups, ours stand by the doors).
        walkways: the walkway network; ``join_m``: walkway ends this close meet.
        walk_speed_mps: ``(mean, sd)`` of the walkers' desired speeds (1.3, 0.2 m/s: Bohannon
            1997, Weidmann 1993 give 1.3-1.4 m/s for free walking adults) ...
        walk_speed_range_mps: ... clipped to this (0.8-1.8 m/s).
        keep_right: ``(low, high)``: each walker keeps this share of the free half width
            (half the width less its radius and 0.1 m) right of the centre line, drawn per walker.
        lookahead_m: walkers head for the point of their lane this far ahead.
        end_m: a walker this close to a walkway's end goes on (or back).
        relaxation_s, repulsion_strength_mps2, repulsion_range_m: the social force's tau, A and
            B (0.5 s, 2 m/s^2, 0.3 m: the other crowds'); ``cutoff_ranges``: no force beyond
            this many B of surface distance (10: exp(-10) = 4.5e-5).
        robot_repulsion_gain, car_repulsion_gain: the robot and cars repel this many times as
            strongly as a person.
        give_way, give_way_margin_m, give_way_horizon_s: walkers curve around the robot
            (:func:`~envs.crowds.steering.give_way`).
        yield_s: walkers do not step where a moving car will be within this time (1.5 s).
        group_sizes: standing groups' sizes, in turn (2-4: conversation groups).
        group_spacing_m: neighbours' distance in a group (0.6 m: Hall's personal distance).
        door_distance_m: ``(low, high)``: a group's ring stands this far out from the façade ...
        door_side_m: ``(low, high)``: ... and this far to one side of the door's middle.
        fidget_m, fidget_period_s: standing people shift up to this far from their spots, every
            this many seconds (drawn each time).
        lanes: the road's lanes, directed.
        car_mass_kg: a car's mass (1300 kg: a mid-size hatchback).
        car_speed_mps: the campus speed limit (5.5 m/s, 20 km/h).
        car_accel_mps2: a car's acceleration (2 m/s^2: gentle town driving).
        car_brake_mps2: the braking a car plans with (3 m/s^2: comfortable) ...
        car_max_brake_mps2: ... and the most it brakes (8 m/s^2: full braking on dry asphalt).
        car_gap_m: bumper to bumper behind a stopped car (4 m).
        car_stop_gap_m: bumper to a pedestrian or the robot a car stops for (2.5 m).
        car_watch_margin_m: the corridor a car watches is its width and this either side (0.7 m).
        car_watch_s: a pedestrian or the robot within the corridor this soon counts (1.5 s).
        car_lookahead_m: cars steer toward the lane point this far ahead (8 m).
        parked: ``(x_m, y_m, heading_rad)`` of each parked car.
    """

    shape: str = "person"  # the pedestrians (legs, a torso and a head); cars are car bodies (car:)

    count: int = 30
    max_count: int = 200
    radius_m: float = 0.25
    mass_kg: float = 70.0
    speed_mps: float = 0.5
    car_share: float = 0.1
    group_share: float = 0.2
    walkways: tuple[WalkwayConfig, ...] = ()
    join_m: float = 1.0
    walk_speed_mps: tuple[float, float] = (1.3, 0.2)
    walk_speed_range_mps: tuple[float, float] = (0.8, 1.8)
    keep_right: tuple[float, float] = (0.3, 0.9)
    lookahead_m: float = 2.0
    end_m: float = 1.0
    relaxation_s: float = 0.5
    repulsion_strength_mps2: float = 2.0
    repulsion_range_m: float = 0.3
    cutoff_ranges: float = 10.0
    robot_repulsion_gain: float = 3.0
    car_repulsion_gain: float = 3.0
    give_way: bool = True
    give_way_margin_m: float = 0.3
    give_way_horizon_s: float = 2.0
    yield_s: float = 1.5
    group_sizes: tuple[int, ...] = (3, 2, 4)
    group_spacing_m: float = 0.6
    door_distance_m: tuple[float, float] = (1.5, 4.0)
    door_side_m: tuple[float, float] = (1.5, 6.0)
    fidget_m: float = 0.08
    fidget_period_s: tuple[float, float] = (1.0, 4.0)
    lanes: tuple[LaneConfig, ...] = ()
    car_mass_kg: float = 1300.0
    car_speed_mps: float = 5.5
    car_accel_mps2: float = 2.0
    car_brake_mps2: float = 3.0
    car_max_brake_mps2: float = 8.0
    car_gap_m: float = 4.0
    car_stop_gap_m: float = 2.5
    car_watch_margin_m: float = 0.7
    car_watch_s: float = 1.5
    car_lookahead_m: float = 8.0
    parked: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        super().__post_init__()
        check(self.shape == "person", f"campus.shape must be 'person' (the pedestrians; cars are car bodies), got {self.shape!r}")
        for name in ("car_share", "group_share"):
            value = getattr(self, name)
            check(math.isfinite(value) and 0 <= value <= 1, f"campus.{name} must be in [0, 1], got {value}")
        mean, sd = self.walk_speed_mps
        lo, hi = self.walk_speed_range_mps
        check(
            math.isfinite(mean) and math.isfinite(sd) and mean > 0 and sd >= 0,
            f"campus.walk_speed_mps must be (mean > 0, sd >= 0), got {self.walk_speed_mps}",
        )
        check(
            math.isfinite(hi) and 0 < lo <= hi,
            f"campus.walk_speed_range_mps must be (low, high) with 0 < low <= high, got {self.walk_speed_range_mps}",
        )
        a, b = self.keep_right
        check(0 <= a <= b <= 1, f"campus.keep_right must be (low, high) with 0 <= low <= high <= 1, got {self.keep_right}")
        for name in ("door_distance_m", "door_side_m"):
            a, b = getattr(self, name)
            check(math.isfinite(b) and 0 <= a <= b, f"campus.{name} must be (low, high) with 0 <= low <= high, got {(a, b)}")
        a, b = self.fidget_period_s
        check(
            math.isfinite(b) and 0 < a <= b,
            f"campus.fidget_period_s must be (low, high) with 0 < low <= high, got {self.fidget_period_s}",
        )
        positive = (
            "join_m", "lookahead_m", "end_m", "relaxation_s", "repulsion_range_m", "cutoff_ranges", "give_way_horizon_s",
            "car_mass_kg", "car_speed_mps", "car_accel_mps2", "car_brake_mps2", "car_max_brake_mps2", "car_lookahead_m",
        )  # fmt: skip
        non_negative = (
            "repulsion_strength_mps2", "robot_repulsion_gain", "car_repulsion_gain", "give_way_margin_m", "yield_s",
            "fidget_m", "car_gap_m", "car_stop_gap_m", "car_watch_margin_m", "car_watch_s",
        )  # fmt: skip
        check_ranges(self, "campus", positive=positive, non_negative=non_negative)
        check(
            self.car_brake_mps2 <= self.car_max_brake_mps2,
            f"campus.car_brake_mps2 ({self.car_brake_mps2}) must not exceed car_max_brake_mps2 ({self.car_max_brake_mps2})",
        )
        check(
            len(self.group_sizes) > 0 and all(2 <= n <= 6 for n in self.group_sizes),
            f"campus.group_sizes must be one or more sizes in [2, 6], got {self.group_sizes}",
        )
        check(
            self.group_spacing_m >= 2 * self.radius_m,
            f"campus.group_spacing_m must be >= 2 radius_m ({2 * self.radius_m:g}: people in a group do not overlap), "
            f"got {self.group_spacing_m}",
        )
        for w in self.walkways:
            check(
                w.width_m > 2 * (self.radius_m + _EDGE_GAP_M),
                f"campus: walkway {w.name or w.points_m[:1]!r} width_m {w.width_m} is too narrow for a walker "
                f"(more than 2 (radius_m + {_EDGE_GAP_M}) = {2 * (self.radius_m + _EDGE_GAP_M):g} m)",
            )
        for spot in self.parked:
            check(all(math.isfinite(v) for v in spot), f"campus.parked: spot {spot} must be finite (x_m, y_m, heading_rad)")

    @property
    def split(self) -> tuple[int, tuple[int, ...], int]:
        """``(walkers, group sizes, cars)`` of ``count``: ``round(count car_share)`` cars (half
        up), ``round(people group_share)`` people in groups of ``group_sizes`` in turn (the last
        group takes what is left; one person left over joins the last group, or walks)."""
        cars = _round_half_up(self.count * self.car_share)
        people = self.count - cars
        left = _round_half_up(people * self.group_share)
        sizes: list[int] = []
        while left >= 2:
            size = min(self.group_sizes[len(sizes) % len(self.group_sizes)], left)
            if left - size == 1:
                size += 1
            sizes.append(size)
            left -= size
        return people - sum(sizes), tuple(sizes), cars

    def top_speeds(self) -> tuple[tuple[str, float, float], ...]:
        """Walkers (the social force's cap times the top desired speed), standing people
        (``speed_mps``) and cars (``car_speed_mps``, their footprint box's bounding radius)."""
        return (
            ("walkers", SPEED_CAP * self.walk_speed_range_mps[1], self.radius_m),
            ("standing people", self.speed_mps, self.radius_m),
            ("cars", self.car_speed_mps, self.car.bounding_radius_m),
        )


# ---------------------------------------------------------------------- polylines
class _Polylines:
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
        x, y, tx, ty = _point_at(s, self.pts, self.cum, int(self.first[k]), int(self.n[k]))
        return np.array([x, y]), np.array([tx, ty])


@numba.njit(cache=True)
def _project(px: float, py: float, pts: NDArray[np.float64], cum: NDArray[np.float64], first: int, n: int) -> float:
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
def _point_at(
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


# ---------------------------------------------------------------------- kernels
@numba.njit(cache=True)
def _walk(
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
        s = _project(px, py, pts, cum, first[w], npts[w])
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
                s = _project(px, py, pts, cum, first[w], npts[w])
        goal_s = min(max(s + direction[i] * lookahead, 0.0), length_w)
        gx, gy, tx, ty = _point_at(goal_s, pts, cum, first[w], npts[w])
        tx *= direction[i]
        ty *= direction[i]
        off = keep[i] * max(0.0, half_width[w] - radius - _EDGE_GAP_M)
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
        speed = math.sqrt(vx * vx + vy * vy)
        cap = SPEED_CAP * desired[i]
        if speed > cap:
            vx *= cap / speed
            vy *= cap / speed
        out[i, 0] = vx
        out[i, 1] = vy
    return out


@numba.njit(cache=True)
def _drive(
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
    ``_BOX``: its box's extent along and across the car's way) or ``stop_gap`` before a disc
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
        s = _project(px, py, pts, cum, first[w], npts[w])
        if s >= length[w] - _CAR_LEAVE_M:
            at_end[c] = True
        gx, gy, _, _ = _point_at(s + lookahead, pts, cum, first[w], npts[w])
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
            if k == _SKIP or j == own_row[c]:
                continue
            rx = all_pos[j, 0] - px
            ry = all_pos[j, 1] - py
            ahead = rx * ux + ry * uy
            if ahead < -half_length or ahead > horizon:
                continue
            lateral = -rx * uy + ry * ux
            if k == _BOX:
                cd = abs(math.cos(all_angle[j] - way))
                sd = abs(math.sin(all_angle[j] - way))
                along = half_length * cd + half_width * sd
                across = half_length * sd + half_width * cd
                if abs(lateral) >= half_width + across + _CAR_SIDE_GAP_M:
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


# ---------------------------------------------------------------------- the crowd
@register_crowd("campus", CampusConfig)
class CampusCrowd(Crowd):
    """Walkers, standing people, moving and parked cars (in that body order; module docstring).

    Attributes:
        walkers, standing, cars, parked_count: how many of each; ``sizes``: the groups' sizes.
        way, direction, keep, desired_mps: ``(walkers,)`` each walker's walkway, its direction
            along it (+1: in point order), its share of the free half width kept right, its speed.
        spot: ``(standing, 2)`` where each standing person stands; ``group_of``, ``group_centre``.
        lane: ``(cars,)`` each moving car's lane.
        walkways, lanes: the packed polylines (:class:`_Polylines`).
        doors: ``(D, 4)`` each door's middle, outward heading and half width.
    """

    fill = PEOPLE_FILL
    standing_fill = STANDING_FILL

    def __init__(self, name: str, config: CampusConfig, world: WorldConfig) -> None:
        super().__init__(name, config, world)
        self.c = config
        self.dt_s = world.dt_s
        self.walkers, self.sizes, self.cars = config.split
        self.standing = int(sum(self.sizes))
        self.parked_count = len(config.parked) if config.count > 0 else 0  # none in the empty campus
        self.first_car = self.walkers + self.standing
        self.first_parked = self.first_car + self.cars
        self.size_members(self.first_parked + self.parked_count)
        self.radii_m[self.first_car :] = config.car.bounding_radius_m
        self.member_mass_kg[self.first_car :] = config.car_mass_kg
        self.group_of = np.repeat(np.arange(len(self.sizes)), self.sizes).astype(np.int64)
        self.car_half = np.array([0.5 * config.car.length_m, 0.5 * config.car.width_m])
        self._car_halves = np.tile(self.car_half, (self.count - self.first_car, 1))  # per car, for the walkers' kernel
        self._check_in_field(name, world)
        self._build_network(name, config.join_m)
        self.lanes = _Polylines([np.asarray(lane.points_m, dtype=np.float64) for lane in config.lanes])
        self.doors = self._doors(world)
        if self.walkers and not config.walkways:
            raise ConfigError(f"crowd {name!r}: {self.walkers} walkers need walkways (campus.walkways is empty)")
        if self.cars and not config.lanes:
            raise ConfigError(f"crowd {name!r}: {self.cars} cars need lanes (campus.lanes is empty)")
        if self.sizes and not (self.doors.shape[0] or config.walkways):
            raise ConfigError(f"crowd {name!r}: standing groups need buildings with doors or walkways to stand by")
        self._check_parked(name, np.asarray(config.parked, dtype=np.float64).reshape(-1, 3))
        self.parked_spots = np.asarray(config.parked[: self.parked_count], dtype=np.float64).reshape(-1, 3)
        segments = world.static_segments()
        floor = segments[:, 4] <= 0.0  # what stands on the floor: walls, buildings, poles, trunks
        self._seg = np.ascontiguousarray(segments[floor, :4])
        self._solids = self._solid_edges(world)
        self._clear_state()
        self._gain_key: tuple[int, Any] = (-1, None)
        self._gain = np.ones(0)
        self._kind = np.zeros(0, dtype=np.int64)
        self._start_headings = np.zeros(self.count)

    # ------------------------------------------------------------------ construction
    def _check_in_field(self, name: str, world: WorldConfig) -> None:
        xmin, ymin, xmax, ymax = world.field_m
        lines: list[tuple[str, WalkwayConfig | LaneConfig]] = [(f"walkway {k}", w) for k, w in enumerate(self.c.walkways)]
        lines += [(f"lane {k}", lane) for k, lane in enumerate(self.c.lanes)]
        for label, item in lines:
            pts = np.asarray(item.points_m, dtype=np.float64)
            bad = np.flatnonzero((pts[:, 0] < xmin) | (pts[:, 0] > xmax) | (pts[:, 1] < ymin) | (pts[:, 1] > ymax))
            if bad.size:
                raise ConfigError(
                    f"crowd {name!r}: {label} {item.name!r} point {pts[bad[0]].tolist()} is outside the field of "
                    f"world {world.name!r} (x {xmin:g}..{xmax:g}, y {ymin:g}..{ymax:g})"
                )

    def _check_parked(self, name: str, spots: NDArray[np.float64]) -> None:
        """Every parked spot (at any count) puts its car inside the field, clear of the others."""
        xmin, ymin, xmax, ymax = self.world_config.arena_m
        boxes = [self.c.car.footprint(*spot) for spot in spots]
        for spot, box in zip(spots, boxes):
            if not np.all((box >= (xmin, ymin)) & (box <= (xmax, ymax))):
                raise ConfigError(
                    f"crowd {name!r}: parked spot {tuple(float(v) for v in spot)} puts the car (corners "
                    f"{np.round(box, 2).tolist()}) outside the field of world {self.world_config.name!r} "
                    f"(x {xmin:g}..{xmax:g}, y {ymin:g}..{ymax:g})"
                )
        for a in range(len(boxes)):
            for b in range(a):
                if _boxes_overlap(boxes[a], boxes[b], 0.0):
                    raise ConfigError(
                        f"crowd {name!r}: parked spots {tuple(spots[b].tolist())} and "
                        f"{tuple(spots[a].tolist())} overlap (a car is {self.c.car.length_m} x {self.c.car.width_m} m)"
                    )

    def _build_network(self, name: str, join_m: float) -> None:
        """The walkways packed, their ends' nodes (ends within ``join_m`` are one) and each node's ends."""
        c = self.c
        self.walkways = _Polylines([np.asarray(w.points_m, dtype=np.float64) for w in c.walkways])
        self.half_width = np.array([0.5 * w.width_m for w in c.walkways], dtype=np.float64)
        count = len(c.walkways)
        ends = np.array([self.walkways.line(k)[e] for k in range(count) for e in (0, -1)]).reshape(-1, 2)
        parent = list(range(ends.shape[0]))

        def root(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for a in range(ends.shape[0]):
            for b in range(a):
                if np.hypot(*(ends[a] - ends[b])) <= join_m:
                    parent[root(a)] = root(b)
        roots = sorted({root(i) for i in range(ends.shape[0])})
        index = {r: k for k, r in enumerate(roots)}
        self.node = np.array([index[root(i)] for i in range(ends.shape[0])], dtype=np.int64).reshape(count, 2)
        members = [[(k, e) for k in range(count) for e in (0, 1) if self.node[k, e] == nd] for nd in range(len(roots))]
        self.adj_start = np.concatenate([[0], np.cumsum([len(m) for m in members])]).astype(np.int64)
        self.adj_way = np.array([k for m in members for k, _ in m], dtype=np.int64)
        self.adj_end = np.array([e for m in members for _, e in m], dtype=np.int64)

    def _doors(self, world: WorldConfig) -> NDArray[np.float64]:
        """``(D, 4)``: every building door's middle ``(x, y)``, outward heading and half width."""
        out = []
        for feature in world.features_of_type("buildings").values():
            default = getattr(feature, "facade", None)
            for building in getattr(feature, "items", ()):
                facade = building.facade or default
                half = 0.5 * (facade.door_size_m[0] if facade is not None else 1.8)
                out += [(x, y, heading, half) for x, y, heading in building.door_points()]
        return np.asarray(out, dtype=np.float64).reshape(-1, 4)

    @staticmethod
    def _solid_edges(world: WorldConfig) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
        """The floor-standing solids' edges (start ``(E, 2)``, direction ``(E, 2)``) and each
        solid's first edge ``(K,)``: a point is inside solid k when left of all its edges."""
        starts: list[NDArray[np.float64]] = []
        dirs: list[NDArray[np.float64]] = []
        firsts: list[int] = []
        for feature in world.features.values():
            for solid in feature.solids():
                if solid.bottom_m > 0.0:
                    continue
                corners = solid.corners
                firsts.append(sum(s.shape[0] for s in starts))
                starts.append(corners)
                dirs.append(np.roll(corners, -1, axis=0) - corners)
        if not starts:
            return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
        return np.concatenate(starts), np.concatenate(dirs), np.asarray(firsts, dtype=np.int64)

    def _clear_state(self) -> None:
        w, s, cars = self.walkers, self.standing, self.cars
        self.way = np.zeros(w, dtype=np.int64)
        self.direction = np.ones(w)
        self.keep = np.zeros(w)
        self.desired_mps = np.full(w, self.c.walk_speed_mps[0])
        self.spot = np.zeros((s, 2))
        self.group_centre = np.zeros((len(self.sizes), 2))
        self.fidget = np.zeros((s, 2))
        self.next_fidget_s = np.zeros(s)
        self.lane = np.zeros(cars, dtype=np.int64)

    def bodies(self) -> list[BodySpec]:
        """People (``shape: person``) then cars (``shape: car``, sized by ``car``)."""
        c = self.c
        person = BodySpec("crowd", c.radius_m, c.mass_kg, shape="person", person=c.person)
        car = BodySpec("crowd", c.car.bounding_radius_m, c.car_mass_kg, shape="car", car=c.car)
        return [person] * self.first_car + [car] * (self.count - self.first_car)

    def start_headings(self) -> NDArray[np.float64]:
        return self._start_headings

    # ------------------------------------------------------------------ reset
    def reset(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        self.held[:] = False
        self._clear_state()
        out = np.zeros((self.count, 2))
        headings = np.zeros(self.count)
        boxes: list[NDArray[np.float64]] = []  # the cars' footprints placed so far
        for k, (x, y, heading) in enumerate(self.parked_spots):
            out[self.first_parked + k] = (x, y)
            headings[self.first_parked + k] = heading
            boxes.append(self.c.car.footprint(x, y, heading))
        self._place_cars(rng, taken, boxes, out, headings)
        taken += [(float(x), float(y), float(self.c.car.bounding_radius_m)) for x, y in out[self.first_car :]]
        for g, size in enumerate(self.sizes):
            self.group_centre[g], self.spot[self.group_of == g] = self._place_group(rng, g, size, taken)
        out[self.walkers : self.first_car] = self.spot
        out[: self.walkers] = self._place_walkers(rng, taken)
        self.next_fidget_s = rng.uniform(*self.c.fidget_period_s, size=self.standing)
        self._start_headings = headings
        return out

    def _free(self, xy: NDArray[np.float64], radius: float, taken: Taken) -> bool:
        """Whether a disc at ``xy`` overlaps nothing taken, no floor-standing segment, no solid, and is inside."""
        xmin, ymin, xmax, ymax = self.world_config.arena_m
        if not (xmin + radius <= xy[0] <= xmax - radius and ymin + radius <= xy[1] <= ymax - radius):
            return False
        if taken:
            t = np.asarray(taken, dtype=np.float64)
            if np.any(np.sum((t[:, :2] - xy) ** 2, axis=1) <= (t[:, 2] + radius + _PLACE_GAP_M) ** 2):
                return False
        a, d = self._seg[:, :2], self._seg[:, 2:] - self._seg[:, :2]
        if a.shape[0]:
            t = np.clip(np.einsum("ij,ij->i", xy - a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0.0, 1.0)
            if np.min(np.hypot(*(a + t[:, None] * d - xy).T)) < radius + _PLACE_GAP_M:
                return False
        starts, dirs, firsts = self._solids
        if firsts.size:
            rel = xy - starts
            left = dirs[:, 0] * rel[:, 1] - dirs[:, 1] * rel[:, 0]
            if np.any(np.minimum.reduceat(left, firsts) > 0.0):
                return False
        return True

    def _place_cars(
        self,
        rng: np.random.Generator,
        taken: Taken,
        boxes: list[NDArray[np.float64]],
        out: NDArray[np.float64],
        headings: NDArray[np.float64],
    ) -> None:
        """The moving cars spread evenly along the lanes (by length), a random phase and jitter per lane."""
        c = self.c
        lanes = self.lanes
        if not self.cars:
            return
        usable = np.maximum(lanes.length - _CAR_LEAVE_M, 0.0)
        quota = usable / usable.sum() * self.cars
        per_lane = np.floor(quota).astype(np.int64)
        for k in np.argsort(-(quota - per_lane), kind="stable")[: self.cars - int(per_lane.sum())]:
            per_lane[k] += 1
        need = c.car.length_m + c.car_gap_m
        car = self.first_car
        for k, n in enumerate(per_lane):
            if n == 0:
                continue
            spacing = usable[k] / n
            if spacing < need:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: lane {c.lanes[k].name or k!r} of crowd {self.name!r} "
                    f"({lanes.length[k]:.1f} m) has no room for {n} cars {c.car_gap_m:g} m apart; ask for fewer cars "
                    "(count, car_share) or a shorter car_gap_m"
                )
            for _ in range(100):
                s = rng.uniform(0.0, spacing) + spacing * np.arange(n) + rng.uniform(0.0, spacing - need, size=n)
                s = np.sort(np.mod(s, usable[k]))
                placed = [lanes.at(k, float(v)) for v in s]
                new = [c.car.footprint(p[0], p[1], math.atan2(t[1], t[0])) for p, t in placed]
                if all(self._box_free(box, taken, boxes) for box in new):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free spots on lane {c.lanes[k].name or k!r} for {n} cars of "
                    f"crowd {self.name!r}"
                )
            for (p, t), box in zip(placed, new):
                out[car] = p
                headings[car] = math.atan2(t[1], t[0])
                self.lane[car - self.first_car] = k
                boxes.append(box)
                car += 1

    def _box_free(self, box: NDArray[np.float64], taken: Taken, boxes: list[NDArray[np.float64]]) -> bool:
        """Whether a car footprint ``box`` clears every disc taken and every car placed."""
        if any(_boxes_overlap(box, other, _PLACE_GAP_M) for other in boxes):
            return False
        return all(_box_disc_gap(box, np.array([x, y])) > r + _PLACE_GAP_M for x, y, r in taken)

    def _place_group(
        self, rng: np.random.Generator, g: int, size: int, taken: Taken
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """A free spot for group ``g``: by a door (beside its way out), else beside a walkway."""
        c = self.c
        r = c.radius_m
        for _ in range(_PLACE_TRIES):
            ring = group_ring(size, c.group_spacing_m, rng.uniform(-math.pi, math.pi))
            ring_r = float(np.max(np.hypot(*ring.T))) + r
            side = 1.0 if rng.random() < 0.5 else -1.0
            if self.doors.shape[0]:
                x, y, heading, half = self.doors[rng.integers(self.doors.shape[0])]
                out = np.array([math.cos(heading), math.sin(heading)])
                along = np.array([-out[1], out[0]])
                centre = (
                    np.array([x, y])
                    + out * (rng.uniform(*c.door_distance_m) + ring_r)
                    + along * side * (half + rng.uniform(*c.door_side_m) + ring_r)
                )
            else:
                k = int(rng.choice(len(c.walkways), p=self.walkways.length / self.walkways.length.sum()))
                p, t = self.walkways.at(k, float(rng.uniform(0.0, self.walkways.length[k])))
                centre = p + side * np.array([-t[1], t[0]]) * (self.half_width[k] + ring_r + 0.3)
            people = centre + ring
            if not all(self._free(p, r, taken) for p in people):
                continue
            taken += [(float(px), float(py), r) for px, py in people]
            return centre, people
        raise RuntimeError(
            f"world {self.world_config.name!r}: no room for standing group {g} ({size} people) of crowd {self.name!r}; "
            "ask for fewer people in groups (group_share) or wider door_side_m"
        )

    def _place_walkers(self, rng: np.random.Generator, taken: Taken) -> NDArray[np.float64]:
        """Each walker at a random free spot of a walkway (by length), on its side of the centre line."""
        c = self.c
        w = self.walkers
        out = np.zeros((w, 2))
        if not w:
            return out
        ways = self.walkways
        p_way = ways.length / ways.length.sum()
        mean, sd = c.walk_speed_mps
        self.desired_mps = np.clip(rng.normal(mean, sd, size=w), *c.walk_speed_range_mps)
        self.keep = rng.uniform(*c.keep_right, size=w)
        for i in range(w):
            for _ in range(_PLACE_TRIES):
                k = int(rng.choice(len(p_way), p=p_way))
                direction = 1.0 if rng.random() < 0.5 else -1.0
                p, t = ways.at(k, float(rng.uniform(0.0, ways.length[k])))
                off = self.keep[i] * max(0.0, self.half_width[k] - c.radius_m - _EDGE_GAP_M)
                xy = p + direction * off * np.array([t[1], -t[0]])
                if self._free(xy, c.radius_m, taken):
                    break
            else:
                raise RuntimeError(
                    f"world {self.world_config.name!r}: no free spot on the walkways for walker {i} of crowd {self.name!r} "
                    f"({w} walkers); ask for fewer (count)"
                )
            out[i] = xy
            self.way[i] = k
            self.direction[i] = direction
            taken.append((float(xy[0]), float(xy[1]), c.radius_m))
        return out

    # ------------------------------------------------------------------ every step
    def _views(self, state: WorldState, others: Rows) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """``(M,)`` each of ``others``' repulsion gain for walkers (the robot's, 0 for a car: its
        box repels, 1 for people) and ``(B,)`` each body's kind for the cars (cached)."""
        key = (state.body_count, others if isinstance(others, slice) else others.tobytes())
        if key != self._gain_key:
            rows = np.arange(state.body_count)
            car_rows = np.asarray(self.rows[self.first_car : self.count])
            kind = np.full(state.body_count, _DISC, dtype=np.int64)
            kind[car_rows] = _BOX
            self._kind = kind
            other_rows = rows[others]
            self._gain = np.where(other_rows == 0, self.c.robot_repulsion_gain, np.where(kind[other_rows] == _BOX, 0.0, 1.0))
            self._gain_key = key
        return self._gain, self._kind

    def commands(self, state: WorldState, others: Rows, rng: np.random.Generator) -> Commands:
        c = self.c
        rows = self.member_rows
        pos = state.positions[rows]
        vel = state.velocities[rows]
        angles = state.angles[rows]
        w, fc, fp = self.walkers, self.first_car, self.first_parked
        out = np.zeros((self.count, 2))
        gain, kind = self._views(state, others)
        teleports: tuple[tuple[int, NDArray[np.float64]], ...] = ()
        headings: tuple[tuple[int, float], ...] = ()
        if w:
            ways = self.walkways
            out[:w] = _walk(
                pos[:w], vel[:w], self.desired_mps, self.way, self.direction, self.keep, rng.random(w),
                ways.pts, ways.cum, ways.first, ways.n, ways.length, self.half_width,
                self.node, self.adj_start, self.adj_way, self.adj_end,
                state.positions[others], state.radii_m[others], gain,
                pos[fc:], angles[fc:], vel[fc:], self._car_halves,
                c.radius_m, c.lookahead_m, c.end_m, c.relaxation_s, c.repulsion_strength_mps2, c.repulsion_range_m,
                c.cutoff_ranges * c.repulsion_range_m, c.car_repulsion_gain, c.yield_s, self.dt_s,
            )  # fmt: skip
            if c.give_way:
                out[:w] = give_way(
                    pos[:w], out[:w], self.radii_m[:w], ~self.held[:w], state.positions[0], state.velocities[0],
                    state.robot_radius_m, c.give_way_margin_m, c.give_way_horizon_s,
                )  # fmt: skip
        if self.standing:
            due = state.time_s >= self.next_fidget_s
            if due.any():
                n = int(due.sum())
                angle = rng.uniform(-math.pi, math.pi, size=n)
                reach = c.fidget_m * np.sqrt(rng.random(n))
                self.fidget[due] = reach[:, None] * np.stack([np.cos(angle), np.sin(angle)], axis=1)
                self.next_fidget_s[due] += rng.uniform(*c.fidget_period_s, size=n)
            out[w:fc] = seek(pos[w:fc], self.spot + self.fidget, self.max_speed[w:fc], self.held[w:fc], self.radii_m[w:fc])
        if self.cars:
            lanes = self.lanes
            out[fc:fp], at_end = _drive(
                pos[fc:fp], vel[fc:fp], angles[fc:fp], self.lane, self.held[fc:fp], self.rows[fc:fp],
                lanes.pts, lanes.cum, lanes.first, lanes.n, lanes.length,
                state.positions, state.velocities, state.radii_m, state.angles, kind,
                float(self.car_half[0]), float(self.car_half[1]), c.car_speed_mps, c.car_accel_mps2, c.car_brake_mps2,
                c.car_max_brake_mps2, c.car_gap_m, c.car_stop_gap_m, c.car_watch_margin_m, c.car_watch_s,
                c.car_lookahead_m, self.dt_s,
            )  # fmt: skip
            if at_end.any():
                teleports, headings = self._re_entries(state, np.flatnonzero(at_end), out, rng)
        if self.parked_count:
            back = (self.parked_spots[:, :2] - pos[fp:]) / self.dt_s
            speed = np.hypot(back[:, 0], back[:, 1])
            out[fp:] = back * np.minimum(1.0, _PARKED_RETURN_MPS / np.maximum(speed, 1e-12))[:, None]
        out[self.held] = 0.0
        return Commands(out, None, teleports, headings)

    def _re_entries(
        self, state: WorldState, leaving: NDArray[np.int64], out: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[tuple[tuple[int, NDArray[np.float64]], ...], tuple[tuple[int, float], ...]]:
        """Cars at their lane's end (``leaving``, indices among the moving cars) come back in at the
        start of a lane drawn at random among the free ones, facing along it at their speed; one
        finding none brakes (at ``car_max_brake_mps2``) and waits at the end."""
        c = self.c
        rows = self.member_rows
        pos, vel, angles = state.positions[rows], state.velocities[rows], state.angles[rows]
        cars_xy, cars_heading = pos[self.first_car :].copy(), angles[self.first_car :].copy()  # (updated as cars move)
        moves: list[tuple[int, NDArray[np.float64]]] = []
        turns: list[tuple[int, float]] = []
        for car in leaving:
            i = self.first_car + int(car)
            if self.held[i]:
                continue
            speed = float(np.hypot(*vel[i]))
            for k in rng.permutation(len(c.lanes)):
                p, t = self.lanes.at(int(k), 0.0)
                if self._start_free(state, i, p, t, speed, cars_xy, cars_heading):
                    break
            else:
                out[i] = vel[i] * max(0.0, 1.0 - c.car_max_brake_mps2 * self.dt_s / max(speed, 1e-9))
                continue
            heading = math.atan2(t[1], t[0])
            moves.append((i, p))
            turns.append((i, heading))
            self.lane[int(car)] = int(k)
            cars_xy[i - self.first_car], cars_heading[i - self.first_car] = p, heading
        return tuple(moves), tuple(turns)

    def _start_free(
        self,
        state: WorldState,
        member: int,
        start: NDArray[np.float64],
        tangent: NDArray[np.float64],
        speed: float,
        cars_xy: NDArray[np.float64],
        cars_heading: NDArray[np.float64],
    ) -> bool:
        """Whether a car entering at ``start`` along ``tangent`` at ``speed`` finds its way clear:
        no other car's box (the cars at ``cars_xy``, ``cars_heading``), nor the robot or a person,
        in the strip from just behind it to where it could stop ``car_gap_m`` short
        (``car_stop_gap_m`` for the robot and people)."""
        c = self.c
        hl, hw = float(self.car_half[0]), float(self.car_half[1])
        ahead = hl + max(c.car_gap_m, c.car_stop_gap_m) + speed * speed / (2.0 * c.car_brake_mps2)
        normal = np.array([-tangent[1], tangent[0]]) * (hw + _CAR_SIDE_GAP_M)
        back, front = start - tangent * (hl + 0.5), start + tangent * ahead
        strip = np.array([back - normal, front - normal, front + normal, back + normal])
        centre = 0.5 * (back + front)
        reach = 0.5 * (ahead + hl + 0.5) + hw + c.car.bounding_radius_m
        near = np.flatnonzero(np.hypot(*(cars_xy - centre).T) <= reach)
        for j in near:
            if j + self.first_car == member:
                continue
            if _boxes_overlap(strip, c.car.footprint(float(cars_xy[j, 0]), float(cars_xy[j, 1]), float(cars_heading[j])), 0.0):
                return False
        people = np.concatenate([[0], np.asarray(self.rows[: self.first_car])]).astype(np.int64)
        xy, r = state.positions[people], state.radii_m[people]
        close = np.hypot(*(xy - centre).T) <= reach
        return all(_box_disc_gap(strip, p) > rr for p, rr in zip(xy[close], r[close]))

    # ------------------------------------------------------------------ drawing
    def facing_rad(self, state: WorldState) -> NDArray[np.float64]:
        """``(people,)`` where each person faces: a walker where it walks, a standing person its group's centre."""
        pos = state.positions[self.member_rows]
        vel = state.velocities[self.member_rows]
        w, fc = self.walkers, self.first_car
        out = np.arctan2(vel[:fc, 1], vel[:fc, 0])
        to_centre = self.group_centre[self.group_of] - pos[w:fc]
        out[w:fc] = np.arctan2(to_centre[:, 1], to_centre[:, 0])
        return out

    def draw(self, canvas: Any, state: WorldState) -> None:
        """People as discs (walkers and standing people in two shades) with a tick where they
        face, cars as their footprint boxes (moving and parked in two shades) with a line to the front."""
        rows = self.member_rows
        pos = state.positions[rows]
        facing = self.facing_rad(state)
        for i in range(self.first_car):
            (x, y), r, a = pos[i], float(self.radii_m[i]), float(facing[i])
            canvas.circle(x, y, r, self.fill if i < self.walkers else self.standing_fill, 0)
            canvas.circle(x, y, r, self.outline, 1)
            canvas.line((x, y), (x + r * math.cos(a), y + r * math.sin(a)), self.outline, 1)
        angles = state.angles[rows]
        for i in range(self.first_car, self.count):
            (x, y), heading = pos[i], float(angles[i])
            corners = self.c.car.footprint(float(x), float(y), heading)
            canvas.polygon(corners, CAR_FILL if i < self.first_parked else PARKED_FILL, 0)
            canvas.polygon(corners, self.outline, 1)
            canvas.line(0.5 * (corners[0] + corners[1]), (x, y), self.outline, 1)


def _boxes_overlap(a: NDArray[np.float64], b: NDArray[np.float64], gap: float) -> bool:
    """Whether two convex outlines ``(4, 2)`` come closer than ``gap`` (separating axes, each
    outline grown by ``gap / 2`` along every axis)."""
    for poly in (a, b):
        edges = np.roll(poly, -1, axis=0) - poly
        normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / np.hypot(*edges.T)[:, None]
        pa, pb = a @ normals.T, b @ normals.T
        if np.any((pa.max(axis=0) + gap <= pb.min(axis=0)) | (pb.max(axis=0) + gap <= pa.min(axis=0))):
            return False
    return True


def _box_disc_gap(box: NDArray[np.float64], xy: NDArray[np.float64]) -> float:
    """Distance from ``xy`` to a convex outline ``box`` ``(K, 2)`` (counter-clockwise), 0 inside."""
    edges = np.roll(box, -1, axis=0) - box
    rel = xy - box
    if np.all(edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0] >= 0.0):
        return 0.0
    t = np.clip(np.einsum("ij,ij->i", rel, edges) / np.einsum("ij,ij->i", edges, edges), 0.0, 1.0)
    return float(np.min(np.hypot(*(box + t[:, None] * edges - xy).T)))
