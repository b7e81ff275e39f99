"""Outdoor scenery as static solids: buildings with façades, poles (street lamps, utility poles) and trees.

Each is a feature type (:mod:`envs.features.base`) whose :meth:`~FeatureConfig.solids` are
convex prisms with a height interval and an appearance; the world collides with their sides
where they reach the floor, range sensors see the sides that span their height, the
localizers' map holds them, and cameras render their colours.

**Buildings** (``type: buildings``): convex footprints (counter-clockwise; a concave building
is several convex parts) up to ``height_m``, each side a façade (:class:`FacadeConfig`): a
wall colour, optional vertical panels of another colour, pilasters (columns), windows floor by
floor and doors, so that a façade has vertical edges at known places, as real ones do. A
side facing the sun is brighter than one facing away (``sun_azimuth_rad``, ``ambient``), so
a building's corners are edges too.

**Poles** (``type: poles``) and **trees** (``type: trees``): cylinders as regular polygons
inscribed in their circles (eight sides for a pole, twelve for a crown: the polygon stays
within 2-3 % of the radius); a tree is a trunk from the floor and a crown that starts above
it and does not collide.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from core.schema import check, check_ranges, check_rgb
from envs.features.base import (
    FacadeProfile,
    FeatureConfig,
    Rgb,
    Solid,
    check_convex,
    register_feature,
    regular_polygon,
)

if TYPE_CHECKING:
    from envs.config import WorldConfig

#: a façade rectangle: (s0, s1, z0, z1, rgb), painted over the wall in order
_Rect = tuple[float, float, float, float, Rgb]


@dataclass(frozen=True)
class FacadeConfig:
    """What a building's sides look like (the same on every side, centred on each side).

    The wall is ``wall_rgb``; with ``panel_m > 0`` vertical panels ``panel_m`` wide alternate
    ``wall_rgb`` and ``panel_rgb`` along each side from its first corner. Pilasters (with
    ``column_pitch_m > 0``) stand every ``column_pitch_m``, ``column_width_m`` wide, from the
    floor to the roof, the set centred on the side and none within ``margin_m`` of a corner.
    Windows ``window_size_m`` (width, height) sit ``sill_m`` above each floor of
    ``floor_m`` (the ground floor too with ``ground_floor_windows``), every ``window_pitch_m``
    centred on the side (0: none), skipping any that would touch a pilaster or come within
    ``margin_m`` of a corner, and on the top floor only where they fit under the roof. A
    door ``door_size_m`` stands in the middle of each side listed in the building's ``doors``.
    """

    wall_rgb: Rgb = (196, 186, 168)
    panel_m: float = 0.0
    panel_rgb: Rgb = (170, 160, 145)
    column_pitch_m: float = 0.0
    column_width_m: float = 0.5
    column_rgb: Rgb = (225, 222, 214)
    floor_m: float = 3.5
    window_size_m: tuple[float, float] = (1.2, 1.5)
    window_pitch_m: float = 2.4
    sill_m: float = 0.9
    window_rgb: Rgb = (62, 78, 96)
    ground_floor_windows: bool = True
    door_size_m: tuple[float, float] = (1.8, 2.4)
    door_rgb: Rgb = (92, 64, 40)
    margin_m: float = 0.6

    def __post_init__(self) -> None:
        for name in ("wall_rgb", "panel_rgb", "column_rgb", "window_rgb", "door_rgb"):
            check_rgb(getattr(self, name), f"facade.{name}")
        check_ranges(self, "facade", non_negative=("panel_m", "column_pitch_m", "window_pitch_m", "margin_m", "sill_m"))
        check(math.isfinite(self.floor_m) and self.floor_m > 0, f"facade.floor_m must be finite and > 0, got {self.floor_m}")
        check(
            math.isfinite(self.column_width_m) and self.column_width_m > 0,
            f"facade.column_width_m must be finite and > 0, got {self.column_width_m}",
        )
        for name in ("window_size_m", "door_size_m"):
            w, h = getattr(self, name)
            check(
                math.isfinite(w) and math.isfinite(h) and w > 0 and h > 0,
                f"facade.{name} must be two positive sizes, got {(w, h)}",
            )
        check(
            self.window_pitch_m == 0 or self.window_size_m[0] < self.window_pitch_m,
            f"facade.window_size_m width {self.window_size_m[0]} must be less than window_pitch_m {self.window_pitch_m}",
        )
        check(
            self.sill_m + self.window_size_m[1] < self.floor_m,
            f"facade: sill_m {self.sill_m} + window height {self.window_size_m[1]} must be less than floor_m {self.floor_m}",
        )
        check(
            self.column_pitch_m == 0 or self.column_width_m < self.column_pitch_m,
            f"facade.column_width_m {self.column_width_m} must be less than column_pitch_m {self.column_pitch_m}",
        )

    def rects(self, length_m: float, height_m: float, door: bool) -> list[_Rect]:
        """The side's coloured rectangles in painting order (panels, pilasters, windows, door)."""
        out: list[_Rect] = []
        if self.panel_m > 0:
            count = math.ceil(length_m / self.panel_m - 1e-9)
            out += [
                (k * self.panel_m, min(length_m, (k + 1) * self.panel_m), 0.0, height_m, self.panel_rgb)
                for k in range(1, count, 2)
            ]
        columns = _centred(length_m, self.column_pitch_m, self.margin_m + 0.5 * self.column_width_m)
        half_col = 0.5 * self.column_width_m
        out += [(c - half_col, c + half_col, 0.0, height_m, self.column_rgb) for c in columns]
        w, h = self.window_size_m
        centres = _centred(length_m, self.window_pitch_m, self.margin_m + 0.5 * w)
        centres = [c for c in centres if all(abs(c - col) >= half_col + 0.5 * w + 0.1 for col in columns)]
        door_w, door_h = self.door_size_m
        floors = math.ceil(height_m / self.floor_m - 1e-9)
        for f in range(0 if self.ground_floor_windows else 1, floors):
            z0 = f * self.floor_m + self.sill_m
            if z0 + h > height_m - 0.2:  # no window into the roof's edge
                continue
            for c in centres:
                if door and f == 0 and abs(c - 0.5 * length_m) < 0.5 * (door_w + w) + 0.2:
                    continue
                out.append((c - 0.5 * w, c + 0.5 * w, z0, z0 + h, self.window_rgb))
        if door and door_w < length_m - 2 * self.margin_m:
            mid = 0.5 * length_m
            out.append((mid - 0.5 * door_w, mid + 0.5 * door_w, 0.0, min(door_h, height_m), self.door_rgb))
        return out


