"""``route_follower``: drive a world's route (a ``route`` feature of its map) from the localizer's estimate.

The far-landmark stereo paper's robot drives a route of about 100 m across a campus; this is
that drive, done from the observation alone: the localizer's estimate behind
:class:`~envs.wrappers.LocalizationObservation` (never the truth) and, to keep clear of
people and cars, a range sensor (a ``lidar`` entry, or a ``sonar`` ring, or none).

**Path.** Pure pursuit (Coulter 1992) along the route's polyline: the progress ``s`` is the
arc length of the route point nearest the estimate, searched from the last progress up to
``search_ahead_m`` ahead and never decreasing (a route passing near itself cannot send the
robot back); the robot steers on the circle through the route point ``lookahead_m`` beyond
``s`` (curvature ``2 y / L^2``, the point at ``(x, y)`` in the robot's frame, ``L`` its
distance), at ``cruise`` (action units), slower where the circle needs more than the turn-rate
limit. With that point more than ``turn_in_place_rad`` off the heading it turns in place first.
Over the last ``slow_down_m`` the speed falls linearly (not below ``creep``), the last step
sized to land on the end; within ``arrive_m`` of it the drive is done and the robot stands
still for good (a world's ``goal`` there then ends the episode). The forward speed rises by
at most ``max_accel_mps2`` (braking is immediate).

**Looking around first** (``look_around_turns > 0``; ``look_then_route`` turns twice): before
anything else the robot turns in place at its turn-rate limit through that many full turns, so that
a localizer that starts without a pose (global localization) sees the whole room before the robot
commits to its estimate and drives by it (ours: in the crowded room the first scan often fits a
pose turned about the room's centre better than the truth, and the turns give the filter the scans
that tell them apart).

**Without an estimate** (the localizer claims none) the robot stands still and waits; with
``coast_s > 0`` it first keeps its last command for that long.

**Obstacles.** Each reading of the range sensor short of its maximum range is a point in the
robot's frame (a sonar's reading: points across its cone). The corridor ahead is the circle
the robot is about to drive, ``robot_radius_m + side_margin_m`` either side of it; the gap to an
obstacle is its distance along that circle less the robot's radius. A gap under ``slow_m``
slows the robot (linearly, to zero at ``stop_m``); under ``stop_m`` it stops and waits, and it
drives on once the gap exceeds ``stop_m + resume_m``. It does not swerve (pure pursuit steers
back to the route); people give way to a robot (the campus crowd's walkers do).

What it did is in attributes: :attr:`~RouteFollower.progress_m`, :attr:`~RouteFollower.phase`
and :attr:`~RouteFollower.blocked_steps` (steps spent waiting for the way to clear).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import ArrayLike, NDArray

from agents.policies.base import FixedPolicy, Observation, check_command, read_estimate
from core.geometry import polyline_point, ring_directions
from core.schema import is_int, is_real

#: the states of :attr:`RouteFollower.phase`
PHASES = ("look", "wait", "drive", "done")


@dataclass(frozen=True)
class RouteParams:
    """The settings of :class:`RouteFollower` (module docstring), each with its default.

    Speeds are in action units (fractions of the env's limits) unless named ``_mps``, distances
    in metres, times in seconds, angles in radians.

    Attributes:
        dt_s: the env's time step (the last step before the end is sized to land on it; timers).
        max_speed_mps, max_turn_rate_rps: the env's limits (commands are computed in m/s and rad/s).
        cruise: forward speed along the route (1.0: the campus robot's 1 m/s; the paper gives none).
        max_turn: the fastest turn (action units: a fraction of the env's turn-rate limit; 1.0). Below 1
            the robot slows in bends so that it turns no faster (a scene map's drive on free-running
            webcams, :class:`agents.experiments.scene_maps.MappingDrive`).
        creep: the slowest forward speed while moving toward the end (0.05).
        lookahead_m: the pure-pursuit look-ahead (1.5 m: 1.5 s at 1 m/s; tracks a 3 m radius turn
            within a few centimetres, and dead-reckoning noise without weaving).
        search_ahead_m: the progress is searched this far ahead of the last (5 m: a few steps' travel and more).
        turn_in_place_rad: the look-ahead point farther than this off the heading: turn in place (0.8).
        turn_gain: turn rate per radian of heading error while turning in place (2 per s).
        slow_down_m: the speed falls linearly to ``creep`` over the route's last this many metres (2 m).
        arrive_m: within this of the route's end the drive is done (5 cm).
        max_accel_mps2: the forward speed rises by at most this (0.5 m/s^2: gentle on wheels and odometry).
        robot_radius_m: the robot's radius (``make_policy`` reads the world's; 0.3 m).
        side_margin_m: the corridor watched for obstacles is this wider than the robot either side (0.3 m).
        slow_m: an obstacle in the corridor nearer than this (gap from the robot's surface) slows
            the robot (3 m: 3 s at cruise) ...
        stop_m: ... and nearer than this stops it (0.8 m: a person's personal distance, room to brake).
        resume_m: a stopped robot drives on once the gap exceeds ``stop_m`` by this (0.2 m).
        coast_s: without an estimate the last command is kept this long before standing still (0: at once).
        look_around_turns: full turns in place before anything else (0: none; ``look_then_route``: 2).
        sonar_cone_rad: a sonar's cone (``make_policy`` reads the world's; 22.5 deg).
        sonar_rays: points across each sonar cone a reading stands for (5).

    Raises:
        ValueError: for a bad value, naming it.
    """

    dt_s: float = 0.1
    max_speed_mps: float = 1.0
    max_turn_rate_rps: float = 1.0
    cruise: float = 1.0
    max_turn: float = 1.0
    creep: float = 0.05
    lookahead_m: float = 1.5
    search_ahead_m: float = 5.0
    turn_in_place_rad: float = 0.8
    turn_gain: float = 2.0
    slow_down_m: float = 2.0
    arrive_m: float = 0.05
    max_accel_mps2: float = 0.5
    robot_radius_m: float = 0.3
    side_margin_m: float = 0.3
    slow_m: float = 3.0
    stop_m: float = 0.8
    resume_m: float = 0.2
    coast_s: float = 0.0
    look_around_turns: float = 0.0
    sonar_cone_rad: float = 2 * math.pi / 16
    sonar_rays: int = 5

    #: the settings that may be 0
    _MAY_BE_ZERO: ClassVar[tuple[str, ...]] = ("side_margin_m", "resume_m", "coast_s", "stop_m", "look_around_turns")

    def __post_init__(self) -> None:
        where = "RouteFollower"
        for f in fields(self):
            value = getattr(self, f.name)
            number = is_real(value, finite=True)
            if f.name == "sonar_rays":
                if not (is_int(value) and value >= 1):
                    raise ValueError(f"{where} sonar_rays must be a whole number >= 1, got {value!r}")
            elif f.name in self._MAY_BE_ZERO:
                if not (number and value >= 0):
                    raise ValueError(f"{where} {f.name} must be a number >= 0, got {value!r}")
            elif not (number and value > 0):
                raise ValueError(f"{where} {f.name} must be a number > 0, got {value!r}")
        for name in ("cruise", "creep", "max_turn"):
            check_command(f"{where} {name}", getattr(self, name))
        if self.creep > self.cruise:
            raise ValueError(f"{where} needs creep ({self.creep}) at most cruise ({self.cruise})")
        if self.stop_m >= self.slow_m:
            raise ValueError(
                f"{where} needs stop_m ({self.stop_m}) below slow_m ({self.slow_m}): else there is no room to slow down"
            )
        if self.turn_in_place_rad >= math.pi:
            raise ValueError(f"{where} turn_in_place_rad must be below pi, got {self.turn_in_place_rad}")


class RouteFollower(FixedPolicy):
    """Pure pursuit along a route from the localizer's estimate, stopping for obstacles (module docstring).

    Args:
        action_space: the env's ``Box(-1, 1, (2,))``.
        route_m: the route's points ``(P, 2)`` in driving order (the map's ``route`` feature).
        bounds_m: the field ``(xmin, ymin, xmax, ymax)`` the estimate is normalized to.
        seed: unused (the policy is deterministic); kept for the common signature.
        beam_angles_rad: the ``lidar`` entry's beam directions relative to the heading (None:
            the observation's ``lidar`` is not read).
        max_range_m: the range sensor's maximum range (its readings there hit nothing).
        **params: the settings, by name (:class:`RouteParams`).

    Attributes:
        params: the :class:`RouteParams` in use.
        route: ``(P, 2)``; ``length_m``: its length.
        progress_m: the arc length reached along the route (None before the first estimate).
        phase: ``"look"`` (turning in place first), ``"wait"`` (no estimate yet), ``"drive"`` or ``"done"``.
        blocked_steps: steps it stood still for an obstacle this episode.

    Raises:
        ValueError: for an unknown setting, a bad value or a bad route, naming it.
    """

    needs_feature = "route"  # it drives the route of the world's map

    #: the observation keys of the range sensors it reads, in order of preference
    lidar_key: ClassVar[str] = "lidar"
    sonar_key: ClassVar[str] = "sonar"

    def __init__(
        self,
        action_space: spaces.Box,
        route_m: ArrayLike,
        bounds_m: tuple[float, float, float, float],
        seed: int | None = None,
        *,
        beam_angles_rad: ArrayLike | None = None,
        max_range_m: float = math.inf,
        **params: Any,
    ) -> None:
        super().__init__(action_space, seed)
        known = {f.name for f in fields(RouteParams)}
        unknown = sorted(set(params) - known)
        if unknown:
            raise ValueError(
                f"RouteFollower has no setting {', '.join(map(repr, unknown))} (settings: {', '.join(sorted(known))})"
            )
        self.params = RouteParams(**params)
        route = np.asarray(route_m, dtype=np.float64)
        if route.ndim != 2 or route.shape[0] < 2 or route.shape[1] != 2 or not np.all(np.isfinite(route)):
            raise ValueError(
                f"RouteFollower needs a route of at least two finite points (x, y), got {np.asarray(route_m).tolist()!r}"
            )
        steps = np.hypot(*np.diff(route, axis=0).T)
        if np.any(steps <= 1e-9):
            raise ValueError(f"RouteFollower: the route's consecutive points must differ, got {route.tolist()}")
        self.route = route
        self._cum = np.concatenate([[0.0], np.cumsum(steps)])
        self.length_m = float(self._cum[-1])
        if len(bounds_m) != 4:
            raise ValueError(f"RouteFollower bounds_m must be (xmin, ymin, xmax, ymax), got {bounds_m!r}")
        xmin, ymin, xmax, ymax = (float(b) for b in bounds_m)
        self.bounds_m = (xmin, ymin, xmax, ymax)
        self.beam_angles_rad = None if beam_angles_rad is None else np.asarray(beam_angles_rad, dtype=np.float64).reshape(-1)
        if not max_range_m > 0:
            raise ValueError(f"RouteFollower max_range_m must be > 0, got {max_range_m!r}")
        self.max_range_m = float(max_range_m)
        self._sonar_dirs: NDArray[np.float64] | None = None
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        super().reset(seed)
        self.progress_m: float | None = None
        p = self.params
        self._look_steps = math.ceil(p.look_around_turns * 2 * math.pi / (self._turn_limit_rps * p.dt_s) - 1e-9)
        self.phase = "look" if self._look_steps else "wait"
        self.blocked_steps = 0
        self._speed_mps = 0.0  # the last forward command
        self._last = np.zeros(2)
        self._lost_s = 0.0
        self._blocked = False

    # ------------------------------------------------------------------ the route
    def point_at(self, s: float) -> NDArray[np.float64]:
        """``(2,)`` the route point at arc length ``s`` (clamped to the route)."""
        return polyline_point(self.route, self._cum, s)

    def project(self, xy: NDArray[np.float64], low_m: float = 0.0, high_m: float = math.inf) -> float:
        """The arc length, within ``[low_m, high_m]``, of the route point nearest ``xy``."""
        a, b = self.route[:-1], self.route[1:]
        d = b - a
        t = np.clip(np.einsum("ij,ij->i", xy - a, d) / np.einsum("ij,ij->i", d, d), 0.0, 1.0)
        s = np.clip(self._cum[:-1] + t * (self._cum[1:] - self._cum[:-1]), low_m, high_m)
        # the nearest among each segment's nearest point within the window
        points = np.array([self.point_at(v) for v in s])
        return float(s[int(np.argmin(np.hypot(*(points - xy).T)))])

    # ------------------------------------------------------------------ sensing
    def obstacle_points(self, observation: Observation) -> NDArray[np.float64]:
        """``(K, 2)`` what the range sensor sees, in the robot's frame (x ahead, y left)."""
        if self.beam_angles_rad is not None and self.lidar_key in observation:
            ranges = np.asarray(observation[self.lidar_key], dtype=np.float64).reshape(-1)
            if ranges.size != self.beam_angles_rad.size:
                raise ValueError(
                    f"RouteFollower: the {self.lidar_key!r} entry has {ranges.size} readings, its beam_angles_rad "
                    f"{self.beam_angles_rad.size}"
                )
            angles = self.beam_angles_rad
        elif self.sonar_key in observation:
            ranges = np.asarray(observation[self.sonar_key], dtype=np.float64).reshape(-1)
            if self._sonar_dirs is None or self._sonar_dirs.size != ranges.size * self.params.sonar_rays:
                offsets = np.linspace(-0.5, 0.5, self.params.sonar_rays) * self.params.sonar_cone_rad
                self._sonar_dirs = (ring_directions(ranges.size)[:, None] + offsets[None]).reshape(-1)
            ranges = np.repeat(ranges, self.params.sonar_rays)
            angles = self._sonar_dirs
        else:
            return np.zeros((0, 2))
        hit = ranges < 0.999 * self.max_range_m
        return np.stack([ranges[hit] * np.cos(angles[hit]), ranges[hit] * np.sin(angles[hit])], axis=1)

    def gap_ahead(self, points: NDArray[np.float64], curvature: float) -> float:
        """The gap (m, from the robot's surface) to the nearest of ``points`` in the corridor along
        the circle of ``curvature`` (1/m, left positive); inf when none is."""
        p = self.params
        half = p.robot_radius_m + p.side_margin_m
        x, y = points[:, 0], points[:, 1]
        if abs(curvature) < 1e-6:
            along, off = x, np.abs(y)
        else:
            r = 1.0 / curvature  # the centre at (0, r)
            off = np.abs(np.hypot(x, y - r) - abs(r))
            swept = np.mod(np.arctan2(x, np.sign(r) * (r - y)), 2 * math.pi)  # angle travelled along the circle
            swept = np.where(swept > math.pi, swept - 2 * math.pi, swept)
            along = abs(r) * swept
        inside = (off < half) & (along > 0.0)
        if not inside.any():
            return math.inf
        return float(np.min(along[inside])) - p.robot_radius_m

    # ------------------------------------------------------------------ acting
    def _act(self, observation: Observation) -> NDArray[np.float64]:
        p = self.params
        pose = read_estimate(observation, self.bounds_m, type(self).__name__)
        if self._look_steps:
            self._look_steps -= 1
            self.phase = "look" if self._look_steps else "wait"
            return self._command(0.0, self._turn_limit_rps)
        if self.phase == "done":
            return np.zeros(2)
        if pose is None:
            self._lost_s += p.dt_s
            if self.phase == "drive" and self._lost_s <= p.coast_s + 1e-9:
                return self._last.copy()
            self._speed_mps = 0.0
            self._last = np.zeros(2)
            return np.zeros(2)
        self._lost_s = 0.0
        xy = pose[:2]
        if self.progress_m is None:
            self.progress_m = self.project(xy)
            self.phase = "drive"
        else:
            self.progress_m = max(self.progress_m, self.project(xy, self.progress_m, self.progress_m + p.search_ahead_m))
        remaining = self.length_m - self.progress_m
        end_gap = float(np.hypot(*(self.route[-1] - xy)))
        if remaining <= p.arrive_m or end_gap <= p.arrive_m:
            self.phase = "done"
            self._last = np.zeros(2)
            return np.zeros(2)
        target = self.point_at(self.progress_m + p.lookahead_m)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        dx, dy = target - xy
        x, y = c * dx + s * dy, -s * dx + c * dy  # in the robot's frame
        distance = math.hypot(x, y)
        bearing = math.atan2(y, x)
        if abs(bearing) > p.turn_in_place_rad:
            self._speed_mps = 0.0
            rate = float(np.clip(p.turn_gain * bearing, -self._turn_limit_rps, self._turn_limit_rps))
            return self._command(0.0, rate)
        curvature = 2.0 * y / (distance * distance) if distance > 1e-9 else 0.0
        # the speed: cruise, toward the end slower and landing on it, within the turn-rate limit
        speed = p.cruise * p.max_speed_mps
        left = min(remaining, end_gap)
        speed = min(speed, max(p.creep * p.max_speed_mps, speed * min(1.0, left / p.slow_down_m)), left / p.dt_s)
        if abs(curvature) > 1e-9:
            speed = min(speed, self._turn_limit_rps / abs(curvature))
        gap = self.gap_ahead(self.obstacle_points(observation), curvature)
        clear = p.stop_m + (p.resume_m if self._blocked else 0.0)
        self._blocked = gap <= clear
        if self._blocked:
            self.blocked_steps += 1
            self._speed_mps = 0.0
            return self._command(0.0, 0.0)
        if gap < p.slow_m:
            speed = min(speed, p.cruise * p.max_speed_mps * (gap - p.stop_m) / (p.slow_m - p.stop_m))
        speed = min(speed, self._speed_mps + p.max_accel_mps2 * p.dt_s)
        self._speed_mps = speed
        return self._command(speed, speed * curvature)

    @property
    def _turn_limit_rps(self) -> float:
        """The fastest turn it commands, rad/s (``max_turn`` of the env's limit)."""
        return self.params.max_turn * self.params.max_turn_rate_rps

    def _command(self, speed_mps: float, rate_rps: float) -> NDArray[np.float64]:
        p = self.params
        action = np.array([np.clip(speed_mps / p.max_speed_mps, -1.0, 1.0), np.clip(rate_rps / p.max_turn_rate_rps, -1.0, 1.0)])
        self._last = action
        return action.copy()


class LookThenRoute(RouteFollower):
    """``look_then_route``: :class:`RouteFollower` that first turns in place twice (``look_around_turns=2``).

    The fixed policy for a route driven from an unknown start (the crowded room's task): two turns
    at the turn-rate limit (8.4 s in the room) let a global localizer see the room twice over before
    the drive. On the room task's seeds 0-11 (``prior: none``, the task's return over 40 s) it
    scores -51.1 at crowd 16 and -125.0 at crowd 30, against -78.2 and -155.9 for ``route_follower``
    and -77.7 and -146.8 for ``spin``. Two turns: under the task's earlier reward (a wrong pose by
    position alone) one, two and three turns scored -47.1, -44.6 and -39.5 at crowd 16 and -142.4,
    -119.0 and -119.0 at crowd 30 (one is too few at crowd 30, where people hide parts of the room;
    a third adds little). Its lead over ``spin`` does not hold up on more seeds: on 60 others the
    paired difference in return is +6.8 [-3.1, 15.0] at crowd 16 and +12.0 [-9.3, 32.4] at 30, within
    the noise (the first scan decides most of a room episode; ``models/README.md``).
    """

    def __init__(self, *args: Any, **params: Any) -> None:
        params.setdefault("look_around_turns", 2.0)
        super().__init__(*args, **params)


def route_points(world: Any, features: Mapping[str, Mapping[str, Any]], name: str | None = None) -> NDArray[np.float64]:
    """The points of the world's route from the map (``name``: which, where it has several).

    Raises:
        ValueError: for a world without a route feature, or with several and no ``name``.
    """
    routes = [key for key, data in features.items() if data.get("type") == "route"]
    if name is None and len(routes) == 1:
        name = routes[0]
    if name not in routes:
        raise ValueError(
            f"route_follower drives a route of the map: world {world.name!r} has "
            + (f"routes {', '.join(routes)}; name one (route=...)" if routes else "no route feature (features: type route)")
            + (f"; it has no route {name!r}" if name is not None and routes else "")
        )
    return np.asarray(features[name]["points_m"], dtype=np.float64)


def range_sensor_kwargs(metadata: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """The beam angles and maximum range of the sensor writing the ``lidar`` entry (else the
    ``sonar`` ring's range), from the env's sensor metadata."""
    by_key = {meta.get("key"): meta for meta in metadata.values()}
    if RouteFollower.lidar_key in by_key:
        meta = by_key[RouteFollower.lidar_key]
        return {"beam_angles_rad": np.asarray(meta["beam_angles_rad"]), "max_range_m": float(meta["max_range_m"])}
    if RouteFollower.sonar_key in by_key:
        return {"max_range_m": float(by_key[RouteFollower.sonar_key]["max_range_m"])}
    return {}
