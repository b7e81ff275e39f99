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

**Sections.** :meth:`Figures.section` gives the discs cut at one height (centres, radii, the
body row each belongs to and whether it blocks a camera's view) and the sides of the boxes
cut there, as segments. The world makes one
:class:`Figures` per step (lazily, when a sensor asks) and caches each height's section.

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
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from localizers.schema import check, check_ranges, check_rgb

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


#: shared, read-only: a section without box sides
_NO_POINTS = np.zeros((0, 2))
_NO_ROWS = np.zeros(0, dtype=np.int64)
_NO_POINTS.setflags(write=False)
_NO_ROWS.setflags(write=False)


class Appearance(NamedTuple):
    """The moving bodies as a camera renders them (:meth:`Figures.appearance`).

    Attributes:
        disc_xy: ``(P, 2)`` centres, ``disc_r`` ``(P,)``, ``disc_z0``, ``disc_z1`` ``(P,)`` the
            heights each spans, ``disc_rgb`` ``(P, 3)``, ``disc_row`` ``(P,)`` its body row.
        side_a, side_b: ``(4Q, 2)`` the sides of the box parts (four per box, counter-clockwise),
            ``side_z0``, ``side_z1``, ``side_rgb`` ``(4Q, 3)``, ``side_box`` ``(4Q,)`` which box.
    """

    disc_xy: NDArray[np.float64]
    disc_r: NDArray[np.float64]
    disc_z0: NDArray[np.float64]
    disc_z1: NDArray[np.float64]
    disc_rgb: NDArray[np.float64]
    disc_row: NDArray[np.int64]
    side_a: NDArray[np.float64]
    side_b: NDArray[np.float64]
    side_z0: NDArray[np.float64]
    side_z1: NDArray[np.float64]
    side_rgb: NDArray[np.float64]
    side_box: NDArray[np.int64]


class Section(NamedTuple):
    """What a horizontal plane cuts through the bodies at one height: discs, and box sides.

    Attributes:
        centres: ``(K, 2)``; ``radii``: ``(K,)``.
        rows: ``(K,)`` the body row each disc belongs to.
        occludes: ``(K,)`` whether the disc blocks a camera's sight line.
        seg_a, seg_b: ``(S, 2)`` the ends of the sides of the boxes cut (a car's body, its
            wheels), four per box; ``seg_rows``: ``(S,)`` the body row of each.
    """

    centres: NDArray[np.float64]
    radii: NDArray[np.float64]
    rows: NDArray[np.int64]
    occludes: NDArray[np.bool_]
    seg_a: NDArray[np.float64] = _NO_POINTS
    seg_b: NDArray[np.float64] = _NO_POINTS
    seg_rows: NDArray[np.int64] = _NO_ROWS

    def walls(self, seg_a: NDArray[np.float64], seg_b: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The static walls ``seg_a, seg_b`` ``(W, 2)`` a sensor sees at this height, followed
        by the box sides of the section (the walls themselves, no copy, when there are none)."""
        if not self.seg_a.shape[0]:
            return seg_a, seg_b
        return np.concatenate((seg_a, self.seg_a)), np.concatenate((seg_b, self.seg_b))


@numba.njit(cache=True)
def _half_chord(radius: float, centre_z: float, height: float) -> float:
    """Half the chord a horizontal plane at ``height`` cuts through a circle of ``radius``
    centred at ``centre_z`` in a vertical plane (a ball's section radius, a wheel's half length); 0 outside it."""
    dz = height - centre_z
    return math.sqrt(max(radius * radius - dz * dz, 0.0))


@numba.njit(cache=True)
def _cut(
    height: float,
    xy: NDArray[np.float64],
    slope: NDArray[np.float64],
    z_ref: NDArray[np.float64],
    z_lo: NDArray[np.float64],
    z_hi: NDArray[np.float64],
    radius: NDArray[np.float64],
    kind: NDArray[np.int64],
    keep: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """Indices, centres and radii of the parts that span ``height`` (among those ``keep`` marks), in part order."""
    n = xy.shape[0]
    index = np.empty(n, dtype=np.int64)
    centres = np.empty((n, 2))
    radii = np.empty(n)
    k = 0
    for p in range(n):
        if not (keep[p] and z_lo[p] <= height < z_hi[p]):
            continue
        r = radius[p]
        if kind[p] == BALL:
            r = _half_chord(r, z_ref[p], height)
            if r <= 0.0:
                continue
        index[k] = p
        if slope[p, 0] == 0.0 and slope[p, 1] == 0.0:
            centres[k, 0] = xy[p, 0]
            centres[k, 1] = xy[p, 1]
        else:
            centres[k, 0] = xy[p, 0] + slope[p, 0] * (height - z_ref[p])
            centres[k, 1] = xy[p, 1] + slope[p, 1] * (height - z_ref[p])
        radii[k] = r
        k += 1
    return index[:k], centres[:k], radii[:k]


@numba.njit(cache=True)
def _cut_boxes(
    height: float,
    positions: NDArray[np.float64],
    angles: NDArray[np.float64],
    row: NDArray[np.int64],
    offset: NDArray[np.float64],
    half: NDArray[np.float64],
    wheel_r: NDArray[np.float64],
    z_lo: NDArray[np.float64],
    z_hi: NDArray[np.float64],
    keep: NDArray[np.bool_],
    whole: bool = False,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """The sides ``(4K, 2)`` ends a, ends b and ``(4K,)`` rows of the boxes that span ``height``
    (with ``whole``: of every box kept, a wheel as a box of its diameter).

    Box ``p`` sits ``offset[p]`` (forward, left) from its body's centre in the body's frame,
    with half sizes ``half[p]`` (along, across); a wheel (``wheel_r > 0``) is as long as its
    chord at ``height``.
    """
    n = row.shape[0]
    a = np.empty((4 * n, 2))
    b = np.empty((4 * n, 2))
    rows = np.empty(4 * n, dtype=np.int64)
    k = 0
    for p in range(n):
        if not (keep[p] and (whole or z_lo[p] <= height < z_hi[p])):
            continue
        hl = half[p, 0]
        if wheel_r[p] > 0.0:  # a wheel standing on the floor: its centre at the height of its radius
            hl = wheel_r[p] if whole else _half_chord(wheel_r[p], wheel_r[p], height)
            if hl <= 0.0:
                continue
        hw = half[p, 1]
        body = row[p]
        c = math.cos(angles[body])
        s = math.sin(angles[body])
        cx = positions[body, 0] + offset[p, 0] * c - offset[p, 1] * s
        cy = positions[body, 1] + offset[p, 0] * s + offset[p, 1] * c
        # corners counter-clockwise: front right, front left, rear left, rear right
        xs = (hl, hl, -hl, -hl)
        ys = (-hw, hw, hw, -hw)
        for i in range(4):
            j = (i + 1) % 4
            a[k + i, 0] = cx + xs[i] * c - ys[i] * s
            a[k + i, 1] = cy + xs[i] * s + ys[i] * c
            b[k + i, 0] = cx + xs[j] * c - ys[j] * s
            b[k + i, 1] = cy + xs[j] * s + ys[j] * c
            rows[k + i] = body
        k += 4
    return a[:k], b[:k], rows[:k]


@numba.njit(cache=True)
def _pose_parts(
    positions: NDArray[np.float64],
    row: NDArray[np.int64],
    kind: NDArray[np.int64],
    lateral: NDArray[np.float64],
    swing_sign: NDArray[np.float64],
    heading: NDArray[np.float64],
    swing_tan: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Reference points ``(P, 2)`` and slopes ``(P, 2)`` of every part for the bodies' poses.

    A part sits ``lateral`` to the left of its body's centre (a hip joint); a leg's centre
    moves ``-swing_sign tan(alpha)`` per metre up along the body's heading (forward below the hip
    for the leg that swings forward).
    """
    n = row.shape[0]
    xy = np.empty((n, 2))
    slope = np.zeros((n, 2))
    for p in range(n):
        b = row[p]
        x = positions[b, 0]
        y = positions[b, 1]
        if kind[p] == LEG:
            c = math.cos(heading[b])
            s = math.sin(heading[b])
            x -= lateral[p] * s
            y += lateral[p] * c
            t = -swing_sign[p] * swing_tan[b]
            slope[p, 0] = t * c
            slope[p, 1] = t * s
        xy[p, 0] = x
        xy[p, 1] = y
    return xy, slope


class Layout(NamedTuple):
    """Every part's static facts (``(P,)`` each, in body-row order), fixed between resets."""

    row: NDArray[np.int64]  # the body row it belongs to
    kind: NDArray[np.int64]  # LEG, TORSO, HEAD, COLUMN or BALL
    lateral: NDArray[np.float64]  # its offset to the left of the body's centre (a hip joint)
    swing_sign: NDArray[np.float64]  # +1 / -1 for the legs (they swing in opposition), 0 otherwise
    z_ref: NDArray[np.float64]  # the height of its reference point (a leg's hip joint; a ball's centre)
    z_lo: NDArray[np.float64]
    z_hi: NDArray[np.float64]
    radius: NDArray[np.float64]
    occludes: NDArray[np.bool_]
    every: NDArray[np.bool_]  # all true: the mask that keeps every part

    @property
    def upright(self) -> bool:
        """Whether no part leans (no legs): then which parts a height cuts, and their radii,
        stay the same between resets, and only the bodies' positions move the sections."""
        return not bool(np.any(self.kind == LEG))


class BoxLayout(NamedTuple):
    """Every box part's static facts (a car's body, cabin and wheels), in body-row order."""

    row: NDArray[np.int64]  # (Q,) the body row it belongs to
    offset: NDArray[np.float64]  # (Q, 2) its centre (forward, left) of the body's centre, in the body's frame
    half: NDArray[np.float64]  # (Q, 2) half its length (along the body) and width
    wheel_r: NDArray[np.float64]  # (Q,) a wheel's radius (its length is its chord at the height), 0 for a box
    z_lo: NDArray[np.float64]
    z_hi: NDArray[np.float64]
    occludes: NDArray[np.bool_]
    every: NDArray[np.bool_]


#: per (height, mask) of an upright layout: the rows of the parts cut there, their radii there, whether they
#: occlude, and how to take their positions (a slice where the rows are consecutive)
_UprightCut = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_], "slice | NDArray[np.int64]"]