def _centred(length: float, pitch: float, keep_off: float) -> list[float]:
    """Positions every ``pitch`` centred on ``[0, length]``, none within ``keep_off`` of an end (pitch 0: none)."""
    if pitch <= 0 or length < 2 * keep_off:
        return []
    count = int(math.floor((length - 2 * keep_off) / pitch + 1e-9)) + 1
    first = 0.5 * (length - (count - 1) * pitch)
    return [first + k * pitch for k in range(count)]


@functools.lru_cache(maxsize=4096)
def facade_profile(facade: FacadeConfig, length_m: float, height_m: float, door: bool, shade: float) -> FacadeProfile:
    """The :class:`FacadeProfile` of one side ``length_m`` long and ``height_m`` tall, its colours times ``shade``.

    The rectangles of :meth:`FacadeConfig.rects` are painted over the wall; the side is cut at
    every rectangle's vertical side, and each interval into the runs of constant colour.
    """
    rects = facade.rects(length_m, height_m, door)
    cuts = sorted({0.0, length_m, *(min(max(v, 0.0), length_m) for r in rects for v in r[:2])})
    breaks: list[float] = [cuts[0]]
    runs_per_interval: list[list[tuple[float, float, Rgb]]] = []
    for s0, s1 in zip(cuts, cuts[1:]):
        if s1 - s0 <= 1e-9:
            continue
        mid = 0.5 * (s0 + s1)
        covering = [r for r in rects if r[0] <= mid < r[1]]
        zs = sorted({0.0, height_m, *(min(max(v, 0.0), height_m) for r in covering for v in r[2:4])})
        runs: list[tuple[float, float, Rgb]] = []
        for z0, z1 in zip(zs, zs[1:]):
            if z1 - z0 <= 1e-9:
                continue
            zm = 0.5 * (z0 + z1)
            colour = facade.wall_rgb
            for r in covering:
                if r[2] <= zm < r[3]:
                    colour = r[4]
            if runs and runs[-1][2] == colour:
                runs[-1] = (runs[-1][0], z1, colour)
            else:
                runs.append((z0, z1, colour))
        if runs_per_interval and runs_per_interval[-1] == runs:
            breaks[-1] = s1  # the same stack as the interval before: no edge between them
        else:
            runs_per_interval.append(runs)
            breaks.append(s1)
    index = np.cumsum([0] + [len(r) for r in runs_per_interval]).astype(np.int64)
    flat = [run for runs in runs_per_interval for run in runs]
    run_z = np.array([(z0, z1) for z0, z1, _ in flat], dtype=np.float64).reshape(-1, 2)
    run_rgb = np.clip(np.rint(np.array([rgb for _, _, rgb in flat], dtype=np.float64).reshape(-1, 3) * shade), 0, 255)
    profile = FacadeProfile(np.asarray(breaks, dtype=np.float64), index, run_z, run_rgb)
    for array in profile:
        array.setflags(write=False)
    return profile


