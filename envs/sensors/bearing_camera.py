"""Bearing camera: the bearing of each landmark whose line of sight is clear.

Omnidirectional (the papers' robots) or, with ``fov_rad`` below a full turn, a forward
camera that must be turned toward landmarks.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numba
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState
from localizers.geometry import in_field_of_view
from localizers.raycast import sight_lines_clear
from localizers.schema import check

if TYPE_CHECKING:
    from envs.config import WorldConfig

SIGHT_LINE = (255, 255, 160)


@dataclass(frozen=True)
class BearingCameraConfig(SensorConfig):
    """Camera reporting landmark bearings: omnidirectional or, with ``fov_rad`` below a full
    turn, forward-looking."""

    key: str = "landmarks"
    noise_std_rad: float = math.radians(1.0)
    max_range_m: float = math.inf  # applies to every landmark on top of its own max_range_m
    fov_rad: float = 2 * math.pi  # horizontal field of view centred on the robot's heading
    dropout_probability: float = 0.0  # a visible landmark is missed in a frame
    false_detection_probability: float = 0.0  # per slot and frame: a wrong bearing is reported
    height_m: float = 0.6  # the lens's height: bodies block a sight line where they reach above it

    def __post_init__(self) -> None:
        check(self.noise_std_rad >= 0, f"camera.noise_std_rad must be >= 0, got {self.noise_std_rad}")
        check(self.max_range_m > 0, f"camera.max_range_m must be > 0, got {self.max_range_m}")
        check(0 < self.fov_rad <= 2 * math.pi, f"camera.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        check(0 <= self.dropout_probability <= 1, f"camera.dropout_probability must be in [0, 1], got {self.dropout_probability}")
        check(
            0 <= self.false_detection_probability <= 1,
            f"camera.false_detection_probability must be in [0, 1], got {self.false_detection_probability}",
        )
        check(
            math.isfinite(self.height_m) and self.height_m >= 0, f"camera.height_m must be finite and >= 0, got {self.height_m}"
        )

    def check_world(self, world: WorldConfig, name: str) -> None:
        check(len(world.landmarks) > 0, f"world {world.name!r}: the bearing camera {name!r} needs landmarks")


@register_sensor("bearing_camera", BearingCameraConfig)
class BearingCamera(SensorBase):
    """A bearing per landmark whose line of sight is clear, within range and, for a camera
    narrower than a full turn, inside the field of view around the heading.

    Observation ``(3 L,)``: for each landmark slot in turn ``(visible, cos(bearing),
    sin(bearing))`` in the robot frame (a flat vector, as stable-baselines3 expects; reshape
    to ``(L, 3)`` to read it), zeros when not detected. A false detection puts a uniformly
    random bearing in a slot with ``visible = 1``. ``info`` gets ``visible_landmarks`` and
    ``false_detections``: ``(L,)`` flags of the landmarks truly in sight (before dropout) and of
    the slots holding a false detection.
    """

    draw_layer = "under"

    def __init__(self, name: str, config: BearingCameraConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.count = state.landmark_xy.shape[0]
        self.max_range_m = np.minimum(state.landmark_max_range_m, config.max_range_m)
        seen = state.walls_above(config.height_m)
        self._seg_a, self._seg_b = state.seg_a[seen], state.seg_b[seen]

    def space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, shape=(3 * self.count,), dtype=np.float32)

    def metadata(self) -> dict[str, Any]:
        return {"landmark_count": self.count, "noise_std_rad": self.config.noise_std_rad, "fov_rad": self.config.fov_rad}

    def true_visibility(self, state: WorldState) -> NDArray[np.bool_]:
        """``(L,)`` landmarks in the field of view whose line of sight is clear and within range (no dropout).

        A sight line is blocked by the walls and by the bodies' sections at the camera's
        height (a person's torso, a robot's body; not a ball below the lens).
        """
        occluders = state.occluders(self.config.height_m)
        clear = sight_lines_clear(
            state.positions[0],
            state.landmark_xy,
            state.landmark_radius_m,
            self.max_range_m,
            self._seg_a,
            self._seg_b,
            occluders.centres,
            occluders.radii,
        )
        if self.config.fov_rad < 2 * math.pi:
            clear &= in_field_of_view(state.positions[0], state.angles[0], state.landmark_xy, self.config.fov_rad)
        return clear

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        cfg = self.config
        draws = rng.random((3, self.count))  # dropout, false detection, false bearing
        noise = rng.standard_normal((self.count,)) * cfg.noise_std_rad
        visible = self.true_visibility(state)
        obs = _bearing_slots(
            state.positions[0],
            state.angles[0],
            state.landmark_xy,
            visible,
            draws,
            noise,
            cfg.dropout_probability,
            cfg.false_detection_probability,
        )
        # fixed shapes (one flag per landmark), so that vector envs can stack the infos
        return obs.reshape(-1), {"visible_landmarks": visible, "false_detections": draws[1] < cfg.false_detection_probability}

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[np.float32], info: Mapping[str, Any]) -> None:
        """Sight lines to the landmarks truly in view and, for a narrow camera, the edges of its view."""
        pose = state.robot_pose
        for j in np.flatnonzero(info.get("visible_landmarks", ())):
            canvas.line(pose[:2], state.landmark_xy[j], SIGHT_LINE, 1)
        fov = self.config.fov_rad
        if fov < 2 * np.pi:
            reach = float(np.hypot(*np.ptp(state.seg_a, axis=0))) if len(state.seg_a) else 10.0
            for side in (-0.5, 0.5):
                edge = pose[2] + side * fov
                canvas.line(pose[:2], pose[:2] + reach * np.array([np.cos(edge), np.sin(edge)]), SIGHT_LINE, 1)


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
) -> NDArray[np.float32]:
    """Fill the ``(L, 3)`` camera slots."""
    n = landmark_xy.shape[0]
    obs = np.zeros((n, 3), dtype=np.float32)
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
    return obs
