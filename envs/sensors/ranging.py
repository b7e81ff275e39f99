"""Range sensors: rays cast from the robot's centre against walls and everything that moves.

:class:`Lidar` reads one range per beam; :class:`Sonar` is a ring of cones, each reading
the nearest of its rays. Both share :class:`RangeSensor` (casting, noise, drawing).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState
from localizers.geometry import ring_directions
from localizers.raycast import cast_rays
from localizers.schema import check

if TYPE_CHECKING:
    from envs.config import WorldConfig


@dataclass(frozen=True)
class LidarConfig(SensorConfig):
    """2-D scanning range finder (default: Hokuyo UTM-30LX)."""

    key: str = "lidar"
    fov_rad: float = math.radians(270.0)
    beams: int = 1081
    max_range_m: float = 30.0
    range_std_m: float = 0.01

    def __post_init__(self) -> None:
        check(0 < self.fov_rad <= 2 * math.pi, f"lidar.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(self.beams >= 1, f"lidar.beams must be >= 1, got {self.beams}")
        check(self.max_range_m > 0, f"lidar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"lidar.range_std_m must be >= 0, got {self.range_std_m}")

    @property
    def relative_angles_rad(self) -> tuple[float, float]:
        """First and last beam angle relative to the robot heading."""
        if self.beams == 1:
            return (0.0, 0.0)
        full_turn = math.isclose(self.fov_rad, 2 * math.pi)
        span = self.fov_rad * (self.beams - 1) / self.beams if full_turn else self.fov_rad
        return (-span / 2, span / 2)


@dataclass(frozen=True)
class SonarConfig(SensorConfig):
    """A ring of sonar range sensors around the body: how near the walls and the crowd are.

    ``sensors`` transducers, evenly spaced from the heading counter-clockwise, each report
    the nearest wall or moving body inside its cone (``cone_rad`` wide, sampled by
    ``rays_per_cone`` rays), measured from the robot's centre; ``max_range_m`` when
    nothing is within range. None of the papers' worlds has one: it is the obstacle
    awareness a learned policy may use (add it with the env kwarg ``sonar={}``).
    """

    key: str = "sonar"
    sensors: int = 12
    cone_rad: float = math.radians(30.0)
    rays_per_cone: int = 5
    max_range_m: float = 2.0
    range_std_m: float = 0.02

    def __post_init__(self) -> None:
        check(self.sensors >= 1, f"sonar.sensors must be >= 1, got {self.sensors}")
        spacing = 2 * math.pi / self.sensors
        check(
            0 < self.cone_rad <= spacing + 1e-12,
            f"sonar.cone_rad must be in (0, 2 pi / sensors = {spacing:.4f}] (cones may not overlap), got {self.cone_rad}",
        )
        check(self.rays_per_cone >= 1, f"sonar.rays_per_cone must be >= 1, got {self.rays_per_cone}")
        check(self.max_range_m > 0, f"sonar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"sonar.range_std_m must be >= 0, got {self.range_std_m}")


class RangeSensor(SensorBase):
    """Rays cast from the robot's centre; they hit walls and everything that moves, the ball
    too (not landmark poles). Subclasses say where the rays go and how they become readings.

    Attributes:
        relative_angles: ``(R,)`` ray directions relative to the heading, ascending, spanning less than a turn.
        reading_angles: ``(B,)`` the direction of each reading relative to the heading.
    """

    hit_color: tuple[int, int, int] = (255, 20, 20)
    hit_size_px = 2

    def __init__(
        self,
        name: str,
        config: LidarConfig | SonarConfig,
        state: WorldState,
        ray_angles: NDArray[np.float64],
        reading_angles: NDArray[np.float64],
    ) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.relative_angles = ray_angles
        self.reading_angles = reading_angles
        self.rows = np.arange(1, state.body_count)

    def space(self) -> spaces.Box:
        return spaces.Box(0.0, self.config.max_range_m, shape=(self.reading_angles.shape[0],), dtype=np.float32)

    def metadata(self) -> dict[str, Any]:
        return {"beam_angles_rad": self.reading_angles.copy(), "max_range_m": float(self.config.max_range_m)}

    def readings(self, rays: NDArray[np.float64]) -> NDArray[np.float64]:
        """The ``(B,)`` readings from the ``(R,)`` ranges of the rays."""
        return rays

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        rays = cast_rays(
            state.positions[0],
            self.relative_angles + state.robot_pose[2],
            cfg.max_range_m,
            state.seg_a,
            state.seg_b,
            state.positions[self.rows],
            state.radii_m[self.rows],
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


@register_sensor("lidar", LidarConfig)
class Lidar(RangeSensor):
    """2-D scanning range finder: one reading per beam."""

    def __init__(self, name: str, config: LidarConfig, world: WorldConfig, state: WorldState) -> None:
        lo, hi = config.relative_angles_rad
        beams = np.linspace(lo, hi, config.beams)
        super().__init__(name, config, state, beams, beams)


@register_sensor("sonar", SonarConfig)
class Sonar(RangeSensor):
    """Ring of sonar range sensors: each reads the nearest hit among the rays of its cone.

    Observation ``(sensors,)``: ranges from the robot's centre, in sensor order from the
    heading counter-clockwise; ``max_range_m`` where the cone is clear.
    """

    hit_color = (0, 200, 255)  # drawn at each cone's centre
    hit_size_px = 4

    def __init__(self, name: str, config: SonarConfig, world: WorldConfig, state: WorldState) -> None:
        k = config.rays_per_cone
        offsets = ((np.arange(k) + 0.5) / k - 0.5) * config.cone_rad
        centres = ring_directions(config.sensors)
        # cones do not overlap (SonarConfig checks it), so the rays are ascending within a turn
        super().__init__(name, config, state, (centres[:, None] + offsets[None, :]).reshape(-1), centres)

    def readings(self, rays: NDArray[np.float64]) -> NDArray[np.float64]:
        return rays.reshape(self.reading_angles.shape[0], -1).min(axis=1)