@dataclass(frozen=True)
class BuildingConfig:
    """One building: a convex footprint (counter-clockwise corners, metres) up to ``height_m``.

    ``doors`` lists the sides (side ``i`` runs from corner ``i`` to corner ``i + 1``) with a door
    in their middle; ``facade`` overrides the feature's default façade for this building.
    """

    name: str
    footprint_m: tuple[tuple[float, float], ...]
    height_m: float
    doors: tuple[int, ...] = ()
    facade: FacadeConfig | None = None

    def __post_init__(self) -> None:
        where = f"building {self.name!r}"
        check_convex(np.asarray(self.footprint_m, dtype=np.float64), f"{where}: footprint_m")
        check(
            math.isfinite(self.height_m) and self.height_m > 0, f"{where}: height_m must be finite and > 0, got {self.height_m}"
        )
        sides = len(self.footprint_m)
        bad = [d for d in self.doors if not 0 <= d < sides]
        check(not bad, f"{where}: doors {bad} are not sides of its footprint (sides 0..{sides - 1})")

    @property
    def corners(self) -> NDArray[np.float64]:
        return np.asarray(self.footprint_m, dtype=np.float64)

    def door_points(self) -> list[tuple[float, float, float]]:
        """``(x, y, outward heading)`` of the middle of each side with a door."""
        c = self.corners
        out = []
        for d in self.doors:
            a, b = c[d], c[(d + 1) % c.shape[0]]
            mid = 0.5 * (a + b)
            out.append((float(mid[0]), float(mid[1]), math.atan2(a[0] - b[0], b[1] - a[1])))
        return out