def consecutive(rows: NDArray[np.int64]) -> slice | NDArray[np.int64]:
    """Consecutive rows as a slice (indexing gives a view), else the rows themselves."""
    if rows.size and np.array_equal(rows, np.arange(rows[0], rows[0] + rows.size)):
        return slice(int(rows[0]), int(rows[0]) + rows.size)
    return rows


class Dress(NamedTuple):
    """What every step's :class:`Figures` share between two resets (made by :class:`FigureModel`).

    Attributes:
        layout: the disc parts; ``boxes``: the box parts (None: no cars).
        part_rgb: ``(P, 3)`` every disc part's colour and ``box_rgb`` ``(Q, 3)`` every box
            part's, 0-255 (what a camera sees).
        upright_cuts: for an upright layout (no legs), its cuts by (height, occluders only),
            filled on first use and shared by every step's figures; None where parts lean.
        no_slope: ``(P, 2)`` zeros (read-only), an upright layout's slopes.
    """

    layout: Layout
    boxes: BoxLayout | None
    part_rgb: NDArray[np.float64]
    box_rgb: NDArray[np.float64]
    upright_cuts: dict[tuple[float, bool], _UprightCut] | None
    no_slope: NDArray[np.float64]


class Figures:
    """The parts of every body at one step, and their cached sections by height (read-only).

    Made by :meth:`FigureModel.pose`; a snapshot of the world holds one. Everything that stays
    the same between resets is in the shared :class:`Dress`, so that making one costs a few
    attribute stores: the world makes one every step, whose sensors read one section of it
    or none (for an upright layout, a section is a view of the positions: :meth:`_cut`).
    """

    __slots__ = ("_angles", "_appearance", "_dress", "_occluders", "_positions", "_sections", "_slope", "_xy")

    def __init__(
        self,
        dress: Dress,
        positions: NDArray[np.float64] | None,
        angles: NDArray[np.float64] | None = None,
        xy: NDArray[np.float64] | None = None,
        slope: NDArray[np.float64] | None = None,
    ) -> None:
        self._dress = dress
        self._appearance: Appearance | None = None
        self._positions = positions  # the bodies' positions (an upright layout's parts stand at their centres; boxes)
        self._angles = angles  # the bodies' headings (the boxes turn with them)
        self._xy = xy  # None: the parts stand at their bodies' centres (taken from the positions on first use)
        self._slope = slope  # None: no part leans
        self._sections: dict[float, Section] = {}
        self._occluders: dict[float, Section] = {}

    @property
    def layout(self) -> Layout:
        """The disc parts' static facts."""
        return self._dress.layout

    @property
    def part_rgb(self) -> NDArray[np.float64]:
        """``(P, 3)`` every disc part's colour, 0-255 (what a camera sees)."""
        return self._dress.part_rgb

    @property
    def box_rgb(self) -> NDArray[np.float64]:
        """``(Q, 3)`` every box part's colour, 0-255."""
        return self._dress.box_rgb

    @property
    def xy(self) -> NDArray[np.float64]:
        """``(P, 2)`` every disc part's reference point."""
        if self._xy is None:
            assert self._positions is not None
            self._xy = self._positions[self._dress.layout.row]
        return self._xy

    @property
    def slope(self) -> NDArray[np.float64]:
        """``(P, 2)`` every disc part's shift of its centre per metre up."""
        return self._dress.no_slope if self._slope is None else self._slope

    def section(self, height_m: float) -> Section:
        """The discs and box sides cut at ``height_m`` (cached per height), in part order: body rows ascending."""
        found = self._sections.get(height_m)
        if found is None:
            found = self._sections[height_m] = self._cut(height_m, False)
        return found

    def occluders(self, height_m: float) -> Section:
        """The discs and box sides at ``height_m`` that block a camera's sight lines (cached per height)."""
        found = self._occluders.get(height_m)
        if found is None:
            found = self._occluders[height_m] = self._cut(height_m, True)
        return found

    def appearance(self) -> Appearance:
        """Every part as a camera sees it (made once per step, on first use): the discs upright
        at their centre half-way up (a leg's lean is a few centimetres there), the boxes whole
        (a wheel as a box of its diameter), each with its height interval and colour. Legs
        start at the floor."""
        if self._appearance is not None:
            return self._appearance
        m, q, part_rgb = self._dress.layout, self._dress.boxes, self._dress.part_rgb
        z0 = np.maximum(m.z_lo, 0.0)
        centres = self.xy + self.slope * (0.5 * (z0 + m.z_hi) - m.z_ref)[:, None] if m.row.size else np.zeros((0, 2))
        if q is None:
            none = np.zeros((0, 2))
            out = Appearance(centres, m.radius, z0, m.z_hi, part_rgb, m.row, none, none, np.zeros(0), np.zeros(0),
                             np.zeros((0, 3)), np.zeros(0, dtype=np.int64))  # fmt: skip
        else:
            assert self._positions is not None and self._angles is not None
            a, b, _ = _cut_boxes(
                0.0, self._positions, self._angles, q.row, q.offset, q.half, q.wheel_r, q.z_lo, q.z_hi, q.every, True
            )
            rep = np.repeat
            out = Appearance(centres, m.radius, z0, m.z_hi, part_rgb, m.row, a, b, rep(q.z_lo, 4), rep(q.z_hi, 4),
                             rep(self._dress.box_rgb, 4, axis=0), rep(np.arange(q.row.size), 4))  # fmt: skip
        self._appearance = out
        return out

    def _cut(self, height_m: float, occluders_only: bool) -> Section:
        m, q, upright = self._dress.layout, self._dress.boxes, self._dress.upright_cuts
        if upright is None:  # leaning parts (legs): cut at this step's pose
            keep = m.occludes if occluders_only else m.every
            index, centres, radii = _cut(height_m, self.xy, self.slope, m.z_ref, m.z_lo, m.z_hi, m.radius, m.kind, keep)
            discs = Section(centres, radii, m.row[index], m.occludes[index])  # fresh arrays: read, never write
        else:  # upright: the same parts at every step, only their bodies' positions move
            cut = upright.get((height_m, occluders_only))
            if cut is None:
                cut = upright[(height_m, occluders_only)] = self._upright_cut(height_m, occluders_only)
            rows, radii, occludes, take = cut
            assert self._positions is not None
            discs = Section(self._positions[take], radii, rows, occludes)  # a slice: a view of the positions, no copy
        if q is None:
            return discs
        assert self._positions is not None and self._angles is not None
        keep = q.occludes if occluders_only else q.every
        a, b, rows = _cut_boxes(height_m, self._positions, self._angles, q.row, q.offset, q.half, q.wheel_r, q.z_lo, q.z_hi, keep)
        return discs._replace(seg_a=a, seg_b=b, seg_rows=rows)

    def _upright_cut(self, height_m: float, occluders_only: bool) -> _UprightCut:
        """An upright layout's cut at ``height_m`` (made once per height between resets): which
        parts it cuts and their radii there."""
        m = self._dress.layout
        keep = m.occludes if occluders_only else m.every
        index, _, radii = _cut(height_m, self.xy, self.slope, m.z_ref, m.z_lo, m.z_hi, m.radius, m.kind, keep)
        rows = m.row[index]
        rows.setflags(write=False)
        return rows, radii, m.occludes[index], consecutive(rows)


