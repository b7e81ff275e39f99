"""World configurations: frozen dataclasses loaded from ``configs/worlds/<name>.yaml``.

The sensors, crowds and features are mappings from name to a config tagged by ``type``; each
plug-in module owns its config dataclass and registers it (:mod:`envs.plugins`). This module
imports only the plug-ins' ``base`` modules and asks their registries for the tagged class
(through the base config's ``__from_config__`` hook), so it names no plug-in: a new sensor,
crowd or feature is a new module. Importing a ``base`` module imports its package first, whose
``__init__`` registers the built-in types, so a process that only imports this module still
knows them when it loads a world.

Every unit is in the field name (``_m``, ``_rad``, ``_s``, ``_mps``). Loading goes through
:func:`core.schema.from_mapping`, which rejects unknown keys and wrong types with
the key and the file in the message; ranges are checked in ``__post_init__``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from numbers import Integral, Real
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray

import crowdloc_configs
from core.schema import ConfigError, check, check_ranges, from_mapping, is_real, load_yaml
from envs.crowds.base import CrowdConfig
from envs.features.base import FeatureConfig, Segment
from envs.floor import FloorGrid, floor_grid
from envs.sensors.base import SensorConfig
from envs.view import (
    BACKGROUND_PAD_PX,
    CAPTION_PX,
    FRAME_LONG_SIDE_PX,
    MARGIN_PX,
    MAX_BACKGROUND_PX,
    background_size_px,
    drawn_bounds,
    fit,
)

#: the first this-many rows of :meth:`WorldConfig.wall_segments` are the arena boundary
BOUNDARY_SEGMENTS = 4
#: the half thickness of an interior wall (and a floor-standing piece of furniture's side) in the physics
WALL_RADIUS_M = 0.02
CONFIG_DIR = crowdloc_configs.path()  # package data (configs/ in the checkout)
WORLD_DIR = CONFIG_DIR / "worlds"


@dataclass(frozen=True)
class LandmarkConfig:
    """A map feature a localizer knows: a pole seen by the bearing camera, or another kind.

    ``kind`` says what it is (``"pole"``: a pole landmark; later papers add ceiling targets
    and building edges); ``collides`` whether it is a physical obstacle (a pole is; a target
    on the ceiling or an edge far away need not be).
    """

    #: the fields that may be ``inf`` (:func:`non_finite_numbers`): no range limit
    unbounded_fields: ClassVar[frozenset[str]] = frozenset({"max_range_m"})

    name: str
    x_m: float
    y_m: float
    radius_m: float = 0.05
    max_range_m: float = math.inf  # beyond this the camera cannot detect it (small poles)
    kind: str = "pole"
    collides: bool = True

    def __post_init__(self) -> None:
        check(self.radius_m > 0, f"landmark {self.name!r}: radius_m must be > 0, got {self.radius_m}")
        check(self.max_range_m > 0, f"landmark {self.name!r}: max_range_m must be > 0, got {self.max_range_m}")
        check(bool(self.kind), f"landmark {self.name!r}: kind must not be empty")


@dataclass(frozen=True)
class RobotConfig:
    """Our differential-drive robot (a pymunk circle), and how its wheels slip.

    Slip: the body moves, and turns, less than commanded; odometry reads the command, so a
    slip is an unobserved shortening of the motion. The fraction of a step's commanded
    motion that is lost (the body's velocity and turn rate are multiplied by one minus it)
    is :meth:`slip_fraction`, the sum of

    - a random slip: with probability ``slip_probability`` per step, U(0, ``slip_max_fraction``);
    - an acceleration term: ``slip_per_accel_s2`` times the commanded linear acceleration
      ``|v(t) - v(t-1)| / dt`` (m/s^2, the forward speed command; the robot starts each
      episode at rest) plus ``slip_per_angular_accel_s2`` times the commanded angular
      acceleration ``|omega(t) - omega(t-1)| / dt`` (rad/s^2). Real tyres lose grip in
      proportion to the traction force they transmit (the linear part of the slip curve),
      and that force is the mass times the acceleration. The term is deterministic: the
      same command sequence slips the same way;
    - a contact term: ``slip_in_contact`` in a step that starts with the robot touching
      something (a wall, a pole, a crowd member, the ball: the physics' last step left a
      contact on the robot body): a robot pushing or pushed spins its wheels;

    capped at ``slip_max_total`` (< 1: the robot always keeps part of its motion). The
    defaults (0 for the three new terms, cap 0.9) leave every shipped world as it was, and
    the deterministic terms draw nothing from the world's random stream.
    """

    radius_m: float = 0.25
    mass_kg: float = 30.0
    max_speed_mps: float = 1.75
    max_turn_rate_rps: float = 3.0
    friction: float = 0.5
    start_pose: tuple[float, float, float] | None = None  # fixed start; None: random in start_region_m
    start_region_m: tuple[float, float, float, float] | None = None  # (xmin, ymin, xmax, ymax)
    slip_probability: float = 0.0  # per step: the wheels slip and the body moves less than commanded
    slip_max_fraction: float = 0.5  # a slipping step loses U(0, this) of the commanded motion
    slip_per_accel_s2: float = 0.0  # fraction lost per m/s^2 of commanded linear acceleration (s^2/m), in [0, 1]
    slip_per_angular_accel_s2: float = 0.0  # fraction lost per rad/s^2 of commanded angular acceleration (s^2/rad), in [0, 1]
    slip_in_contact: float = 0.0  # fraction lost in a step that starts in contact with anything, in [0, 1]
    slip_max_total: float = 0.9  # the cap on the summed lost fraction, in [0, 1); at least slip_max_fraction

    def __post_init__(self) -> None:
        check(self.radius_m > 0, f"robot.radius_m must be > 0, got {self.radius_m}")
        check(self.mass_kg > 0, f"robot.mass_kg must be > 0, got {self.mass_kg}")
        check(self.max_speed_mps > 0, f"robot.max_speed_mps must be > 0, got {self.max_speed_mps}")
        check(self.max_turn_rate_rps > 0, f"robot.max_turn_rate_rps must be > 0, got {self.max_turn_rate_rps}")
        check_ranges(self, "robot", non_negative=("friction",))  # (finite: pymunk aborts the process on a NaN)
        check(
            self.start_pose is not None or self.start_region_m is not None,
            "robot: give start_pose or start_region_m",
        )
        if self.start_region_m is not None:
            x0, y0, x1, y1 = self.start_region_m
            check(
                x0 <= x1 and y0 <= y1,
                f"robot.start_region_m must be (xmin, ymin, xmax, ymax) with xmin <= xmax and ymin <= ymax, "
                f"got {list(self.start_region_m)}",
            )
        check(0 <= self.slip_probability <= 1, f"robot.slip_probability must be in [0, 1], got {self.slip_probability}")
        check(0 <= self.slip_max_fraction <= 1, f"robot.slip_max_fraction must be in [0, 1], got {self.slip_max_fraction}")
        for name, unit in (("slip_per_accel_s2", " s^2/m"), ("slip_per_angular_accel_s2", " s^2/rad"), ("slip_in_contact", "")):
            value = getattr(self, name)
            check(math.isfinite(value) and 0 <= value <= 1, f"robot.{name} must be finite and in [0, 1]{unit}, got {value}")
        check(
            math.isfinite(self.slip_max_total) and 0 <= self.slip_max_total < 1,
            f"robot.slip_max_total must be finite and in [0, 1) (the robot keeps part of its motion), got {self.slip_max_total}",
        )
        check(
            self.slip_max_fraction <= self.slip_max_total,
            f"robot.slip_max_fraction ({self.slip_max_fraction}) must not exceed robot.slip_max_total "
            f"({self.slip_max_total}), the cap on the lost fraction: raise the cap or lower the random slip",
        )

    @property
    def slips(self) -> bool:
        """Whether any wheel slip is set (random, with acceleration or in contact)."""
        return any(
            v > 0 for v in (self.slip_probability, self.slip_per_accel_s2, self.slip_per_angular_accel_s2, self.slip_in_contact)
        )

    def slip_fraction(self, accel_mps2: float, angular_accel_rps2: float, in_contact: bool, rng: np.random.Generator) -> float:
        """The fraction in ``[0, slip_max_total]`` of this step's commanded motion the wheels lose.

        Args:
            accel_mps2: the commanded linear acceleration magnitude, ``|v(t) - v(t-1)| / dt``.
            angular_accel_rps2: the commanded angular acceleration magnitude, ``|omega(t) - omega(t-1)| / dt``.
            in_contact: whether the robot touches something as the step starts.
            rng: the world's random stream; drawn from only when ``slip_probability > 0``
                (one draw, and a second for the size of a slip); the other terms draw nothing.
        """
        lost = 0.0
        if self.slip_probability > 0 and rng.random() < self.slip_probability:
            lost = rng.uniform(0.0, self.slip_max_fraction)
        lost += self.slip_per_accel_s2 * accel_mps2 + self.slip_per_angular_accel_s2 * angular_accel_rps2
        if in_contact:
            lost += self.slip_in_contact
        return min(self.slip_max_total, lost)


@dataclass(frozen=True)
class GoalConfig:
    """Where an episode ends: the robot has stopped within ``radius_m`` of ``(x_m, y_m)``.

    Stopped: the commanded speed and turn rate have stayed below ``still_fraction`` of their
    limits for ``hold_s``. The episode then terminates (``terminated=True``).
    """

    x_m: float
    y_m: float
    radius_m: float = 0.3
    hold_s: float = 1.0
    still_fraction: float = 0.02

    def __post_init__(self) -> None:
        check(self.radius_m > 0, f"goal.radius_m must be > 0, got {self.radius_m}")
        check(self.hold_s >= 0, f"goal.hold_s must be >= 0, got {self.hold_s}")
        check(0 <= self.still_fraction < 1, f"goal.still_fraction must be in [0, 1), got {self.still_fraction}")


@dataclass(frozen=True)
class FurnitureConfig:
    """A piece of furniture: static, with a height, seen by sensors at the heights it spans.

    ``kind``:

    - ``"box"``: a shelf, a cabinet, a pillar: solid from the floor to ``height_m``; its four
      sides are wall segments that collide and that every sensor below its top sees.
    - ``"table"``: four legs (squares of side ``2 leg_radius_m`` at the corners, from the floor
      to the underside of the top) and a top ``top_thickness_m`` thick at ``height_m``. The legs
      collide; the top does not (our robots are lower than a table), but a sensor at its
      height sees its edges. A LIDAR at 0.2 m sees four legs, one at 1.9 m nothing.

    ``size_m`` is ``(length along the piece's own x, depth)`` before turning by ``angle_rad``
    about its centre ``(x_m, y_m)``. ``map_offset_m`` and ``map_offset_rad`` say where the
    localizers' map has it relative to where it stands (furniture moved since the map was
    made): the map's copy is turned by ``map_offset_rad`` about the centre and shifted; zero by
    default, the map exact.
    """

    name: str
    kind: Literal["box", "table"]
    x_m: float
    y_m: float
    size_m: tuple[float, float]
    height_m: float
    angle_rad: float = 0.0
    leg_radius_m: float = 0.025
    top_thickness_m: float = 0.03
    map_offset_m: tuple[float, float] = (0.0, 0.0)
    map_offset_rad: float = 0.0

    def __post_init__(self) -> None:
        where = f"furniture {self.name!r}"
        numbers = (self.x_m, self.y_m, *self.size_m, self.height_m, self.angle_rad, *self.map_offset_m, self.map_offset_rad)
        check(all(math.isfinite(v) for v in numbers), f"{where}: every number must be finite")
        check(self.size_m[0] > 0 and self.size_m[1] > 0, f"{where}: size_m must be positive, got {self.size_m}")
        check(self.height_m > 0, f"{where}: height_m must be > 0, got {self.height_m}")
        if self.kind == "table":
            check(
                0 < self.leg_radius_m and 4 * self.leg_radius_m < min(self.size_m),
                f"{where}: leg_radius_m must be > 0 and the legs must fit under the top {self.size_m}, got {self.leg_radius_m}",
            )
            check(
                0 < self.top_thickness_m < self.height_m,
                f"{where}: top_thickness_m must be in (0, height_m = {self.height_m}), got {self.top_thickness_m}",
            )

    def footprint(self, in_map: bool = False) -> NDArray[np.float64]:
        """``(4, 2)`` corners of its outline, counter-clockwise (where the map has it with ``in_map``)."""
        return self._place(_rectangle(0.0, 0.0, *self.size_m), in_map)

    def _place(self, local: NDArray[np.float64], in_map: bool) -> NDArray[np.float64]:
        angle = self.angle_rad + (self.map_offset_rad if in_map else 0.0)
        c, s = math.cos(angle), math.sin(angle)
        out = local @ np.array([[c, s], [-s, c]]) + (self.x_m, self.y_m)
        return out + self.map_offset_m if in_map else out

    def segments(self, in_map: bool = False) -> list[Segment]:
        """Its outline segments with their height intervals (where the map has them with ``in_map``)."""
        if self.kind == "box":
            return _outline(self.footprint(in_map), 0.0, self.height_m)
        hx, hy = 0.5 * self.size_m[0] - self.leg_radius_m, 0.5 * self.size_m[1] - self.leg_radius_m
        side = 2.0 * self.leg_radius_m
        under = self.height_m - self.top_thickness_m
        out = _outline(self.footprint(in_map), under, self.height_m)
        for cx, cy in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)):
            out += _outline(self._place(_rectangle(cx, cy, side, side), in_map), 0.0, under)
        return out


def _rectangle(cx: float, cy: float, length: float, depth: float) -> NDArray[np.float64]:
    hx, hy = 0.5 * length, 0.5 * depth
    return np.array([[cx - hx, cy - hy], [cx + hx, cy - hy], [cx + hx, cy + hy], [cx - hx, cy + hy]])


def _outline(corners: NDArray[np.float64], bottom: float, top: float) -> list[Segment]:
    nxt = np.roll(corners, -1, axis=0)
    return [(float(a[0]), float(a[1]), float(b[0]), float(b[1]), bottom, top) for a, b in zip(corners, nxt)]


@dataclass(frozen=True)
class WorldConfig:
    """One scenario: geometry, landmarks, robot, its sensors (in observation order) and the crowds.

    Every number in it, down to the sensors', crowds' and features' fields, must be finite
    (:func:`non_finite_numbers`; the few fields that mean "no limit" may be ``inf``): an
    infinite or NaN mass or friction aborts the whole process inside pymunk, and one in a
    sensor puts NaN or infinite bounds in the observation. The robot's start (``start_pose``,
    or every corner of ``start_region_m``) must be a place its disc fits, by the rule that a
    reset's ``robot_pose`` option follows (:meth:`robot_placement_problem`), and each crowd's
    bodies must fit in the field.
    """

    #: the fields that may be ``inf`` (:func:`non_finite_numbers`): walls as high as anything
    unbounded_fields: ClassVar[frozenset[str]] = frozenset({"wall_height_m"})

    name: str
    description: str
    size_m: tuple[float, float]  # the field / room the robot moves in, from origin_m
    dt_s: float
    max_episode_steps: int
    robot: RobotConfig
    walls: tuple[tuple[float, float, float, float], ...] = ()  # extra segments (x1, y1, x2, y2)
    boundary_margin_m: float = 0.0  # boundary walls this far outside the field
    wall_height_m: float = math.inf  # every wall's height (a sensor above it sees over it)
    furniture: tuple[FurnitureConfig, ...] = ()  # static pieces with a height (a shelf, a table)
    landmarks: tuple[LandmarkConfig, ...] = ()
    sensors: Mapping[str, SensorConfig] = field(default_factory=dict)  # name -> config tagged by type
    crowds: Mapping[str, CrowdConfig] = field(default_factory=dict)  # name -> config tagged by type; bodies in this order
    floor: Literal["field", "room"] = "room"  # how the renderer draws the ground
    origin_m: tuple[float, float] = (0.0, 0.0)  # the field's lower-left corner (a corridor centred on x = 0)
    features: Mapping[str, FeatureConfig] = field(default_factory=dict)  # name -> static scenery tagged by type (a ceiling)
    goal: GoalConfig | None = None  # where an episode terminates (None: it only times out)
    # the top view's window (width, height) in metres, centred on the robot and kept inside the
    # world's bounds, for worlds too large for one frame; None shows the whole world
    view_m: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        for path, value, may_be_inf in non_finite_numbers(self):
            raise ConfigError(
                f"world {self.name!r}: {path} must be {'a number or inf' if may_be_inf else 'finite'}, got {value!r} "
                "(a world's numbers reach the physics and the sensors)"
            )
        w, h = self.size_m
        check(w > 0 and h > 0, f"world {self.name!r}: size_m must be positive, got {self.size_m}")
        check(self.dt_s > 0, f"world {self.name!r}: dt_s must be > 0, got {self.dt_s}")
        check(math.isfinite(self.dt_s), f"world {self.name!r}: dt_s must be finite, got {self.dt_s}")
        check(self.max_episode_steps >= 1, f"world {self.name!r}: max_episode_steps must be >= 1, got {self.max_episode_steps}")
        check(self.wall_height_m > 0, f"world {self.name!r}: wall_height_m must be > 0, got {self.wall_height_m}")
        check(self.boundary_margin_m >= 0, f"world {self.name!r}: boundary_margin_m must be >= 0, got {self.boundary_margin_m}")
        names = [lm.name for lm in self.landmarks]
        check(len(set(names)) == len(names), f"world {self.name!r}: landmark names repeat: {names}")
        names = [f.name for f in self.furniture]
        check(len(set(names)) == len(names), f"world {self.name!r}: furniture names repeat: {names}")
        xmin, ymin, xmax, ymax = self.arena_m
        for piece in self.furniture:
            for corners in (piece.footprint(), piece.footprint(in_map=True)):
                check(
                    bool(np.all((corners >= (xmin, ymin)) & (corners <= (xmax, ymax)))),
                    f"world {self.name!r}: furniture {piece.name!r} (corners {np.round(corners, 3).tolist()}, in the world "
                    f"and in the map) must lie inside the boundary walls x [{xmin:g}, {xmax:g}], y [{ymin:g}, {ymax:g}]",
                )
        check(len(self.sensors) > 0, f"world {self.name!r}: needs at least one sensor (sensors: name -> {{type: ...}})")
        keys: dict[str, str] = {}
        for name, sensor in self.sensors.items():
            check(isinstance(sensor, SensorConfig), f"world {self.name!r}: sensor {name!r} is not a sensor config: {sensor!r}")
            check(
                sensor.key not in keys,
                f"world {self.name!r}: sensors {keys.get(sensor.key)!r} and {name!r} both write observation key "
                f"{sensor.key!r}; give one of them another key",
            )
            keys[sensor.key] = name
            sensor.check_world(self, name)
        object.__setattr__(self, "sensors", dict(self.sensors))  # a copy: the caller's dict may change
        for name, crowd in self.crowds.items():
            check(isinstance(crowd, CrowdConfig), f"world {self.name!r}: crowd {name!r} is not a crowd config: {crowd!r}")
            self._check_crowd_fits(name, crowd)
        clash = sorted(set(self.crowds) & set(self.sensors))
        check(not clash, f"world {self.name!r}: {clash} name both a sensor and a crowd (env kwargs address them by name)")
        object.__setattr__(self, "crowds", dict(self.crowds))
        self._check_dt_resolves_motion()
        for name, feature in self.features.items():
            check(
                isinstance(feature, FeatureConfig), f"world {self.name!r}: feature {name!r} is not a feature config: {feature!r}"
            )
            feature.check_world(self, name)
            for solid in feature.solids():
                check(
                    bool(np.all((solid.corners >= (xmin, ymin)) & (solid.corners <= (xmax, ymax)))),
                    f"world {self.name!r}: feature {name!r}: {solid.kind or 'solid'} {solid.name!r} (corners "
                    f"{np.round(solid.corners, 3).tolist()}) must lie inside the boundary walls x [{xmin:g}, {xmax:g}], "
                    f"y [{ymin:g}, {ymax:g}]",
                )
        clash = sorted(set(self.features) & (set(self.crowds) | set(self.sensors)))
        check(not clash, f"world {self.name!r}: {clash} name a feature and a sensor or crowd")
        object.__setattr__(self, "features", dict(self.features))
        self._check_robot_start()
        self._check_view()

    def _check_robot_start(self) -> None:
        """The robot's start must be a place its disc fits (:meth:`robot_placement_problem`, the
        rule of a reset's ``robot_pose`` option): ``start_pose``, or each corner of ``start_region_m``
        (the start is drawn uniformly in the region)."""
        rc = self.robot
        if rc.start_pose is not None:
            x, y, _ = rc.start_pose
            problem = self.robot_placement_problem(x, y)
            check(problem is None, f"world {self.name!r}: robot.start_pose = {list(rc.start_pose)}: {problem}")
        if rc.start_region_m is not None:
            x0, y0, x1, y1 = rc.start_region_m
            problem = self._robot_outside(x0, y0) or self._robot_outside(x1, y1)
            check(
                problem is None,
                f"world {self.name!r}: robot.start_region_m = {list(rc.start_region_m)} (the start is drawn in it): {problem}",
            )

    def _check_crowd_fits(self, name: str, crowd: CrowdConfig) -> None:
        """Each kind of body of a crowd (:meth:`CrowdConfig.top_speeds` lists them with their
        radii) must fit in the field, where its members are placed."""
        fx0, fy0, fx1, fy1 = self.field_m
        for body, _, radius in crowd.top_speeds():
            check(
                2 * radius <= min(fx1 - fx0, fy1 - fy0),
                f"world {self.name!r}: crowd {name!r}: its {body} of radius {radius:g} m ({2 * radius:g} m across) cannot fit "
                f"in the {fx1 - fx0:g} m x {fy1 - fy0:g} m field, the space it places them in; give a smaller radius",
            )

    def _check_view(self) -> None:
        """``view_m``: two finite sizes > 0, and not so small against the world that the follow
        mode's background (the whole world at the view's scale, :mod:`envs.view`) would exceed
        :data:`envs.view.MAX_BACKGROUND_PX` on a side."""
        view = self.view_m
        if view is None:
            return
        pair = isinstance(view, (tuple, list)) and len(view) == 2
        pair = pair and all(is_real(v) for v in view)
        check(
            pair and all(math.isfinite(v) and v > 0 for v in view),
            f"world {self.name!r}: view_m must be two finite numbers > 0 (the top view's width and height in metres) "
            f"or None, got {view!r}",
        )
        view_w, view_h = float(view[0]), float(view[1])
        object.__setattr__(self, "view_m", (view_w, view_h))
        xmin, ymin, xmax, ymax = bounds = drawn_bounds(self)
        scale = fit(view_w, view_h).scale
        width, height = background_size_px(bounds, scale)
        if max(width, height) > MAX_BACKGROUND_PX:
            # the largest scale that fits, and the views that give it (either size suffices)
            fits = (MAX_BACKGROUND_PX - 2 * BACKGROUND_PAD_PX - 1) / max(xmax - xmin, ymax - ymin)
            least = [
                math.ceil(100.0 * (FRAME_LONG_SIDE_PX - 2 * MARGIN_PX - caption) / fits) / 100.0 for caption in (0, CAPTION_PX)
            ]
            raise ConfigError(
                f"world {self.name!r}: view_m = {list(view)} m is too small for a world of {xmax - xmin:g} m x "
                f"{ymax - ymin:g} m: the top view's background (the whole world at {scale:.3g} px/m) would be "
                f"{width} x {height} px, more than {MAX_BACKGROUND_PX} px on a side; a view_m of at least "
                f"{least} m fits"
            )

    def _check_dt_resolves_motion(self) -> None:
        """Refuse a ``dt_s`` in which a body travels more than its own radius in one step.

        The physics moves every body by its velocity times ``dt_s``, then pushes overlaps
        apart. A body that travels at most its radius per step cannot carry its centre past
        a wall's centre line (or another body's) in one step, so the push-out always sends it
        back the way it came; beyond that, a fast body can end a step past a thin interior
        wall (0.02 m) and be pushed out on the far side, or skip over it entirely, with no
        contact reported. The bound is checked for the robot (``robot.max_speed_mps``) and for
        every kind of body of every crowd at its top speed (:meth:`CrowdConfig.top_speeds`:
        e.g. the soccer ball at its kick speed, 3 m/s with radius 0.11 m, bounds dt to
        0.0367 s). Shipped worlds run at 0.025-0.05 s.
        """
        bodies = [("the robot (robot.max_speed_mps, robot.radius_m)", self.robot.max_speed_mps, self.robot.radius_m)]
        for name, crowd in self.crowds.items():
            bodies += [(f"crowd {name!r}: {body}", speed, radius) for body, speed, radius in crowd.top_speeds()]
        for body, speed, radius in bodies:
            limit = radius / speed
            check(
                self.dt_s <= limit,
                f"world {self.name!r}: dt_s = {self.dt_s} is too long for {body}: at {speed:g} m/s it would travel "
                f"{speed * self.dt_s:.3g} m per step, more than its radius {radius:g} m, and could pass through walls; "
                f"dt_s must be <= {limit:.4g} s (radius / top speed)",
            )

    @property
    def crowd(self) -> CrowdConfig | None:
        """The first crowd: the one whose ``count`` is the world's crowd size (density); None without crowds."""
        return next(iter(self.crowds.values()), None)

    @property
    def crowd_count(self) -> int:
        """Members over every crowd."""
        return sum(c.count for c in self.crowds.values())

    def sensors_of_type(self, type_name: str) -> dict[str, SensorConfig]:
        """The sensors of one registered type (``"lidar"``), by name, in config order."""
        return {name: s for name, s in self.sensors.items() if s.type_name == type_name}

    def sensor_of_type(self, type_name: str) -> SensorConfig | None:
        """The world's one sensor of a registered type, None without one.

        Raises:
            ConfigError: if the world has several (name the one you mean in ``sensors``).
        """
        found = self.sensors_of_type(type_name)
        check(len(found) <= 1, f"world {self.name!r} has several {type_name} sensors: {', '.join(found)}")
        return next(iter(found.values()), None)

    @property
    def field_m(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` of the field (``size_m`` from ``origin_m``): where the robot may be."""
        x0, y0 = self.origin_m
        return (x0, y0, x0 + self.size_m[0], y0 + self.size_m[1])

    @property
    def arena_m(self) -> tuple[float, float, float, float]:
        """``(xmin, ymin, xmax, ymax)`` inside the boundary walls (the field and its margin)."""
        m = self.boundary_margin_m
        xmin, ymin, xmax, ymax = self.field_m
        return (xmin - m, ymin - m, xmax + m, ymax + m)

    def robot_placement_problem(self, x: float, y: float) -> str | None:
        """Why our robot's disc cannot be placed at ``(x, y)``, or None where it fits.

        The disc (``robot.radius_m``) must lie inside the boundary walls, that is the field
        (:attr:`field_m`) and its ``boundary_margin_m`` (:attr:`arena_m`, the field itself where
        the margin is 0: the soccer robot may stand on the touch line), and clear every interior
        wall's and floor-standing furniture segment's thickness (:data:`WALL_RADIUS_M` a side),
        its centre outside every box (under a table is open floor) and every solid standing on
        the floor (a building, a pole, a trunk); a disc placed over a wall would be pushed out
        on either side, or trapped in it. The one rule for a reset's ``robot_pose`` option and
        the config's ``robot.start_pose`` and ``start_region_m``.
        """
        outside = self._robot_outside(x, y)
        if outside:
            return outside
        r = self.robot.radius_m
        for piece in self.furniture:
            corners = piece.footprint()
            if piece.kind == "box" and inside_convex(corners, x, y):  # under a table is open floor
                return f"the robot's centre ({x:g}, {y:g}) would be inside furniture {piece.name!r} (corners {np.round(corners, 3).tolist()})"
        for name, feature in self.features.items():
            for solid in feature.solids():
                if solid.bottom_m <= 0.0 and inside_convex(solid.corners, x, y):  # (a tree's crown is overhead)
                    return (
                        f"the robot's centre ({x:g}, {y:g}) would be inside {solid.kind or 'solid'} {solid.name!r} of feature "
                        f"{name!r} (corners {np.round(solid.corners, 3).tolist()})"
                    )
        a, b = self._interior_floor_walls
        if a.shape[0]:
            d = b - a
            length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
            t = np.clip(np.einsum("ij,ij->i", np.array([x, y]) - a, d) / length2, 0.0, 1.0)
            gap = np.hypot(*(a + t[:, None] * d - (x, y)).T)
            i = int(np.argmin(gap))
            if gap[i] < r + WALL_RADIUS_M:
                return (
                    f"the robot (radius {r:g} m) would overlap wall {tuple(float(v) for v in (*a[i], *b[i]))} "
                    f"(thickness {2 * WALL_RADIUS_M:g} m): its centre is {gap[i]:.3g} m from the wall's line, "
                    f"it must be at least {r + WALL_RADIUS_M:g} m"
                )
        if not self._floor.reachable(x, y):
            return (
                f"the robot's centre ({x:g}, {y:g}) would be in a part of world {self.name!r} that walls close off "
                f"from its main floor ({self._floor.main_area_m2:.4g} m^2, envs.floor): the robot could never get there"
            )
        return None

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the floor grid (megabytes on the campus; remade where it is asked for)."""
        state = dict(self.__dict__)
        state.pop("_floor", None)
        return state

    @functools.cached_property
    def _floor(self) -> FloorGrid:
        """Where the robot can get (:mod:`envs.floor`), made once, at the first placement asked about."""
        a, b = self._interior_floor_walls
        polygons = [piece.footprint() for piece in self.furniture if piece.kind == "box"]
        polygons += [solid.corners for feature in self.features.values() for solid in feature.solids() if solid.bottom_m <= 0.0]
        return floor_grid(self.arena_m, np.hstack([a, b]), polygons, self.robot.radius_m, WALL_RADIUS_M)

    @functools.cached_property
    def _interior_floor_walls(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(seg_a, seg_b)`` of the interior segments standing on the floor (they collide), made once."""
        segments = self.static_segments()[BOUNDARY_SEGMENTS:]
        segments = segments[segments[:, 4] <= 0.0]
        return segments[:, 0:2], segments[:, 2:4]

    def _robot_outside(self, x: float, y: float) -> str | None:
        """Why the robot's disc centred at ``(x, y)`` does not lie inside the boundary walls, or None."""
        r = self.robot.radius_m
        xmin, ymin, xmax, ymax = self.arena_m
        if xmin + r <= x <= xmax - r and ymin + r <= y <= ymax - r:
            return None
        fx0, fy0, fx1, fy1 = self.field_m
        margin = f" and its {self.boundary_margin_m:g} m margin" if self.boundary_margin_m else ""
        where = (
            f"the robot (radius {r:g} m) must fit inside world {self.name!r}'s field (x in [{fx0:g}, {fx1:g}], "
            f"y in [{fy0:g}, {fy1:g}] m){margin}, x in [{xmin:g}, {xmax:g}] and y in [{ymin:g}, {ymax:g}] m"
        )
        if 2 * r > min(xmax - xmin, ymax - ymin):
            return f"{where}: its disc, {2 * r:g} m across, is larger than that"
        return f"{where}: its centre must be in x [{xmin + r:g}, {xmax - r:g}], y [{ymin + r:g}, {ymax - r:g}]"

    def static_segments(self, in_map: bool = False) -> NDArray[np.float64]:
        """``(S, 6)`` every static segment ``(x1, y1, x2, y2, bottom, top)``: the arena boundary
        (counter-clockwise, the first :data:`BOUNDARY_SEGMENTS` rows) and the extra walls, from the
        floor to ``wall_height_m``, then each piece of furniture's, then the sides of the
        features' solids (buildings, poles, trees: :meth:`FeatureConfig.segments`), feature by
        feature in config order. With ``in_map`` the furniture stands where the localizers' map
        has it (``map_offset_m``)."""
        xmin, ymin, xmax, ymax = self.arena_m
        boundary = [(xmin, ymin, xmax, ymin), (xmax, ymin, xmax, ymax), (xmax, ymax, xmin, ymax), (xmin, ymax, xmin, ymin)]
        rows: list[Segment] = [(*wall, 0.0, self.wall_height_m) for wall in boundary + [tuple(w) for w in self.walls]]
        for piece in self.furniture:
            rows += piece.segments(in_map)
        for feature in self.features.values():
            rows += feature.segments()
        return np.asarray(rows, dtype=np.float64).reshape(-1, 6)

    def wall_segments(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(seg_a, seg_b)``, each ``(S, 2)``: the end points of :meth:`static_segments` (the
        boundary first), the segments the world collides with and the sensors see."""
        arr = self.static_segments()
        return np.ascontiguousarray(arr[:, 0:2]), np.ascontiguousarray(arr[:, 2:4])

    def features_of_type(self, type_name: str) -> dict[str, FeatureConfig]:
        """The features of one registered type (``"ceiling"``), by name, in config order."""
        return {name: f for name, f in self.features.items() if f.type_name == type_name}


def non_finite_numbers(value: Any, path: str = "") -> Iterator[tuple[str, float, bool]]:
    """``(path, number, may_be_inf)`` of every number inside ``value`` that is not finite.

    Walks dataclass fields, mappings (a world's sensors, crowds and features by name) and
    tuples, naming each number by its path (``"robot.mass_kg"``, ``"crowds.soccer.mass_kg"``,
    ``"walls[2][0]"``). A config class lists the fields in which ``inf`` means "no limit"
    (a landmark's ``max_range_m``, a column's ``height_m``) in its ``unbounded_fields``; there
    ``inf`` passes and NaN or ``-inf`` is reported with ``may_be_inf`` true. Integers are
    always finite.
    """
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        unbounded: frozenset[str] = getattr(type(value), "unbounded_fields", frozenset())
        for f in dataclasses.fields(value):
            item = getattr(value, f.name)
            inner = f"{path}.{f.name}" if path else f.name
            if f.name in unbounded and isinstance(item, Real):
                if not (math.isfinite(item) or item == math.inf):
                    yield inner, float(item), True
                continue
            yield from non_finite_numbers(item, inner)
    elif isinstance(value, Mapping):
        for key, item in value.items():
            yield from non_finite_numbers(item, f"{path}.{key}" if path else str(key))
    elif isinstance(value, (tuple, list)):
        for i, item in enumerate(value):
            yield from non_finite_numbers(item, f"{path}[{i}]")
    elif isinstance(value, Real) and not isinstance(value, Integral) and not math.isfinite(value):
        yield path, float(value), False


def inside_convex(corners: NDArray[np.float64], x: float, y: float) -> bool:
    """Whether ``(x, y)`` lies inside the convex polygon ``corners`` ``(K, 2)`` (counter-clockwise)."""
    edges = np.roll(corners, -1, axis=0) - corners
    rel = np.array([x, y]) - corners
    return bool(np.all(edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0] > 0.0))


def world_path(name: str) -> Path:
    """Path of a shipped world config."""
    return WORLD_DIR / f"{name}.yaml"


def available_worlds() -> list[str]:
    return sorted(p.stem for p in WORLD_DIR.glob("*.yaml"))


def load_world(name_or_path: str | Path) -> WorldConfig:
    """Load a world by shipped name (``"robocup_crowded"``) or by YAML path.

    Raises:
        ConfigError: naming the unknown world, or the bad key and the file.
    """
    if not isinstance(name_or_path, (str, Path)):
        raise ConfigError(
            f"world must be a shipped world's name, a YAML path or a WorldConfig, got "
            f"{type(name_or_path).__name__} {name_or_path!r}"
        )
    path = Path(name_or_path)
    if path.suffix not in (".yaml", ".yml"):
        path = world_path(str(name_or_path))
        if not path.is_file():
            raise ConfigError(f"unknown world {str(name_or_path)!r}; shipped worlds: {', '.join(available_worlds())}")
    return from_mapping(WorldConfig, load_yaml(path), where=str(path))
