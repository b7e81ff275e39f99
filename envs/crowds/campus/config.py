"""The campus crowd's configuration: its walkways, its lanes and the crowd's numbers.

:class:`CampusConfig` is what a world YAML's ``crowds: {campus: {type: campus, ...}}`` loads
into (the behaviour it sets is described in :mod:`envs.crowds.campus`); :class:`WalkwayConfig`
and :class:`LaneConfig` are the polylines the walkers and the cars follow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from core.schema import check, check_ranges
from envs.crowds.base import PeopleConfig
from envs.crowds.walkers import SPEED_CAP

EDGE_GAP_M = 0.1  # walkers keep this far inside a walkway's edge


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
class CampusConfig(PeopleConfig):
    """Pedestrians and cars of a campus (:mod:`envs.crowds.campus`).

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
        sees_robot: the share of the pedestrians (walkers and standing people) who see the robot
            and react to it (:class:`~envs.crowds.base.PeopleConfig`; 1: everyone, as in every crowd of people).
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
                w.width_m > 2 * (self.radius_m + EDGE_GAP_M),
                f"campus: walkway {w.name or w.points_m[:1]!r} width_m {w.width_m} is too narrow for a walker "
                f"(more than 2 (radius_m + {EDGE_GAP_M}) = {2 * (self.radius_m + EDGE_GAP_M):g} m)",
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
