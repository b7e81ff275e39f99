"""A ring of sonar range sensors: each cone reads the nearest hit among its rays."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from core.geometry import ring_directions
from core.schema import check
from envs.sensors.base import SensorConfig, register_sensor
from envs.sensors.ranging import RangeSensor, check_ray_count
from envs.state import WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig


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
    height_m: float = 0.3  # the transducers' height above the floor

    def __post_init__(self) -> None:
        check(self.sensors >= 1, f"sonar.sensors must be >= 1, got {self.sensors}")
        check(self.rays_per_cone >= 1, f"sonar.rays_per_cone must be >= 1, got {self.rays_per_cone}")
        check_ray_count(
            self.sensors * self.rays_per_cone, f"sonar.sensors x sonar.rays_per_cone ({self.sensors} x {self.rays_per_cone})"
        )
        spacing = 2 * math.pi / self.sensors
        check(
            0 < self.cone_rad <= spacing + 1e-12,
            f"sonar.cone_rad must be in (0, 2 pi / sensors = {spacing:.4f}] (cones may not overlap), got {self.cone_rad}",
        )
        check(self.max_range_m > 0, f"sonar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"sonar.range_std_m must be >= 0, got {self.range_std_m}")
        check(math.isfinite(self.height_m) and self.height_m >= 0, f"sonar.height_m must be finite and >= 0, got {self.height_m}")


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