#: what a body's shape is sized by: a person's ranges, a car's sizes, or nothing (column, ball)
Sizes = PersonConfig | CarConfig | None


class FigureModel:
    """Every body's parts, their sizes (drawn per reset) and the people's gait state.

    Args:
        shapes: per body row after our robot (row 1 on), ``(shape, footprint radius,
            height_m, occludes, sizes)``: sizes a :class:`PersonConfig` for a person, a
            :class:`CarConfig` for a car, None otherwise.

    The robot (row 0) has no parts: its own sensors sit on it.
    """

    def __init__(self, shapes: list[tuple[str, float, float, bool, Sizes]]) -> None:
        self.shapes = shapes
        self.body_count = 1 + len(shapes)
        self.person_rows = np.array([i + 1 for i, s in enumerate(shapes) if s[0] == "person"], dtype=np.int64)
        self._persons = [s[4] for s in shapes if s[0] == "person"]
        self.heading = np.zeros(self.body_count)
        self.phase = np.zeros(self.body_count)
        self.swing_tan = np.zeros(self.body_count)
        self._hip_m = np.zeros(self.body_count)
        self._cadence = np.zeros(self.body_count)
        self._max_step = np.zeros(self.body_count)
        self.boxes = _box_layout(shapes)
        #: ``(Q, 3)`` the box parts' colours: a car's body paint (drawn per reset), its cabin's glass, its tyres
        self.box_rgb = np.zeros((0 if self.boxes is None else self.boxes.row.size, 3))
        self._build(None)
        self._paint(None)

    @property
    def has_people(self) -> bool:
        return self.person_rows.size > 0

    def _build(self, rng: np.random.Generator | None) -> None:
        """Lay out the disc parts; people get sizes from ``rng`` (mid-range sizes without one)."""
        # one tuple per part: (row, kind, lateral, swing sign, z_ref, z_lo, z_hi, radius, occludes)
        parts: list[tuple[int, int, float, float, float, float, float, float, bool]] = []
        for i, (shape, r, height, occ, sizes) in enumerate(self.shapes):
            b = i + 1
            if shape == "column":
                parts.append((b, COLUMN, 0.0, 0.0, 0.0, -math.inf, height, r, occ))
            elif shape == "ball":
                parts.append((b, BALL, 0.0, 0.0, r, 0.0, 2.0 * r, r, occ))
            elif shape == "person":
                person = sizes
                assert isinstance(person, PersonConfig)

                def draw(lo_hi: tuple[float, float]) -> float:
                    return float(rng.uniform(*lo_hi)) if rng is not None else 0.5 * (lo_hi[0] + lo_hi[1])

                stature = draw(person.height_m)
                leg_r, hip_w = draw(person.leg_radius_m), draw(person.hip_half_width_m)
                torso_r, head_r = draw(person.torso_radius_m), draw(person.head_radius_m)
                hip, crotch, shoulder = HIP_FRACTION * stature, CROTCH_FRACTION * stature, SHOULDER_FRACTION * stature
                parts += [
                    (b, LEG, hip_w, 1.0, hip, -math.inf, crotch, leg_r, occ),  # the left leg swings forward first
                    (b, LEG, -hip_w, -1.0, hip, -math.inf, crotch, leg_r, occ),
                    (b, TORSO, 0.0, 0.0, 0.0, crotch, shoulder, torso_r, occ),
                    (b, HEAD, 0.0, 0.0, 0.0, shoulder, stature, head_r, occ),
                ]
                self._hip_m[b] = hip
                self._cadence[b] = person.cadence_hz
                self._max_step[b] = person.max_step_m
            # a car has box parts only (_box_layout)
        #: ``(P, 3)`` every disc part's colour (a person's clothes and hair: :meth:`_paint`)
        self.part_rgb = np.array([BALL_RGB if kind == BALL else COLUMN_RGB for _, kind, *_ in parts], dtype=np.float64).reshape(
            -1, 3
        )
        columns = list(zip(*parts)) if parts else [()] * 9
        lateral, sign, z_ref, z_lo, z_hi, radius = (np.asarray(c, dtype=np.float64) for c in columns[2:8])
        self.layout = Layout(
            np.asarray(columns[0], dtype=np.int64),
            np.asarray(columns[1], dtype=np.int64),
            lateral,
            sign,
            z_ref,
            z_lo,
            z_hi,
            radius,
            np.asarray(columns[8], dtype=np.bool_),
            np.ones(len(parts), dtype=np.bool_),
        )
        for array in self.layout:
            array.setflags(write=False)
        #: an upright layout's cuts by (height, occluders only), valid until the next layout
        self._upright_cuts: dict[tuple[float, bool], _UprightCut] | None = {} if self.layout.upright else None
        self._no_slope = np.zeros((len(parts), 2))
        self._no_slope.setflags(write=False)

    def _paint(self, rng: np.random.Generator | None) -> None:
        """Clothes and hair for every person, paint for every car, from their palettes (each
        palette's first colour without ``rng``); then the :class:`Dress` the figures share (the
        layout is made before: :meth:`_build` is always followed by this)."""
        m = self.layout
        self.part_rgb, self.box_rgb = self.part_rgb.copy(), self.box_rgb.copy()  # figures handed out keep theirs

        def pick(palette: tuple[Rgb, ...]) -> Rgb:
            return palette[int(rng.integers(len(palette)))] if rng is not None else palette[0]

        for i, (shape, _, _, _, sizes) in enumerate(self.shapes):
            if shape == "person":
                assert isinstance(sizes, PersonConfig)
                parts = np.flatnonzero(m.row == i + 1)
                shirt, trousers, head = pick(sizes.shirt_rgb), pick(sizes.trousers_rgb), pick(sizes.head_rgb)
                for p in parts:
                    kind = m.kind[p]
                    self.part_rgb[p] = trousers if kind == LEG else shirt if kind == TORSO else head
            elif shape == "car" and self.boxes is not None:
                assert isinstance(sizes, CarConfig)
                boxes = np.flatnonzero(self.boxes.row == i + 1)  # four wheels, the body, the cabin (CarConfig.boxes)
                self.box_rgb[boxes[:4]] = sizes.wheel_rgb
                self.box_rgb[boxes[4]] = pick(sizes.body_rgb)
                self.box_rgb[boxes[5]] = sizes.cabin_rgb
        self.part_rgb.setflags(write=False)
        self.box_rgb.setflags(write=False)
        # every Figures made from now on shares these (a new Dress: figures handed out keep theirs)
        self._dress = Dress(m, self.boxes, self.part_rgb, self.box_rgb, self._upright_cuts, self._no_slope)
        self._empty: Figures | None = None
        if not m.row.size and self.boxes is None:
            self._empty = Figures(self._dress._replace(upright_cuts=None), None, None, np.zeros((0, 2)), np.zeros((0, 2)))

    def reset(self, rng: np.random.Generator, velocities: NDArray[np.float64]) -> None:
        """New sizes for every person (drawn from ``rng`` only when there are people), standing still.

        A person starts facing a random direction with a random gait phase. Clothes and paint
        are drawn from a child of ``rng`` (:meth:`numpy.random.Generator.spawn`), which leaves
        ``rng``'s own draws as they were.
        """
        self.swing_tan[:] = 0.0
        if not self.has_people:
            if self.boxes is not None:
                self._paint(rng.spawn(1)[0])
            return
        self._build(rng)
        self._paint(rng.spawn(1)[0])
        rows = self.person_rows
        self.heading[rows] = rng.uniform(-math.pi, math.pi, rows.size)
        self.phase[rows] = rng.uniform(0.0, 2.0 * math.pi, rows.size)
        self.advance(velocities, 0.0)

    def advance(self, velocities: NDArray[np.float64], dt: float) -> None:
        """Move the people's gait on by ``dt`` at their current ``velocities`` ``(B, 2)``."""
        if not self.has_people:
            return
        rows = self.person_rows
        v = velocities[rows]
        speed = np.hypot(v[:, 0], v[:, 1])
        walking = speed > STAND_SPEED_MPS
        cadence = self._cadence[rows]
        self.heading[rows] = np.where(walking, np.arctan2(v[:, 1], v[:, 0]), self.heading[rows])
        self.phase[rows] = (self.phase[rows] + np.where(walking, math.pi * cadence * dt, 0.0)) % (2.0 * math.pi)
        step = np.minimum(speed / cadence, self._max_step[rows])
        amplitude = np.where(walking, np.arcsin(np.minimum(step / (2.0 * self._hip_m[rows]), 1.0)), 0.0)
        self.swing_tan[rows] = np.tan(amplitude * np.sin(self.phase[rows]))

    def pose(self, positions: NDArray[np.float64], angles: NDArray[np.float64] | None = None) -> Figures:
        """The :class:`Figures` of the bodies at ``positions`` ``(B, 2)`` in their current gait;
        ``angles`` ``(B,)``: their headings, which the box parts (cars) turn with (needed only
        when there are box parts)."""
        dress = self._dress
        if dress.boxes is not None and angles is None:
            raise ValueError("FigureModel.pose: the bodies include cars, whose boxes turn with the heading: pass angles")
        if self._empty is not None:  # nothing but our robot: one empty figure, its sections cached for good
            return self._empty
        if dress.upright_cuts is not None:  # no legs: each part stands at its body's centre, nothing to pose
            return Figures(dress, positions, angles)
        m = dress.layout
        xy, slope = _pose_parts(positions, m.row, m.kind, m.lateral, m.swing_sign, self.heading, self.swing_tan)
        return Figures(dress, positions, angles, xy, slope)


def _box_layout(shapes: list[tuple[str, float, float, bool, Sizes]]) -> BoxLayout | None:
    """The box parts of the cars among ``shapes`` (fixed sizes: made once), None without any."""
    parts = []
    for i, (shape, _, _, occ, sizes) in enumerate(shapes):
        if shape == "car":
            assert isinstance(sizes, CarConfig)
            parts += [(i + 1, box, occ) for box in sizes.boxes()]
    if not parts:
        return None
    geometry = np.array([box for _, box, _ in parts], dtype=np.float64)  # (Q, 7): forward, lateral, hl, hw, r, z_lo, z_hi
    layout = BoxLayout(
        np.array([row for row, _, _ in parts], dtype=np.int64),
        np.ascontiguousarray(geometry[:, 0:2]),
        np.ascontiguousarray(geometry[:, 2:4]),
        np.ascontiguousarray(geometry[:, 4]),
        np.ascontiguousarray(geometry[:, 5]),
        np.ascontiguousarray(geometry[:, 6]),
        np.array([occ for _, _, occ in parts], dtype=np.bool_),
        np.ones(len(parts), dtype=np.bool_),
    )
    for array in layout:
        array.setflags(write=False)
    return layout
