"""The map-feature plug-in interface: static scenery a sensor renders and a localizer may know.

A feature type is a frozen config dataclass subclassing :class:`FeatureConfig`, registered
under a type name with :func:`register_feature`. A world YAML names its features as a
mapping from name to a config tagged by type::

    features:
      ceiling: {type: ceiling, height_m: 2.5, targets: [...]}

A feature says what a localizer's map holds of it (:meth:`FeatureConfig.map_data`, plain
values, which the env puts in :attr:`localizers.base.LandmarkMap.features`) and how the top
view draws it. Scenery that stands in the world (buildings, poles, trees) also says what its
solids are (:meth:`FeatureConfig.solids`): convex prisms with a height interval and an
appearance. Their sides are static wall segments like the world's own walls (they collide
where they reach the floor, every range sensor sees those spanning its height, and the
localizers' map holds them), and cameras render their colours and façades. A feature without
solids (a ceiling) has no physics.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.plugins import Registry

if TYPE_CHECKING:
    from envs.config import WorldConfig

ConfigT = TypeVar("ConfigT", bound="FeatureConfig")

Rgb = tuple[int, int, int]

#: one static segment with its height interval: (x1, y1, x2, y2, bottom, top), metres
Segment = tuple[float, float, float, float, float, float]


class FacadeProfile(NamedTuple):
    """The colours of one side of a solid, piecewise constant in ``(s, z)``.

    ``s`` runs along the side from its first corner to its second (left to right, seen from
    outside a counter-clockwise solid), ``z`` is the height above the floor. The side is cut
    at ``breaks_s`` ``(K + 1,)`` (0 first, the side's length last) into ``K`` intervals;
    interval ``k`` is a stack of runs ``run_index[k]:run_index[k + 1]`` of ``run_z`` ``(R, 2)``
    (bottom, top, ascending and covering the solid's height interval) with colours
    ``run_rgb`` ``(R, 3)`` (0-255, the side's shading included). Adjacent intervals differ,
    so every interior break is a vertical edge over the heights where their colours differ
    (:meth:`edges`).
    """

    breaks_s: NDArray[np.float64]
    run_index: NDArray[np.int64]
    run_z: NDArray[np.float64]
    run_rgb: NDArray[np.float64]

    def colour(self, s: float, z: float) -> NDArray[np.float64]:
        """``(3,)`` the colour at ``(s, z)`` (clamped to the side)."""
        k = int(np.clip(np.searchsorted(self.breaks_s, s, side="right") - 1, 0, self.breaks_s.size - 2))
        lo, hi = int(self.run_index[k]), int(self.run_index[k + 1])
        j = lo + int(np.clip(np.searchsorted(self.run_z[lo:hi, 1], z, side="right"), 0, hi - lo - 1))
        return self.run_rgb[j]

    def edges(self) -> list[tuple[float, float, float, tuple[float, ...], tuple[float, ...]]]:
        """The vertical edges inside the side: ``(s, z_bottom, z_top, rgb left, rgb right)``
        for each height interval over which the colours either side of a break differ."""
        out: list[tuple[float, float, float, tuple[float, ...], tuple[float, ...]]] = []
        for k in range(1, self.breaks_s.size - 1):
            left = range(int(self.run_index[k - 1]), int(self.run_index[k]))
            right = range(int(self.run_index[k]), int(self.run_index[k + 1]))
            for i in left:
                for j in right:
                    z0 = max(self.run_z[i, 0], self.run_z[j, 0])
                    z1 = min(self.run_z[i, 1], self.run_z[j, 1])
                    if z1 > z0 and not np.array_equal(self.run_rgb[i], self.run_rgb[j]):
                        out.append(
                            (float(self.breaks_s[k]), float(z0), float(z1), tuple(self.run_rgb[i]), tuple(self.run_rgb[j]))
                        )
        out.sort(key=lambda e: (e[0], e[1]))
        return _merge_runs(out)


def _merge_runs(
    edges: list[tuple[float, float, float, tuple[float, ...], tuple[float, ...]]],
) -> list[tuple[float, float, float, tuple[float, ...], tuple[float, ...]]]:
    """Join edges at the same ``s`` whose height intervals touch and whose colours agree."""
    out: list[tuple[float, float, float, tuple[float, ...], tuple[float, ...]]] = []
    for e in edges:
        if out and out[-1][0] == e[0] and out[-1][2] == e[1] and out[-1][3:] == e[3:]:
            last = out[-1]
            out[-1] = (last[0], last[1], e[2], last[3], last[4])
        else:
            out.append(e)
    return out


class Solid(NamedTuple):
    """A convex static prism: a building, a pole, a tree's trunk or crown.

    Attributes:
        corners: ``(K, 2)`` the outline, counter-clockwise, convex.
        bottom_m, top_m: the heights it spans (a crown starts above the trunk).
        rgb: the colour of its sides that have no façade (0-255).
        facades: per side (corner ``i`` to ``i + 1``) its :class:`FacadeProfile`, or None for
            the plain ``rgb``; empty: every side plain.
        kind: what it is (``"building"``, ``"pole"``, ``"trunk"``, ``"crown"``), for drawing.
        name: its name, for messages.
    """

    corners: NDArray[np.float64]
    bottom_m: float
    top_m: float
    rgb: Rgb
    facades: tuple[FacadeProfile | None, ...] = ()
    kind: str = ""
    name: str = ""

    def segments(self) -> list[Segment]:
        """Its sides as static segments with its height interval, in corner order."""
        c = self.corners
        nxt = np.roll(c, -1, axis=0)
        return [(float(a[0]), float(a[1]), float(b[0]), float(b[1]), self.bottom_m, self.top_m) for a, b in zip(c, nxt)]


def regular_polygon(x: float, y: float, radius: float, sides: int) -> NDArray[np.float64]:
    """``(sides, 2)`` the corners, counter-clockwise, of the regular polygon inscribed in the circle
    of ``radius`` about ``(x, y)`` (a pole or a trunk as a static solid), one corner at angle 0."""
    angles = np.arange(sides) * (2.0 * math.pi / sides)
    return np.stack([x + radius * np.cos(angles), y + radius * np.sin(angles)], axis=1)


def check_convex(corners: NDArray[np.float64], where: str) -> None:
    """Raise :class:`ConfigError` unless ``corners`` ``(K, 2)`` (K >= 3, finite) turn counter-clockwise
    at every corner (a convex outline), naming ``where`` and the first corner that does not."""
    c = np.asarray(corners, dtype=np.float64)
    check(c.ndim == 2 and c.shape[0] >= 3 and c.shape[1] == 2, f"{where}: needs at least 3 corners (x, y), got {corners!r}")
    check(bool(np.all(np.isfinite(c))), f"{where}: corners must be finite, got {c.tolist()}")
    edge = np.roll(c, -1, axis=0) - c
    turn = edge[:, 0] * np.roll(edge, -1, axis=0)[:, 1] - edge[:, 1] * np.roll(edge, -1, axis=0)[:, 0]
    bad = np.flatnonzero(turn <= 0.0)
    check(
        bad.size == 0,
        f"{where}: the outline must be convex and counter-clockwise (split a concave building into convex parts); "
        f"it does not turn left at corner {int((bad[0] + 1) % c.shape[0]) if bad.size else 0} of {c.tolist()}",
    )


class FeatureConfig:
    """Base of every feature config (a frozen dataclass), loaded from a mapping with a ``type``."""

    type_name: ClassVar[str] = ""

    @classmethod
    def __from_config__(cls, value: Any, where: str) -> FeatureConfig:
        """Build the config of the type named by ``value["type"]`` (the strict loader's hook)."""
        return FEATURES.config_from(value, where)

    def check_world(self, world: WorldConfig, name: str) -> None:
        """Raise :class:`ConfigError` if this feature does not fit ``world`` (override as needed)."""

    def map_data(self) -> dict[str, Any]:
        """What a localizer's map holds of this feature: plain numbers, strings and arrays."""
        return {}

    def solids(self) -> tuple[Solid, ...]:
        """The convex static objects this feature stands in the world (none by default)."""
        return ()

    def segments(self) -> list[Segment]:
        """Its solids' sides as static segments with their height intervals (:meth:`Solid.segments`)."""
        return [seg for solid in self.solids() for seg in solid.segments()]

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        """Draw the feature on the top view of ``world`` (the background layer)."""


#: the registered feature types; a feature is its config (the factory is the config class)
FEATURES: Registry[FeatureConfig, Callable[..., Any]] = Registry("feature", FeatureConfig)


def register_feature(type_name: str) -> Callable[[type[ConfigT]], type[ConfigT]]:
    """Class decorator: register a :class:`FeatureConfig` dataclass under ``type_name``."""

    def decorate(cls: type[ConfigT]) -> type[ConfigT]:
        FEATURES.register(type_name, cls, cls)
        return cls

    return decorate


def feature_types() -> list[str]:
    """The registered feature type names, sorted."""
    return FEATURES.names()
