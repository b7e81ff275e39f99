"""Every body's parts between resets: sizes and paint drawn per reset, the people's gait.

:class:`FigureModel` lays out the parts of the bodies the crowds declare (:mod:`envs.bodies`:
columns, balls, people, cars), draws each person's sizes and clothes and each car's paint at a
reset, moves the people's gait on every step, and poses the :class:`~envs.figures.Figures` of a
step.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from envs.bodies import (
    BALL,
    BALL_RGB,
    COLUMN,
    COLUMN_RGB,
    CROTCH_FRACTION,
    HEAD,
    HIP_FRACTION,
    LEG,
    SHOULDER_FRACTION,
    STAND_SPEED_MPS,
    TORSO,
    CarConfig,
    PersonConfig,
    Rgb,
    Sizes,
)
from envs.figures import BoxLayout, Dress, Figures, Layout, UprightCut, pose_parts


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
        self._upright_cuts: dict[tuple[float, bool], UprightCut] | None = {} if self.layout.upright else None
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
        xy, slope = pose_parts(positions, m.row, m.kind, m.lateral, m.swing_sign, self.heading, self.swing_tan)
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
