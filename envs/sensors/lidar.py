"""2-D scanning range finder (default: Hokuyo UTM-30LX): one reading per beam."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from envs.sensors.base import SensorConfig, register_sensor
from envs.sensors.ranging import RangeSensor, check_ray_count
from envs.state import WorldState
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
    height_m: float = 0.2  # the scan plane's height above the floor

    def __post_init__(self) -> None:
        check(0 < self.fov_rad <= 2 * math.pi, f"lidar.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(self.beams >= 1, f"lidar.beams must be >= 1, got {self.beams}")
        check_ray_count(self.beams, "lidar.beams")
        check(self.max_range_m > 0, f"lidar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"lidar.range_std_m must be >= 0, got {self.range_std_m}")
        check(math.isfinite(self.height_m) and self.height_m >= 0, f"lidar.height_m must be finite and >= 0, got {self.height_m}")

    @property
    def relative_angles_rad(self) -> tuple[float, float]:
        """First and last beam angle relative to the robot heading."""
        if self.beams == 1:
            return (0.0, 0.0)
        full_turn = math.isclose(self.fov_rad, 2 * math.pi)
        span = self.fov_rad * (self.beams - 1) / self.beams if full_turn else self.fov_rad
        return (-span / 2, span / 2)


@register_sensor("lidar", LidarConfig)
class Lidar(RangeSensor):
    """2-D scanning range finder: one reading per beam."""

    def __init__(self, name: str, config: LidarConfig, world: WorldConfig, state: WorldState) -> None:
        lo, hi = config.relative_angles_rad
        beams = np.linspace(lo, hi, config.beams)
        super().__init__(name, config, state, beams, beams)
