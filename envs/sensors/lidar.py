"""2-D scanning range finder (default: Hokuyo UTM-30LX): one reading per beam.

A real scanner turns: its beams are taken one after another, counter-clockwise (the UTM-30LX's
mirror, and the VLP-16's head seen from above, turn that way), while the robot moves. With
``sweep_s`` (the time of one turn of the scanner) each beam is taken at its own time, from the
robot's pose then (:func:`beam_lags_s`, :class:`envs.sensors.ranging.RangeSensor`); 0 (the default)
takes every beam at the end of the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from core.schema import check
from envs.sensors.base import SensorConfig, register_sensor
from envs.sensors.ranging import RangeSensor, check_ray_count
from envs.state import WorldState

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
    # seconds one turn of the scanner takes; 0: every beam at the end of the step (instantaneous, the default).
    # The datasheet values: Hokuyo UTM-30LX 0.025 (25 ms/scan, 40 Hz; its 270 deg of beams take
    # 18.75 ms of the turn), Velodyne VLP-16 0.1 (600 rpm, 10 Hz, its default). See beam_lags_s.
    sweep_s: float = 0.0

    def __post_init__(self) -> None:
        check(0 < self.fov_rad <= 2 * math.pi, f"lidar.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(self.beams >= 1, f"lidar.beams must be >= 1, got {self.beams}")
        check_ray_count(self.beams, "lidar.beams")
        check(self.max_range_m > 0, f"lidar.max_range_m must be > 0, got {self.max_range_m}")
        check(self.range_std_m >= 0, f"lidar.range_std_m must be >= 0, got {self.range_std_m}")
        check(math.isfinite(self.height_m) and self.height_m >= 0, f"lidar.height_m must be finite and >= 0, got {self.height_m}")
        check(math.isfinite(self.sweep_s) and self.sweep_s >= 0, f"lidar.sweep_s must be finite and >= 0 s, got {self.sweep_s}")

    def check_world(self, world: WorldConfig, name: str) -> None:
        """Refuse a sweep whose beams take longer than one step: the sensor knows the robot's pose
        at the start and the end of the step only, and invents no motion before it."""
        lo, hi = self.relative_angles_rad
        span_s = self.sweep_s * (hi - lo) / (2 * math.pi)
        check(
            span_s <= world.dt_s,
            f"sensor {name!r}: lidar.sweep_s = {self.sweep_s} s takes its beams over {span_s:.6g} s (the "
            f"{math.degrees(hi - lo):.6g} deg from the first to the last beam), longer than the world's step dt_s = "
            f"{world.dt_s} s; each beam is taken from the robot's pose within the step, so the sweep must fit in one",
        )

    @property
    def relative_angles_rad(self) -> tuple[float, float]:
        """First and last beam angle relative to the robot heading."""
        if self.beams == 1:
            return (0.0, 0.0)
        full_turn = math.isclose(self.fov_rad, 2 * math.pi)
        span = self.fov_rad * (self.beams - 1) / self.beams if full_turn else self.fov_rad
        return (-span / 2, span / 2)


def beam_lags_s(angles_rad: NDArray[np.float64], sweep_s: float) -> NDArray[np.float64]:
    """``(B,)`` how long before the end of the step each beam of a scanner turning counter-clockwise
    (``angles_rad`` ascending, relative to the heading) at one turn per ``sweep_s`` is taken: the last
    beam at the end, beam ``k`` ``sweep_s * (a_last - a_k) / (2 pi)`` earlier. (A 270 deg scan's beams
    take three quarters of the turn; a full turn's first beam is taken ``sweep_s (B - 1) / B`` before the end.)"""
    if angles_rad.shape[0] == 0:
        return np.zeros(0)
    return sweep_s * (angles_rad[-1] - angles_rad) / (2 * math.pi)


@register_sensor("lidar", LidarConfig)
class Lidar(RangeSensor):
    """2-D scanning range finder: one reading per beam."""

    def __init__(self, name: str, config: LidarConfig, world: WorldConfig, state: WorldState) -> None:
        lo, hi = config.relative_angles_rad
        beams = np.linspace(lo, hi, config.beams)
        super().__init__(name, config, state, beams, beams, ray_lags_s=beam_lags_s(beams, config.sweep_s), dt_s=world.dt_s)
        self._sweep_s = float(config.sweep_s)

    def metadata(self) -> dict[str, Any]:
        """The range sensor's, with ``sweep_s`` and each beam's ``beam_lags_s`` (what a driver stamping
        each beam tells a localizer: ``deskew``)."""
        return {**super().metadata(), "sweep_s": self._sweep_s, "beam_lags_s": self.ray_lags_s.copy()}
