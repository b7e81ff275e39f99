"""A corridor ceiling: tiles, light panels, sprinkler heads, exit signs and colour targets.

The targets are the ceiling paper's (Fukaya et al.): a line C of one colour (2 cm x 38 cm),
across the corridor, with a square A and a square B (2 cm x 2 cm) of two other colours at its
ends. End A lies at the line's -x end, B at its +x end; a target's colour code ``(A, B, C)``
identifies it. Everything else on the ceiling is scenery that an upward camera sees and a
colour pipeline must not mistake for a target (the exit sign is green like the usual A).

The ceiling is described once, here, as axis-aligned rectangles and discs with a colour and a
label each (:meth:`CeilingConfig.primitives`): the upward camera
(:mod:`envs.sensors.ceiling_camera`) renders them, the top view draws them, and the labels say
which pixels belong to which colour when thresholds are learned from rendered images.

A localizer's map (:meth:`CeilingConfig.map_data`) holds the targets and, under ``plan``, the
ceiling as built (tiles, light panels, sprinklers, the signs with their lettering) as plain values:
a building's ceiling plan, which ``ceiling_target``'s lost test checks its images against.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from core.schema import check, check_rgb
from envs.features.base import FeatureConfig, register_feature

if TYPE_CHECKING:
    from envs.config import WorldConfig

Rgb = tuple[int, int, int]

#: the colour names a target (or a sign) may use: their RGB under the reference light (0-255),
#: fluorescent tape and paper as the paper's targets were made of
PALETTE: dict[str, Rgb] = {
    "green": (40, 190, 70),
    "red": (215, 35, 45),
    "yellow": (235, 215, 40),
    "blue": (40, 80, 215),
    "magenta": (205, 45, 175),
    "cyan": (35, 190, 205),
    "orange": (245, 135, 30),
}

# pixel labels of a rendered ceiling (what each pixel shows); target colours follow as
# LABEL_COLOUR + their index in PALETTE
LABEL_CEILING, LABEL_JOINT, LABEL_LIGHT, LABEL_SPRINKLER, LABEL_SIGN, LABEL_HEAD = 0, 1, 2, 3, 4, 5
LABEL_COLOUR = 16
LABEL_NAMES = {
    LABEL_CEILING: "ceiling",
    LABEL_JOINT: "tile joint",
    LABEL_LIGHT: "light panel",
    LABEL_SPRINKLER: "sprinkler",
    LABEL_SIGN: "exit sign",
    LABEL_HEAD: "head",
    **{LABEL_COLOUR + i: f"target {name}" for i, name in enumerate(PALETTE)},
}


def colour_label(name: str) -> int:
    """The pixel label of target colour ``name``."""
    return LABEL_COLOUR + list(PALETTE).index(name)


@dataclass(frozen=True)
class CeilingTarget:
    """One colour target: its line across the corridor centred at ``(x_m, y_m)``; colours by name."""

    name: str
    y_m: float
    x_m: float = 0.0
    a: str = "green"  # the square at the line's -x end
    b: str = "red"  # the square at the +x end
    c: str = "yellow"  # the line

    def __post_init__(self) -> None:
        for part in ("a", "b", "c"):
            colour = getattr(self, part)
            check(
                colour in PALETTE, f"target {self.name!r}: unknown colour {colour!r} for {part} (colours: {', '.join(PALETTE)})"
            )
        check(
            self.a != self.c and self.b != self.c,
            f"target {self.name!r}: its ends must differ in colour from its line {self.c!r}",
        )

    @property
    def code(self) -> tuple[str, str, str]:
        """The colour code ``(A, B, C)`` that identifies the target."""
        return (self.a, self.b, self.c)


@dataclass(frozen=True)
class SignConfig:
    """A rectangular sign on the ceiling (an exit sign), centred at ``(x_m, y_m)``."""

    x_m: float
    y_m: float
    size_m: tuple[float, float] = (0.36, 0.12)  # across, along
    rgb: Rgb = (20, 160, 85)  # the green of an exit sign
    text_rgb: Rgb = (235, 240, 235)  # its pictogram and lettering: a white band in the middle

    def __post_init__(self) -> None:
        check(
            self.size_m[0] > 0 and self.size_m[1] > 0,
            f"sign at ({self.x_m}, {self.y_m}): size_m must be positive, got {self.size_m}",
        )
        check_rgb(self.rgb, "sign rgb")
        check_rgb(self.text_rgb, "sign text_rgb")

    @property
    def text_size_m(self) -> tuple[float, float]:
        """The white band of its pictogram and lettering (across, along), centred on the sign."""
        return (0.6 * self.size_m[0], 0.3 * self.size_m[1])


class Primitives(NamedTuple):
    """The ceiling as drawing primitives (later ones cover earlier ones).

    Attributes:
        rects: ``(R, 4)`` axis-aligned rectangles ``(x0, y0, x1, y1)``; ``rect_rgb`` ``(R, 3)``; ``rect_label`` ``(R,)``.
        discs: ``(D, 3)`` discs ``(x, y, radius)``; ``disc_rgb`` ``(D, 3)``; ``disc_label`` ``(D,)``.
    """

    rects: NDArray[np.float64]
    rect_rgb: NDArray[np.float64]
    rect_label: NDArray[np.int64]
    discs: NDArray[np.float64]
    disc_rgb: NDArray[np.float64]
    disc_label: NDArray[np.int64]


@register_feature("ceiling")
@dataclass(frozen=True)
class CeilingConfig(FeatureConfig):
    """A flat ceiling at ``height_m`` above the floor, over the whole field.

    Tiles of ``tile_m`` with joints of ``joint_width_m`` (the grid passes through
    ``tile_origin_m``); light panels of ``light_size_m`` (across, along) every
    ``light_pitch_m`` along the corridor at ``x = light_x_m``, the first at ``light_first_y_m``;
    sprinkler heads every ``sprinkler_pitch_m`` at ``x = +-sprinkler_x_m``; the signs; and the
    targets, sorted by ``y_m``, whose parts have the paper's sizes.
    """

    height_m: float = 2.5
    rgb: Rgb = (212, 210, 200)
    tile_m: float = 0.6
    tile_origin_m: tuple[float, float] = (0.3, 0.3)
    joint_width_m: float = 0.01
    joint_rgb: Rgb = (150, 148, 140)
    light_pitch_m: float = 2.4
    light_first_y_m: float = 1.2
    light_x_m: float = 0.0
    light_size_m: tuple[float, float] = (0.3, 0.6)
    light_rgb: Rgb = (255, 255, 250)
    sprinkler_pitch_m: float = 3.6
    sprinkler_first_y_m: float = 3.0
    sprinkler_x_m: float = 0.6
    sprinkler_radius_m: float = 0.03
    sprinkler_rgb: Rgb = (110, 110, 118)
    signs: tuple[SignConfig, ...] = ()
    targets: tuple[CeilingTarget, ...] = ()
    line_length_m: float = 0.38
    line_width_m: float = 0.02
    end_size_m: float = 0.02

    def __post_init__(self) -> None:
        check(self.height_m > 0, f"ceiling.height_m must be > 0, got {self.height_m}")
        for name in (
            "tile_m",
            "light_pitch_m",
            "sprinkler_pitch_m",
            "sprinkler_radius_m",
            "line_length_m",
            "line_width_m",
            "end_size_m",
        ):
            check(getattr(self, name) > 0, f"ceiling.{name} must be > 0, got {getattr(self, name)}")
        check(0 <= self.joint_width_m < self.tile_m, f"ceiling.joint_width_m must be in [0, tile_m), got {self.joint_width_m}")
        check(
            self.light_size_m[0] > 0 and self.light_size_m[1] > 0,
            f"ceiling.light_size_m must be positive, got {self.light_size_m}",
        )
        for name in ("rgb", "joint_rgb", "light_rgb", "sprinkler_rgb"):
            check_rgb(getattr(self, name), f"ceiling.{name}")
        names = [t.name for t in self.targets]
        check(len(set(names)) == len(names), f"ceiling.targets: names repeat: {names}")
        ys = [t.y_m for t in self.targets]
        check(ys == sorted(ys), f"ceiling.targets must be sorted by y_m, got {ys}")
        for t0, t1 in zip(self.targets, self.targets[1:]):
            check(
                t1.y_m - t0.y_m > self.end_size_m,
                f"ceiling.targets {t0.name!r} (y_m {t0.y_m}) and {t1.name!r} (y_m {t1.y_m}) overlap: "
                f"they must be more than {self.end_size_m} m apart",
            )

    def check_world(self, world: WorldConfig, name: str) -> None:
        xmin, ymin, xmax, ymax = world.field_m
        for t in self.targets:
            half = self.target_half_span_m
            check(
                xmin <= t.x_m - half and t.x_m + half <= xmax and ymin <= t.y_m <= ymax,
                f"world {world.name!r}: feature {name!r}: target {t.name!r} at ({t.x_m}, {t.y_m}) is not inside the field {world.field_m}",
            )

    # ------------------------------------------------------------------ geometry
    @property
    def target_half_span_m(self) -> float:
        """From a target's centre to the outer edge of an end square."""
        return self.line_length_m / 2 + self.end_size_m

    def end_xy(self, target: CeilingTarget) -> tuple[tuple[float, float], tuple[float, float]]:
        """Centres of the squares A and B of ``target``: just beyond the ends of its line."""
        offset = self.line_length_m / 2 + self.end_size_m / 2
        return (target.x_m - offset, target.y_m), (target.x_m + offset, target.y_m)

    def target_by_code(self) -> dict[tuple[str, str, str], list[str]]:
        """Target names by colour code (a code shared by several targets is ambiguous on its own)."""
        out: dict[tuple[str, str, str], list[str]] = {}
        for t in self.targets:
            out.setdefault(t.code, []).append(t.name)
        return out

    def primitives(self, extent_m: tuple[float, float, float, float]) -> Primitives:
        """Everything on the ceiling over ``extent_m`` ``(xmin, ymin, xmax, ymax)`` except the
        tile joints (drawn analytically), in drawing order."""
        x0, y0, x1, y1 = extent_m
        rects: list[tuple[float, float, float, float]] = []
        rgb: list[Rgb] = []
        labels: list[int] = []

        def rect(cx: float, cy: float, w: float, h: float, colour: Rgb, label: int) -> None:
            rects.append((cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2))
            rgb.append(colour)
            labels.append(label)

        lw, lh = self.light_size_m
        for y in _pitch(self.light_first_y_m, self.light_pitch_m, y0, y1):
            rect(self.light_x_m, y, lw, lh, self.light_rgb, LABEL_LIGHT)
        for sign in self.signs:
            w, h = sign.size_m
            rect(sign.x_m, sign.y_m, w, h, sign.rgb, LABEL_SIGN)
            rect(sign.x_m, sign.y_m, *sign.text_size_m, sign.text_rgb, LABEL_SIGN)
        for t in self.targets:
            rect(t.x_m, t.y_m, self.line_length_m, self.line_width_m, PALETTE[t.c], colour_label(t.c))
            (ax, ay), (bx, by) = self.end_xy(t)
            rect(ax, ay, self.end_size_m, self.end_size_m, PALETTE[t.a], colour_label(t.a))
            rect(bx, by, self.end_size_m, self.end_size_m, PALETTE[t.b], colour_label(t.b))
        discs = [
            (side * self.sprinkler_x_m, y, self.sprinkler_radius_m)
            for y in _pitch(self.sprinkler_first_y_m, self.sprinkler_pitch_m, y0, y1)
            for side in (-1.0, 1.0)
            if x0 <= side * self.sprinkler_x_m <= x1
        ]
        return Primitives(
            np.asarray(rects, dtype=np.float64).reshape(-1, 4),
            np.asarray(rgb, dtype=np.float64).reshape(-1, 3),
            np.asarray(labels, dtype=np.int64),
            np.asarray(discs, dtype=np.float64).reshape(-1, 3),
            np.tile(np.asarray(self.sprinkler_rgb, dtype=np.float64), (len(discs), 1)),
            np.full(len(discs), LABEL_SPRINKLER, dtype=np.int64),
        )

    # ------------------------------------------------------------------ plug-in hooks
    def map_data(self) -> dict[str, Any]:
        targets = []
        for t in self.targets:
            a_xy, b_xy = self.end_xy(t)
            targets.append({"name": t.name, "x_m": t.x_m, "y_m": t.y_m, "a": t.a, "b": t.b, "c": t.c, "a_xy": a_xy, "b_xy": b_xy})
        return {
            "type": self.type_name,
            "height_m": self.height_m,
            "line_length_m": self.line_length_m,
            "line_width_m": self.line_width_m,
            "end_size_m": self.end_size_m,
            "targets": targets,
            "palette": {name: list(rgb) for name, rgb in PALETTE.items()},
            # the ceiling as built (a building's ceiling plan), for a lost test by the scenery
            "plan": {
                "tile_m": self.tile_m,
                "tile_origin_m": list(self.tile_origin_m),
                "joint_width_m": self.joint_width_m,
                "lights": {
                    "pitch_m": self.light_pitch_m,
                    "first_y_m": self.light_first_y_m,
                    "x_m": self.light_x_m,
                    "size_m": list(self.light_size_m),
                },
                "sprinklers": {
                    "pitch_m": self.sprinkler_pitch_m,
                    "first_y_m": self.sprinkler_first_y_m,
                    "x_m": self.sprinkler_x_m,
                    "radius_m": self.sprinkler_radius_m,
                },
                "signs": [
                    {"x_m": s.x_m, "y_m": s.y_m, "size_m": list(s.size_m), "text_size_m": list(s.text_size_m)} for s in self.signs
                ],
            },
        }

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        prims = self.primitives(world.arena_m)
        for (rx0, ry0, rx1, ry1), colour, label in zip(prims.rects, prims.rect_rgb, prims.rect_label):
            if label == LABEL_LIGHT:
                canvas.rect(rx0, ry0, rx1, ry1, (235, 235, 200), 1)  # outlined: the floor stays readable
            else:
                canvas.rect(rx0, ry0, rx1, ry1, tuple(int(c) for c in colour), 0)


def _pitch(first: float, pitch: float, lo: float, hi: float) -> list[float]:
    """The positions ``first + k pitch`` (any integer ``k``) inside ``[lo, hi]``."""
    k0 = math.ceil((lo - first) / pitch)
    k1 = math.floor((hi - first) / pitch)
    return [first + k * pitch for k in range(k0, k1 + 1)]
