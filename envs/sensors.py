"""Sensors: small strategy objects with ``space()`` and ``observe()``.

Each sensor reads the world's exported arrays (never pymunk directly) and returns its
observation array plus a dict of ground-truth facts for ``info`` (which landmarks were
really visible, which detections were false). Observations are float32 and always inside
the declared space.

A new sensor (ceiling camera, stereo edges, sonar) is one more class here and one more
optional block in the world config.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.config import BearingCameraConfig, LidarConfig, OdometryConfig, SonarConfig
from envs.world import World
from localizers.geometry import in_field_of_view, ring_directions
from localizers.motion import odometry_noise_std, sample_odometry
from localizers.raycast import cast_rays, sight_lines_clear


class Sensor(Protocol):
    key: str

    def space(self) -> spaces.Box: ...

    def reset(self) -> None: ...

    def observe(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]: ...


class Odometry:
    """Noisy increment of the *commanded* motion since the last step, in the previous frame.

    ``command(delta)`` is called by the env with the exact commanded increment before the
    physics step; displacement by contacts never enters it. The noise follows the alpha
    model (:mod:`localizers.motion`).
    """

    key = "odometry"

    def __init__(self, config: OdometryConfig, max_speed_mps: float, max_turn_rate_rps: float, dt_s: float) -> None:
        self.config = config
        self.alphas = np.asarray(config.alphas)
        # bounds: the largest commanded step, widened for noise; clipping at 8 noise sds
        # of the largest step is never reached in practice and keeps the space finite
        trans = max_speed_mps * dt_s
        rot = max_turn_rate_rps * dt_s
        std = odometry_noise_std([trans * math.cos(rot / 2), trans * math.sin(rot / 2), rot], self.alphas)
        self.bound = np.array([trans + 8 * std[1] + 1e-3, trans + 8 * std[1] + 1e-3, rot + 16 * std[0] + 1e-3], dtype=np.float32)
        self._delta = np.zeros(3)

    def space(self) -> spaces.Box:
        return spaces.Box(-self.bound, self.bound, dtype=np.float32)

    def reset(self) -> None:
        self._delta = np.zeros(3)

    def command(self, delta: NDArray[np.float64], rng: np.random.Generator) -> None:
        """Record the commanded increment ``(3,)`` of this step, corrupted by the alpha model."""
        self._delta = sample_odometry(rng, delta, self.alphas)

    def observe(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        return np.clip(self._delta.astype(np.float32), -self.bound, self.bound), {}


class BearingCamera:
    """Bearing camera: a bearing per landmark whose line of sight is clear, within range and,
    for a camera narrower than a full turn, inside the field of view around the heading.

    Observation ``(3 L,)``: for each landmark slot in turn ``(visible, cos(bearing),
    sin(bearing))`` in the robot frame (a flat vector, as stable-baselines3 expects; reshape
    to ``(L, 3)`` to read it), zeros when not detected. A false detection puts a uniformly
    random bearing in a slot with ``visible = 1``.
    """

    key = "landmarks"

    def __init__(self, config: BearingCameraConfig, world: World) -> None:
        self.config = config
        self.count = world.landmark_xy.shape[0]
        self.max_range_m = np.minimum(world.landmark_max_range_m, config.max_range_m)

    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, shape=(3 * self.count,), dtype=np.float32)

    def reset(self) -> None:
        pass

    def true_visibility(self, world: World) -> NDArray[np.bool_]:
        """``(L,)`` landmarks in the field of view whose line of sight is clear and within
        range (no dropout)."""
        clear = sight_lines_clear(
            world.positions[0],
            world.landmark_xy,
            world.landmark_radius_m,
            self.max_range_m,
            world.seg_a,
            world.seg_b,
            world.occluder_xy,
            world.occluder_radius_m,
        )
        if self.config.fov_rad < 2 * math.pi:
            clear &= in_field_of_view(world.positions[0], world.angles[0], world.landmark_xy, self.config.fov_rad)
        return clear

    def observe(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        draws = rng.random((3, self.count))  # dropout, false detection, false bearing
        noise = rng.standard_normal(self.count) * cfg.noise_std_rad
        obs, visible_ids, false_ids = _bearing_slots(
            world.positions[0],
            world.angles[0],
            world.landmark_xy,
            self.true_visibility(world),
            draws,
            noise,
            cfg.dropout_probability,
            cfg.false_detection_probability,
        )
        return obs.reshape(-1), {"visible_landmarks": visible_ids, "false_detections": false_ids}


@numba.njit(cache=True)
def _bearing_slots(
    origin: NDArray[np.float64],
    heading: float,
    landmark_xy: NDArray[np.float64],
    visible: NDArray[np.bool_],
    draws: NDArray[np.float64],
    noise: NDArray[np.float64],
    dropout: float,
    false_rate: float,
) -> tuple[NDArray[np.float32], NDArray[np.int64], NDArray[np.int64]]:
    """Fill the ``(L, 3)`` camera slots; also return the truly visible and the falsely reported ids."""
    n = landmark_xy.shape[0]
    obs = np.zeros((n, 3), dtype=np.float32)
    visible_ids = np.flatnonzero(visible)
    false_ids = np.flatnonzero(draws[1] < false_rate)
    for j in range(n):
        if draws[1, j] < false_rate:
            bearing = (draws[2, j] * 2.0 - 1.0) * math.pi
        elif visible[j] and draws[0, j] >= dropout:
            bearing = math.atan2(landmark_xy[j, 1] - origin[1], landmark_xy[j, 0] - origin[0]) - heading + noise[j]
        else:
            continue
        obs[j, 0] = 1.0
        obs[j, 1] = math.cos(bearing)
        obs[j, 2] = math.sin(bearing)
    return obs, visible_ids, false_ids


class _RangeSensor:
    """Rays cast from the robot's centre; they hit walls and everything that moves, the ball
    too (not landmark poles). Subclasses say where the rays go and how they become readings."""

    key: str

    def __init__(
        self,
        config: LidarConfig | SonarConfig,
        world: World,
        ray_angles: NDArray[np.float64],
        reading_angles: NDArray[np.float64],
    ) -> None:
        self.config = config
        #: ``(R,)`` ray directions relative to the heading, ascending, spanning less than a turn
        self.relative_angles = ray_angles
        #: ``(B,)`` the direction of each reading relative to the heading
        self.reading_angles = reading_angles
        self.rows = np.arange(1, world.body_count)

    def space(self) -> spaces.Box:
        return spaces.Box(0.0, self.config.max_range_m, shape=(self.reading_angles.shape[0],), dtype=np.float32)

    def reset(self) -> None:
        pass

    def readings(self, rays: NDArray[np.float64]) -> NDArray[np.float64]:
        """The ``(B,)`` readings from the ``(R,)`` ranges of the rays."""
        return rays

    def observe(self, world: World, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        pose = world.robot_pose
        rays = cast_rays(
            world.positions[0],
            self.relative_angles + pose[2],
            cfg.max_range_m,
            world.seg_a,
            world.seg_b,
            world.positions[self.rows],
            world.radii_m[self.rows],
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


class Lidar(_RangeSensor):
    """2-D scanning range finder: one reading per beam."""

    key = "lidar"

    def __init__(self, config: LidarConfig, world: World) -> None:
        lo, hi = config.relative_angles_rad
        beams = np.linspace(lo, hi, config.beams)
        super().__init__(config, world, beams, beams)


class Sonar(_RangeSensor):
    """Ring of sonar range sensors: each reads the nearest hit among the rays of its cone.

    Observation ``(sensors,)``: ranges from the robot's centre, in sensor order from the
    heading counter-clockwise; ``max_range_m`` where the cone is clear.
    """

    key = "sonar"

    def __init__(self, config: SonarConfig, world: World) -> None:
        k = config.rays_per_cone
        offsets = ((np.arange(k) + 0.5) / k - 0.5) * config.cone_rad
        centres = ring_directions(config.sensors)
        # cones do not overlap (SonarConfig checks it), so the rays are ascending within a turn
        super().__init__(config, world, (centres[:, None] + offsets[None, :]).reshape(-1), centres)

    def readings(self, rays: NDArray[np.float64]) -> NDArray[np.float64]:
        return rays.reshape(self.reading_angles.shape[0], -1).min(axis=1)
