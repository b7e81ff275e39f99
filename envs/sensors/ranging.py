"""Range sensors: rays cast from the robot's centre against walls and everything that moves.

A sensor whose rays take time (a swept LIDAR: ``ray_lags_s``) casts each ray from the robot's pose
at its time within the step (:func:`core.geometry.poses_along_step` between the step's start
and end poses), along its direction relative to the heading then, in one batched call
(:func:`core.raycast.cast_rays_from`). What moves stays where it is at the end of the step
(a person walking at 1.5 m/s moves 2.8 cm in a UTM-30LX's 18.75 ms of beams).

:class:`RangeSensor` casts, adds noise and draws; the sensor types say where the rays go and
how they become readings: :mod:`envs.sensors.lidar` (one reading per beam) and
:mod:`envs.sensors.sonar` (a ring of cones, each reading the nearest of its rays).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.geometry import poses_along_step
from core.raycast import cast_rays, cast_rays_from
from core.schema import check
from envs.sensors.base import SensorBase
from envs.state import WorldState

#: the most rays a range sensor may cast: one every 0.05 deg over a full turn, finer than 2-D
#: scanning range finders resolve (the Hokuyo UTM-30LX: 0.25 deg); every ray is cast every step,
#: so a count far beyond it only makes the env slow (10**8 beams hang it)
MAX_RAYS = 7200


def check_ray_count(count: int, what: str) -> None:
    """Raise :class:`ConfigError` unless ``count`` rays (``what`` names the fields) is in ``1..MAX_RAYS``."""
    check(
        1 <= count <= MAX_RAYS,
        f"{what} must be in 1..{MAX_RAYS} (one ray every 0.05 deg over a full turn, finer than 2-D scanning range "
        f"finders resolve; every ray is cast every step), got {count}",
    )


class RangeConfig(Protocol):
    """What every range sensor's config has (read-only, as the frozen configs give it)."""

    @property
    def key(self) -> str: ...

    @property
    def max_range_m(self) -> float: ...

    @property
    def range_std_m(self) -> float: ...

    @property
    def height_m(self) -> float: ...


class RangeSensor(SensorBase):
    """Rays cast from the robot's centre in the horizontal plane at the sensor's ``height_m``;
    they hit the walls that reach above it and the sections of everything that moves there
    (:meth:`envs.state.WorldState.section`: a person's legs, torso or head, the ball, a car's
    wheels or body), not landmark poles. Subclasses say where the rays go and how they become readings.

    Attributes:
        relative_angles: ``(R,)`` ray directions relative to the heading, ascending, spanning less than a turn.
        reading_angles: ``(B,)`` the direction of each reading relative to the heading.
        ray_lags_s: ``(R,)`` how long before the end of the step each ray is taken (zeros: all at the end).
    """

    hit_color: tuple[int, int, int] = (255, 20, 20)
    hit_size_px = 2

    def __init__(
        self,
        name: str,
        config: RangeConfig,
        state: WorldState,
        ray_angles: NDArray[np.float64],
        reading_angles: NDArray[np.float64],
        ray_lags_s: NDArray[np.float64] | None = None,
        dt_s: float | None = None,
    ) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.relative_angles = ray_angles
        self.reading_angles = reading_angles
        self.ray_lags_s = np.zeros(ray_angles.shape[0]) if ray_lags_s is None else ray_lags_s
        # each ray's lag as a share of the step (None: every ray at the end, one origin: the fast path)
        self._lag_fractions: NDArray[np.float64] | None = None
        if self.ray_lags_s.any():
            if dt_s is None:
                raise ValueError(f"sensor {name!r}: rays that lag need the world's step dt_s")
            self._lag_fractions = self.ray_lags_s / dt_s
        seen = state.walls_at(config.height_m)
        self._seg_a, self._seg_b = state.seg_a[seen], state.seg_b[seen]

    def space(self) -> spaces.Box:
        return spaces.Box(0.0, self.config.max_range_m, shape=(self.reading_angles.shape[0],), dtype=np.float32)

    def metadata(self) -> dict[str, Any]:
        return {
            "beam_angles_rad": self.reading_angles.copy(),
            "max_range_m": float(self.config.max_range_m),
            "height_m": float(self.config.height_m),  # the map's walls a localizer should expect: those spanning this plane
        }

    def readings(self, rays: NDArray[np.float64]) -> NDArray[np.float64]:
        """The ``(B,)`` readings from the ``(R,)`` ranges of the rays."""
        return rays

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        section = state.section(cfg.height_m)
        seg_a, seg_b = section.walls(self._seg_a, self._seg_b)  # with the sides of a car's body or wheels
        if self._lag_fractions is None:
            rays = cast_rays(
                state.positions[0],
                self.relative_angles + state.robot_pose[2],
                cfg.max_range_m,
                seg_a,
                seg_b,
                section.centres,
                section.radii,
            )
        else:  # each ray from where the robot was at its time
            poses = poses_along_step(state.robot_start, state.robot_pose, self._lag_fractions)
            rays = cast_rays_from(
                poses,  # (x, y, heading): the kernel reads the first two columns
                self.relative_angles + poses[:, 2],
                cfg.max_range_m,
                seg_a,
                seg_b,
                section.centres,
                section.radii,
            )
        ranges = self.readings(rays)
        hit = ranges < cfg.max_range_m
        if cfg.range_std_m > 0:
            ranges = np.where(hit, ranges + rng.standard_normal(ranges.shape[0]) * cfg.range_std_m, ranges)
        return np.clip(ranges, 0.0, cfg.max_range_m).astype(np.float32), {}

    def hit_points(self, ranges: NDArray[np.floating[Any]], pose: NDArray[np.float64]) -> NDArray[np.float64]:
        """``(H, 2)`` world points of the readings that hit something (for drawing)."""
        r = np.asarray(ranges, dtype=np.float64)
        hit = r < self.config.max_range_m
        angles = self.reading_angles[hit] + pose[2]
        return np.asarray(pose[:2] + r[hit, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1))

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.float32], info: Mapping[str, Any]) -> None:
        canvas.points(self.hit_points(reading, state.robot_pose), self.hit_color, self.hit_size_px)