@register_feature("buildings")
@dataclass(frozen=True)
class BuildingsConfig(FeatureConfig):
    """The buildings of an outdoor world (module docstring).

    ``sun_azimuth_rad``: where the (horizontal) light comes from, counter-clockwise from +x;
    a side whose outward normal makes the angle ``phi`` with it has its colours times
    ``ambient + (1 - ambient) max(0, cos phi)``.
    """

    items: tuple[BuildingConfig, ...] = ()
    facade: FacadeConfig = field(default_factory=FacadeConfig)
    sun_azimuth_rad: float = math.radians(225.0)
    ambient: float = 0.6

    def __post_init__(self) -> None:
        names = [b.name for b in self.items]
        check(len(set(names)) == len(names), f"buildings: names repeat: {names}")
        check(math.isfinite(self.sun_azimuth_rad), f"buildings.sun_azimuth_rad must be finite, got {self.sun_azimuth_rad}")
        check(0 <= self.ambient <= 1, f"buildings.ambient must be in [0, 1], got {self.ambient}")

    def shade(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
        """The brightness factor of a counter-clockwise side from ``a`` to ``b`` (its outward normal is to its right)."""
        normal = math.atan2(-(b[0] - a[0]), b[1] - a[1])
        return self.ambient + (1.0 - self.ambient) * max(0.0, math.cos(normal - self.sun_azimuth_rad))

    @functools.cached_property
    def _solids(self) -> tuple[Solid, ...]:
        out = []
        for building in self.items:
            c = building.corners
            facade = building.facade or self.facade
            profiles = []
            for i in range(c.shape[0]):
                a, b = c[i], c[(i + 1) % c.shape[0]]
                length = float(np.hypot(*(b - a)))
                profiles.append(facade_profile(facade, length, building.height_m, i in building.doors, self.shade(a, b)))
            out.append(Solid(c, 0.0, building.height_m, facade.wall_rgb, tuple(profiles), "building", building.name))
        return tuple(out)

    def solids(self) -> tuple[Solid, ...]:
        return self._solids

    def map_data(self) -> dict[str, Any]:
        return {
            "type": self.type_name,
            "buildings": [
                {"name": b.name, "footprint_m": [list(p) for p in b.footprint_m], "height_m": b.height_m} for b in self.items
            ],
        }

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        """Footprints shaded by height (the taller, the darker), doors as short bars."""
        for building in self.items:
            level = min(1.0, building.height_m / 40.0)
            grey = int(round(200 - 120 * level))
            canvas.polygon(building.corners, (grey, grey - 8, grey - 20), 0)
            canvas.polygon(building.corners, (40, 40, 40), 1)
            for x, y, heading in building.door_points():
                canvas.line((x, y), (x + 1.2 * math.cos(heading), y + 1.2 * math.sin(heading)), (150, 90, 40), 3)


@dataclass(frozen=True)
class PoleConfig:
    """A street lamp or utility pole: a cylinder of ``radius_m`` from the floor to ``height_m``."""

    x_m: float
    y_m: float
    radius_m: float = 0.1
    height_m: float = 7.0
    rgb: Rgb = (120, 122, 126)
    name: str = ""

    def __post_init__(self) -> None:
        where = f"pole {self.name or (self.x_m, self.y_m)!r}"
        check(math.isfinite(self.x_m) and math.isfinite(self.y_m), f"{where}: x_m and y_m must be finite")
        check(0 < self.radius_m <= 2, f"{where}: radius_m must be in (0, 2], got {self.radius_m}")
        check(
            math.isfinite(self.height_m) and self.height_m > 0, f"{where}: height_m must be finite and > 0, got {self.height_m}"
        )
        check_rgb(self.rgb, f"{where}: rgb")


@register_feature("poles")
@dataclass(frozen=True)
class PolesConfig(FeatureConfig):
    """Street lamps and utility poles (module docstring); ``sides``: corners of each pole's polygon."""

    items: tuple[PoleConfig, ...] = ()
    sides: int = 8

    def __post_init__(self) -> None:
        check(6 <= self.sides <= 64, f"poles.sides must be in [6, 64], got {self.sides}")

    @functools.cached_property
    def _solids(self) -> tuple[Solid, ...]:
        return tuple(
            Solid(
                regular_polygon(p.x_m, p.y_m, p.radius_m, self.sides), 0.0, p.height_m, p.rgb, (), "pole", p.name or f"pole {i}"
            )
            for i, p in enumerate(self.items)
        )

    def solids(self) -> tuple[Solid, ...]:
        return self._solids

    def map_data(self) -> dict[str, Any]:
        return {"type": self.type_name, "poles": [[p.x_m, p.y_m, p.radius_m, p.height_m] for p in self.items]}

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        for p in self.items:
            canvas.circle(p.x_m, p.y_m, max(p.radius_m, 0.15), (70, 70, 75), 0)


@dataclass(frozen=True)
class TreeConfig:
    """A tree: a trunk of ``trunk_radius_m`` up to ``trunk_height_m``, then a crown of
    ``crown_radius_m`` up to ``crown_top_m`` (it does not collide: it is above the bodies)."""

    x_m: float
    y_m: float
    trunk_radius_m: float = 0.18
    trunk_height_m: float = 2.6
    crown_radius_m: float = 2.0
    crown_top_m: float = 7.5
    trunk_rgb: Rgb = (96, 74, 52)
    crown_rgb: Rgb = (58, 102, 48)
    name: str = ""

    def __post_init__(self) -> None:
        where = f"tree {self.name or (self.x_m, self.y_m)!r}"
        check(math.isfinite(self.x_m) and math.isfinite(self.y_m), f"{where}: x_m and y_m must be finite")
        check(0 < self.trunk_radius_m < self.crown_radius_m, f"{where}: needs 0 < trunk_radius_m < crown_radius_m")
        check(math.isfinite(self.crown_radius_m), f"{where}: crown_radius_m must be finite, got {self.crown_radius_m}")
        check(
            0 < self.trunk_height_m < self.crown_top_m and math.isfinite(self.crown_top_m),
            f"{where}: needs 0 < trunk_height_m < crown_top_m (finite), got {self.trunk_height_m}, {self.crown_top_m}",
        )
        check_rgb(self.trunk_rgb, f"{where}: trunk_rgb")
        check_rgb(self.crown_rgb, f"{where}: crown_rgb")


@register_feature("trees")
@dataclass(frozen=True)
class TreesConfig(FeatureConfig):
    """Trees (module docstring): trunks of ``trunk_sides`` corners, crowns of ``crown_sides``."""

    items: tuple[TreeConfig, ...] = ()
    trunk_sides: int = 8
    crown_sides: int = 12

    def __post_init__(self) -> None:
        check(6 <= self.trunk_sides <= 64, f"trees.trunk_sides must be in [6, 64], got {self.trunk_sides}")
        check(6 <= self.crown_sides <= 64, f"trees.crown_sides must be in [6, 64], got {self.crown_sides}")

    @functools.cached_property
    def _solids(self) -> tuple[Solid, ...]:
        out: list[Solid] = []
        for i, t in enumerate(self.items):
            name = t.name or f"tree {i}"
            out.append(
                Solid(
                    regular_polygon(t.x_m, t.y_m, t.trunk_radius_m, self.trunk_sides),
                    0.0,
                    t.trunk_height_m,
                    t.trunk_rgb,
                    (),
                    "trunk",
                    name,
                )  # fmt: skip
            )
            out.append(
                Solid(
                    regular_polygon(t.x_m, t.y_m, t.crown_radius_m, self.crown_sides),
                    t.trunk_height_m,
                    t.crown_top_m,
                    t.crown_rgb,
                    (),
                    "crown",
                    name,
                )  # fmt: skip
            )
        return tuple(out)

    def solids(self) -> tuple[Solid, ...]:
        return self._solids

    def map_data(self) -> dict[str, Any]:
        return {"type": self.type_name, "trees": [[t.x_m, t.y_m, t.trunk_radius_m, t.crown_radius_m] for t in self.items]}

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        for t in self.items:
            canvas.circle(t.x_m, t.y_m, t.crown_radius_m, (120, 170, 100), 1)
            canvas.circle(t.x_m, t.y_m, max(t.trunk_radius_m, 0.15), (96, 74, 52), 0)
