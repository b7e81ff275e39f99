"""A route: the polyline a robot is to drive along (the map knows it; a route follower drives it).

``type: route`` with ``points_m``, at least two points. The localizers' map holds it
(:meth:`RouteConfig.map_data`), so a policy plans on it without ground truth; the top view
draws it. Give the world a ``goal`` at its last point for the episode to end there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.features.base import FeatureConfig, register_feature

if TYPE_CHECKING:
    from envs.config import WorldConfig

ROUTE_RGB = (230, 120, 20)


@register_feature("route")
@dataclass(frozen=True)
class RouteConfig(FeatureConfig):
    """The route's points ``(x, y)`` in metres, in driving order."""

    points_m: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_m, dtype=np.float64).reshape(-1, 2) if len(self.points_m) else np.zeros((0, 2))
        check(pts.shape[0] >= 2, f"route.points_m needs at least two points (x, y), got {self.points_m!r}")
        check(bool(np.all(np.isfinite(pts))), f"route.points_m must be finite, got {self.points_m!r}")
        steps = np.hypot(*np.diff(pts, axis=0).T)
        check(bool(np.all(steps > 1e-6)), f"route.points_m: consecutive points must differ, got {self.points_m!r}")

    @property
    def points(self) -> NDArray[np.float64]:
        """``(P, 2)`` the route's points."""
        return np.asarray(self.points_m, dtype=np.float64).reshape(-1, 2)

    @property
    def length_m(self) -> float:
        """The route's length along its polyline."""
        return float(np.hypot(*np.diff(self.points, axis=0).T).sum())

    def check_world(self, world: WorldConfig, name: str) -> None:
        xmin, ymin, xmax, ymax = world.field_m
        pts = self.points
        outside = np.flatnonzero((pts[:, 0] < xmin) | (pts[:, 0] > xmax) | (pts[:, 1] < ymin) | (pts[:, 1] > ymax))
        check(
            outside.size == 0,
            f"world {world.name!r}: feature {name!r}: route point {pts[outside[0]].tolist() if outside.size else None} "
            f"is outside the field x [{xmin:g}, {xmax:g}], y [{ymin:g}, {ymax:g}]",
        )

    def map_data(self) -> dict[str, Any]:
        return {"type": self.type_name, "points_m": self.points.tolist(), "length_m": self.length_m}

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        pts = self.points
        for a, b in zip(pts, pts[1:]):
            canvas.line(a, b, ROUTE_RGB, 2)
        canvas.circle(float(pts[0, 0]), float(pts[0, 1]), 0.6, ROUTE_RGB, 2)
        end, before = pts[-1], pts[-2]
        heading = math.atan2(end[1] - before[1], end[0] - before[0])
        for side in (-1.0, 1.0):
            tip = end - 1.5 * np.array([math.cos(heading + side * 0.45), math.sin(heading + side * 0.45)])
            canvas.line(end, tip, ROUTE_RGB, 2)
