"""The bodies' parts at one step, and what a horizontal plane cuts through them.

:class:`Figures` holds every body's parts posed for one step (made by
:class:`envs.figure_model.FigureModel`; a :class:`~envs.state.WorldState` carries one) and gives
their :class:`Section` at a sensor's height (discs, and the sides of a car's boxes) and their
:class:`Appearance` for a camera. The static facts shared by every step between two resets are
the :class:`Layout` of the disc parts, the :class:`BoxLayout` of the box parts and the
:class:`Dress` that holds them with the colours. What the parts are is :mod:`envs.bodies`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np
from numpy.typing import NDArray

from envs.bodies import BALL, LEG

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
def pose_parts(
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
UprightCut = tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.bool_], "slice | NDArray[np.int64]"]


def consecutive(rows: NDArray[np.int64]) -> slice | NDArray[np.int64]:
    """Consecutive rows as a slice (indexing gives a view), else the rows themselves."""
    if rows.size and np.array_equal(rows, np.arange(rows[0], rows[0] + rows.size)):
        return slice(int(rows[0]), int(rows[0]) + rows.size)
    return rows


class Dress(NamedTuple):
    """What every step's :class:`Figures` share between two resets (made by :class:`~envs.figure_model.FigureModel`).

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
    upright_cuts: dict[tuple[float, bool], UprightCut] | None
    no_slope: NDArray[np.float64]


class Figures:
    """The parts of every body at one step, and their cached sections by height (read-only).

    Made by :meth:`envs.figure_model.FigureModel.pose`; a snapshot of the world holds one. Everything that stays
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

    def _upright_cut(self, height_m: float, occluders_only: bool) -> UprightCut:
        """An upright layout's cut at ``height_m`` (made once per height between resets): which
        parts it cuts and their radii there."""
        m = self._dress.layout
        keep = m.occludes if occluders_only else m.every
        index, _, radii = _cut(height_m, self.xy, self.slope, m.z_ref, m.z_lo, m.z_hi, m.radius, m.kind, keep)
        rows = m.row[index]
        rows.setflags(write=False)
        return rows, radii, m.occludes[index], consecutive(rows)
