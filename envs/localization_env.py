"""``LocalizationEnv``: a robot localizing itself among a crowd, as a Gymnasium environment.

Observation (a ``spaces.Dict``, float32, every bound finite):

- ``odometry``: ``(3,)`` noisy commanded increment ``(dx, dy, dtheta)`` since the last step;
- ``landmarks``: ``(3 L,)`` per-landmark ``(visible, cos, sin)`` of the bearing, flattened (worlds with a camera);
- ``lidar``: ``(B,)`` ranges (worlds with a LIDAR);
- ``sonar``: ``(S,)`` nearest range in each sonar cone (with a sonar ring, e.g. ``sonar={}``).

Action: ``Box(-1, 1, (2,))``, scaled to the world's forward speed and turn rate limits.
Ground truth (``true_pose``, ``visible_landmarks``, ``false_detections``, ``contacts``) is in
``info`` only. The base environment's reward is 0: tasks add rewards as wrappers
(``agents.rewards``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.config import WorldConfig, load_world
from envs.sensors import BearingCamera, Lidar, Odometry, Sensor, Sonar
from envs.world import World
from localizers.base import LandmarkMap
from localizers.schema import ConfigError, replace_checked

#: keyword overrides accepted by the env (besides ``world`` and ``render_mode``)
OVERRIDE_SECTIONS = ("robot", "odometry", "camera", "lidar", "sonar", "crowd")

Overlay = Callable[[Any], None]


class LocalizationEnv(gym.Env[dict[str, NDArray[np.float32]], NDArray[np.float32]]):
    """A crowded world seen through noisy sensors.

    Args:
        world: a shipped world name (``"robocup_crowded"``), a YAML path or a ``WorldConfig``.
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        crowd_size: number of moving obstacles (robots or people), the crowd density.
        robot, odometry, camera, lidar, sonar, crowd: mappings overriding fields of that
            section of the world config, for example ``camera={"noise_std_rad": 0.0}``; a
            sensor the world lacks is added with its defaults and the overrides
            (``sonar={}`` gives a robot a sonar ring).

    Raises:
        ConfigError: for an unknown keyword, key or value, naming it.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 30}

    def __init__(
        self,
        world: str | WorldConfig = "robocup_crowded",
        render_mode: str | None = None,
        crowd_size: int | None = None,
        **overrides: Any,
    ) -> None:
        config = world if isinstance(world, WorldConfig) else load_world(world)
        config = apply_overrides(config, crowd_size=crowd_size, **overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(f"render_mode {render_mode!r} is not one of {self.metadata['render_modes']}")
        self.config = config
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": int(round(1.0 / config.dt_s))}
        self.world = World(config)
        rc = config.robot
        self.max_speed_mps = rc.max_speed_mps
        self.max_turn_rate_rps = rc.max_turn_rate_rps
        self.odometry = Odometry(config.odometry, rc.max_speed_mps, rc.max_turn_rate_rps, config.dt_s)
        self.sensors: list[Sensor] = [self.odometry]
        self.camera = BearingCamera(config.camera, self.world) if config.camera is not None else None
        if self.camera is not None:
            self.sensors.append(self.camera)
        self.lidar = Lidar(config.lidar, self.world) if config.lidar is not None else None
        if self.lidar is not None:
            self.sensors.append(self.lidar)
        self.sonar = Sonar(config.sonar, self.world) if config.sonar is not None else None
        if self.sonar is not None:
            self.sensors.append(self.sonar)
        self.observation_space = spaces.Dict({s.key: s.space() for s in self.sensors})
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._overlays: list[Overlay] = []
        self._renderer: Any = None
        self._world_rng = np.random.default_rng(0)
        self._sensor_rng = np.random.default_rng(1)
        self._last_obs: dict[str, NDArray[np.float32]] = {}
        self._last_info: dict[str, Any] = {}

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        super().reset(seed=seed)
        # independent streams: a sensor setting never changes how the crowd moves
        self._world_rng, self._sensor_rng = self.np_random.spawn(2)
        self.world.reset(self._world_rng)
        if options and "robot_pose" in options:
            given = options["robot_pose"]
            try:
                pose = np.asarray(given, dtype=np.float64)
            except (TypeError, ValueError):
                pose = np.full(0, np.nan)
            if pose.shape != (3,) or not np.all(np.isfinite(pose)):
                raise ValueError(f"options['robot_pose'] must be three finite numbers (x_m, y_m, theta_rad), got {given!r}")
            self.world.set_robot_pose(pose)
        for sensor in self.sensors:
            sensor.reset()
        obs, info = self._observe()
        if self.render_mode == "human":
            self.render()
        return obs, info

    def step(self, action: NDArray[np.float32]) -> tuple[dict[str, NDArray[np.float32]], float, bool, bool, dict[str, Any]]:
        a_v, a_w = self._check_action(action)
        dt = self.config.dt_s
        v = a_v * self.max_speed_mps
        omega = a_w * self.max_turn_rate_rps
        theta = float(self.world.angles[0])
        # the commanded motion: turn by omega dt while driving the chord of that arc
        half = 0.5 * omega * dt
        commanded = np.array([v * dt * math.cos(half), v * dt * math.sin(half), omega * dt])
        self.odometry.command(commanded, self._sensor_rng)
        slip = 1.0
        odo = self.config.odometry
        if odo.slip_probability > 0 and self._world_rng.random() < odo.slip_probability:
            slip = 1.0 - self._world_rng.uniform(0.0, odo.slip_max_fraction)
        heading = theta + half
        velocity = np.array([v * slip * math.cos(heading), v * slip * math.sin(heading)])
        n_contacts = len(self.world.contacts)
        self.world.step(velocity, omega * slip, self._world_rng)
        obs, info = self._observe()
        info["contacts"] = self.world.contacts[n_contacts:]
        if self.render_mode == "human":
            self.render()
        return obs, 0.0, False, False, info

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self._renderer is None:
            from envs.render import Renderer

            self._renderer = Renderer(self.config, self.render_mode, self.metadata["render_fps"])
        return self._renderer.draw(self, self._overlays)

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ------------------------------------------------------------------ extras
    def add_overlay(self, draw: Overlay) -> None:
        """Register ``draw(canvas)``, called on every rendered frame (estimates, particles)."""
        self._overlays.append(draw)

    def remove_overlay(self, draw: Overlay) -> None:
        self._overlays.remove(draw)

    @property
    def landmark_map(self) -> LandmarkMap:
        """The known map a localizer gets: landmark positions and the field's bounds."""
        w, h = self.config.size_m
        walls = np.hstack([self.world.seg_a, self.world.seg_b])
        return LandmarkMap(self.world.landmark_xy.copy(), self.world.landmark_names, (0.0, 0.0, w, h), walls)

    @property
    def lidar_beam_angles_rad(self) -> NDArray[np.float64] | None:
        """``(B,)`` the LIDAR's beam angles relative to the heading (ascending), or None without a LIDAR."""
        return None if self.lidar is None else self.lidar.relative_angles.copy()

    @property
    def last_observation(self) -> dict[str, NDArray[np.float32]]:
        return self._last_obs

    @property
    def last_info(self) -> dict[str, Any]:
        return self._last_info

    def _observe(self) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        obs: dict[str, NDArray[np.float32]] = {}
        info: dict[str, Any] = {"true_pose": self.world.robot_pose, "time_s": self.world.time_s, "contacts": []}
        for sensor in self.sensors:
            value, extra = sensor.observe(self.world, self._sensor_rng)
            obs[sensor.key] = value
            info.update(extra)
        self._last_obs = obs
        self._last_info = info
        return obs, info

    def _check_action(self, action: Any) -> tuple[float, float]:
        a = np.asarray(action)
        if a.shape != (2,) or a.dtype.kind not in "fiu":
            raise ValueError(f"action must be a numeric array of shape (2,), got {action!r}")
        v, w = float(a[0]), float(a[1])
        # written so that NaN fails too
        if not (-1.0 <= v <= 1.0 and -1.0 <= w <= 1.0):
            raise ValueError(f"action {[v, w]} is outside the action space [-1, 1]^2 (or not finite)")
        return v, w


def apply_overrides(config: WorldConfig, crowd_size: int | None = None, **overrides: Any) -> WorldConfig:
    """Apply env keyword overrides to a world config, checking every key and value.

    Raises:
        ConfigError: naming an unknown keyword, an unknown key inside a section, or a bad value.
    """
    unknown = sorted(set(overrides) - set(OVERRIDE_SECTIONS))
    if unknown:
        valid = ["world", "render_mode", "crowd_size", *OVERRIDE_SECTIONS]
        raise ConfigError(f"unknown env keyword {unknown[0]!r} = {overrides[unknown[0]]!r} (valid: {', '.join(valid)})")
    changes: dict[str, Any] = {}
    for section, value in overrides.items():
        if value is None:
            continue
        if not isinstance(value, Mapping):
            raise ConfigError(f"env kwarg {section!r} must be a mapping of overrides, got {type(value).__name__} {value!r}")
        # a sensor the world lacks (camera, lidar, sonar) is added: its defaults, then the overrides
        changes[section] = dict(value)
    if crowd_size is not None:
        crowd = dict(changes.get("crowd", {}))
        if "count" in crowd:
            raise ConfigError(f"give the crowd size once: crowd_size={crowd_size!r} and crowd={{'count': {crowd['count']!r}}}")
        crowd["count"] = crowd_size
        changes["crowd"] = crowd
    if not changes:
        return config
    return replace_checked(config, changes, where=f"env kwargs for world {config.name!r}")
