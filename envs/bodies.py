"""What stands where, by height: the 2.5-D description of every moving body and static object.

Physics stays 2-D (pymunk collides footprint discs and wall segments), but every body also
has a vertical profile, and every sensor a mounting height at which it sees the world's
horizontal cross-section. This module is the one description of that profile; the range
sensors, the cameras and the renderer read it, none of them keeps its own.

**Parts.** A body is made of upright parts, each a disc of a radius (or, for a car, a box)
over a height interval ``[z_lo, z_hi)``:

- ``column``: one disc of the footprint radius from the floor to ``height_m`` (a soccer
  robot's body, a pole; ``inf``: as tall as anything a sensor looks at);
- ``ball``: a sphere of the footprint radius resting on the floor: its section at height
  ``z`` is the disc of radius ``sqrt(r^2 - (z - r)^2)``;
- ``person``: two legs, a torso and a head (:class:`PersonConfig`), sizes drawn per person
  at every reset. A leg is a tilted cylinder hanging from its hip joint, swinging forward
  and back with the gait while the person walks and still (upright, beside the other) while
  the person stands: at height ``z`` its centre lies ``(z_hip - z) tan(alpha)`` ahead of the
  hip, ``alpha`` the leg's swing angle. So a LIDAR at 0.2 m sees two leg discs whose gap
  changes with the gait phase, one at 1.2 m sees the torso and one above the head nothing;
- ``car``: boxes that turn with the body's heading (:class:`CarConfig`): four wheels below
  the sill (a wheel's section at height ``z`` is a chord ``2 sqrt(r^2 - (z - r)^2)`` long
  and the tyre's width wide), the lower body from the sill to the beltline and the cabin
  from there to the roof. A LIDAR at 0.2 m sees the four wheels and, between them, under
  the car; one at 0.6 m sees the body's sides, one over the roof nothing. Its footprint box
  is what collides (the other shapes collide by their footprint disc).

Each part is stored as a reference point ``xy`` at height ``z_ref`` and a ``slope`` (the
horizontal shift of its centre per metre up), so its centre at height ``z`` is
``xy + slope (z - z_ref)``; a column and a ball have zero slope.

**Sections.** :meth:`envs.figures.Figures.section` gives the discs cut at one height (centres,
radii, the body row each belongs to and whether it blocks a camera's view) and the sides of the
boxes cut there, as segments. The world makes one :class:`~envs.figures.Figures` per step
(:class:`envs.figure_model.FigureModel` poses it, lazily, when a sensor asks) and caches each
height's section.

This module says what the bodies are (their shapes, sizes, proportions and colours);
:mod:`envs.figure_model` lays out their parts and moves the gait, :mod:`envs.figures` cuts them.

**Gait.** A walking person (speed above :data:`STAND_SPEED_MPS`) faces its direction of
travel, its gait phase advancing at ``pi cadence`` rad/s (one step per ``1 / cadence`` s);
its step length is ``speed / cadence`` up to ``max_step_m``, so the legs' swing amplitude
``alpha_max = asin(step / (2 z_hip))`` grows with speed. Below :data:`STAND_SPEED_MPS` the
phase and heading freeze and the legs stand together.

Anthropometry (proportions of the stature ``H``, after Drillis and Contini's segment
table): the hip joints at 0.53 H, the legs up to the crotch at 0.47 H, the torso from there
to the shoulders at 0.82 H, the head (with the neck) from 0.82 H to H.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from core.schema import check, check_ranges, check_rgb

#: a person moving slower than this stands: legs together, heading and gait phase frozen
STAND_SPEED_MPS = 0.05
#: proportions of the stature: hip joint (leg pivot), crotch (top of the legs), shoulders (top of the torso)
HIP_FRACTION, CROTCH_FRACTION, SHOULDER_FRACTION = 0.53, 0.47, 0.82
#: the shapes a body can have (``BodySpec.shape``)
SHAPES = ("column", "ball", "person", "car")
#: part kinds
LEG, TORSO, HEAD, COLUMN, BALL = 0, 1, 2, 3, 4


Rgb = tuple[int, int, int]
#: the colour of bodies without a palette (a soccer robot's column) and of the ball, 0-255
COLUMN_RGB: Rgb = (60, 60, 64)
BALL_RGB: Rgb = (235, 120, 30)


def _check_palette(value: tuple[Rgb, ...], where: str) -> None:
    check(len(value) > 0, f"{where} must be a non-empty list of RGB colours, got {value!r}")
    for i, colour in enumerate(value):
        check_rgb(colour, f"{where}[{i}]")


def _check_range(name: str, value: tuple[float, float], lo: float, hi: float) -> None:
    a, b = value
    check(
        math.isfinite(a) and math.isfinite(b) and lo <= a <= b <= hi,
        f"person.{name} must be a range (low, high) with {lo} <= low <= high <= {hi}, got {value}",
    )


@dataclass(frozen=True)
class PersonConfig:
    """Adult body sizes, each drawn uniformly from its range per person at every reset, and the gait.

    The defaults span adults from about the 5th to the 95th percentile (stature 1.55-1.90 m).
    """

    height_m: tuple[float, float] = (1.55, 1.90)  # stature H
    leg_radius_m: tuple[float, float] = (0.05, 0.07)  # a leg's section (thigh and calf alike)
    hip_half_width_m: tuple[float, float] = (0.08, 0.11)  # from the body's centre to each hip joint, sideways
    torso_radius_m: tuple[float, float] = (0.15, 0.20)  # the torso's section, as a disc
    head_radius_m: tuple[float, float] = (0.08, 0.10)  # the head's section with the hair
    cadence_hz: float = 1.8  # steps per second while walking
    max_step_m: float = 0.8  # the longest step, heel to heel
    # clothing and hair, drawn per person at every reset (what a camera sees; 0-255 RGB)
    shirt_rgb: tuple[Rgb, ...] = (
        (178, 42, 40), (40, 70, 150), (228, 228, 222), (32, 32, 34), (88, 138, 62), (222, 180, 42), (120, 120, 128),
        (150, 88, 140), (60, 120, 170), (200, 110, 60),
    )  # fmt: skip
    trousers_rgb: tuple[Rgb, ...] = ((40, 45, 62), (30, 30, 32), (92, 82, 70), (62, 72, 112), (150, 140, 120), (70, 70, 74))
    head_rgb: tuple[Rgb, ...] = ((36, 26, 20), (72, 50, 36), (22, 22, 22), (150, 120, 80), (190, 160, 130), (120, 100, 90))

    def __post_init__(self) -> None:
        _check_range("height_m", self.height_m, 0.5, 2.5)
        for name in ("shirt_rgb", "trousers_rgb", "head_rgb"):
            _check_palette(getattr(self, name), f"person.{name}")
        for name in ("leg_radius_m", "hip_half_width_m", "torso_radius_m", "head_radius_m"):
            _check_range(name, getattr(self, name), 0.005, 0.5)
        check(
            math.isfinite(self.cadence_hz) and 0 < self.cadence_hz <= 5,
            f"person.cadence_hz must be in (0, 5], got {self.cadence_hz}",
        )
        check(
            math.isfinite(self.max_step_m) and 0 < self.max_step_m <= 1.5,
            f"person.max_step_m must be in (0, 1.5], got {self.max_step_m}",
        )
        check(
            self.hip_half_width_m[0] >= self.leg_radius_m[1],
            f"person.hip_half_width_m {self.hip_half_width_m} must be at least the widest leg radius "
            f"{self.leg_radius_m[1]} (the legs would overlap)",
        )


@dataclass(frozen=True)
class CarConfig:
    """A car's body and wheels, in its own frame (x forward along its heading, y to its left).

    Sizes are those of a mid-size hatchback. The lower body is a box of ``length_m x width_m``
    from ``sill_m`` to ``beltline_m``; the cabin a box of ``cabin_length_m x cabin_width_m``
    centred ``cabin_offset_m`` ahead of the car's centre (negative: behind it), from the
    beltline to the roof at ``height_m``; the four wheels stand ``wheelbase_m`` apart along
    the car and ``track_m`` apart across it (centre to centre), each ``wheel_width_m`` wide,
    seen below the sill (above it they are inside the body). The car turns to face its
    direction of travel at up to ``turn_rate_rps``.
    """

    length_m: float = 4.4
    width_m: float = 1.8
    height_m: float = 1.45
    sill_m: float = 0.3
    beltline_m: float = 0.95
    cabin_length_m: float = 2.4
    cabin_width_m: float = 1.6
    cabin_offset_m: float = -0.2
    wheel_radius_m: float = 0.32
    wheel_width_m: float = 0.2
    wheelbase_m: float = 2.65
    track_m: float = 1.55
    turn_rate_rps: float = 1.0
    # paint, drawn per car at every reset; the cabin's glass and the tyres (0-255 RGB)
    body_rgb: tuple[Rgb, ...] = (
        (225, 225, 228), (28, 28, 30), (150, 152, 158), (160, 30, 34), (36, 60, 120), (200, 200, 190), (60, 90, 70),
    )  # fmt: skip
    cabin_rgb: Rgb = (48, 58, 68)
    wheel_rgb: Rgb = (26, 26, 26)

    def __post_init__(self) -> None:
        _check_palette(self.body_rgb, "car.body_rgb")
        check_rgb(self.cabin_rgb, "car.cabin_rgb")
        check_rgb(self.wheel_rgb, "car.wheel_rgb")
        check_ranges(self, "car", positive=(
            "length_m", "width_m", "height_m", "sill_m", "beltline_m", "cabin_length_m", "cabin_width_m",
            "wheel_radius_m", "wheel_width_m", "wheelbase_m", "track_m", "turn_rate_rps",
        ))  # fmt: skip
        check(math.isfinite(self.cabin_offset_m), f"car.cabin_offset_m must be finite, got {self.cabin_offset_m}")
        check(
            self.sill_m < self.beltline_m < self.height_m,
            f"car: sill_m {self.sill_m} < beltline_m {self.beltline_m} < height_m {self.height_m} must hold",
        )
        check(
            self.sill_m <= 2 * self.wheel_radius_m,
            f"car.sill_m {self.sill_m} is above the wheels' tops (2 x wheel_radius_m {self.wheel_radius_m}): the body would float",
        )
        check(
            0.5 * self.wheelbase_m + self.wheel_radius_m <= 0.5 * self.length_m
            and 0.5 * self.track_m + 0.5 * self.wheel_width_m <= 0.5 * self.width_m,
            f"car: the wheels (wheelbase_m {self.wheelbase_m}, track_m {self.track_m}, wheel_radius_m "
            f"{self.wheel_radius_m}, wheel_width_m {self.wheel_width_m}) must lie inside the body "
            f"({self.length_m} x {self.width_m} m)",
        )
        check(
            0.5 * self.cabin_length_m + abs(self.cabin_offset_m) <= 0.5 * self.length_m and self.cabin_width_m <= self.width_m,
            f"car: the cabin ({self.cabin_length_m} x {self.cabin_width_m} m, {self.cabin_offset_m} m ahead of the centre) "
            f"must lie inside the body ({self.length_m} x {self.width_m} m)",
        )

    @property
    def bounding_radius_m(self) -> float:
        """The radius of the circle around the footprint box (what a crowd member's ``radius_m`` must cover)."""
        return math.hypot(0.5 * self.length_m, 0.5 * self.width_m)

    def footprint(self, x: float, y: float, heading: float) -> NDArray[np.float64]:
        """``(4, 2)`` the footprint box's corners (counter-clockwise) for a car at ``(x, y)`` facing ``heading``."""
        c, s = math.cos(heading), math.sin(heading)
        local = 0.5 * np.array(
            [
                [self.length_m, -self.width_m],
                [self.length_m, self.width_m],
                [-self.length_m, self.width_m],
                [-self.length_m, -self.width_m],
            ]
        )
        return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])

    def boxes(self) -> list[tuple[float, float, float, float, float, float, float]]:
        """Its parts as ``(forward, lateral, half length, half width, wheel radius or 0, z_lo, z_hi)``."""
        body = (0.0, 0.0, 0.5 * self.length_m, 0.5 * self.width_m, 0.0, self.sill_m, self.beltline_m)
        cabin = (
            self.cabin_offset_m,
            0.0,
            0.5 * self.cabin_length_m,
            0.5 * self.cabin_width_m,
            0.0,
            self.beltline_m,
            self.height_m,
        )
        r, w = self.wheel_radius_m, 0.5 * self.wheel_width_m
        wheels = [
            (f * 0.5 * self.wheelbase_m, side * 0.5 * self.track_m, r, w, r, 0.0, self.sill_m)
            for f in (1.0, -1.0)
            for side in (1.0, -1.0)
        ]
        return [*wheels, body, cabin]


def turn_to_travel(
    angles: NDArray[np.float64], velocities: NDArray[np.float64], dt: float, max_rate: NDArray[np.float64]
) -> NDArray[np.float64]:
    """``(n,)`` turn rates that bring bodies at ``angles`` ``(n,)`` to face their ``velocities``
    ``(n, 2)`` within one step of ``dt``, at most ``max_rate`` ``(n,)`` rad/s either way; zero
    for a body slower than :data:`STAND_SPEED_MPS` (a parked car keeps its heading)."""
    want = np.arctan2(velocities[:, 1], velocities[:, 0])
    error = (want - angles + math.pi) % (2.0 * math.pi) - math.pi
    moving = np.hypot(velocities[:, 0], velocities[:, 1]) > STAND_SPEED_MPS
    return np.where(moving, np.clip(error / dt, -max_rate, max_rate), 0.0)


#: what a body's shape is sized by: a person's ranges, a car's sizes, or nothing (column, ball)
Sizes = PersonConfig | CarConfig | None
