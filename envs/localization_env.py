"""``LocalizationEnv``: a robot localizing itself among a crowd, as a Gymnasium environment.

Observation: a ``spaces.Dict`` with one float32 entry per sensor the world config names
(``sensors:`` in its YAML), under the sensor's ``key``; every bound is finite. The shipped
worlds have ``odometry`` ``(3,)`` (the noisy commanded increment since the last step) and
either ``landmarks`` ``(3 L,)`` (a bearing camera's ``(visible, cos, sin)`` per landmark,
flattened) or ``lidar`` ``(B,)``; ``sonar={}`` adds a sonar ring (``sonar`` ``(S,)``).

Action: ``Box(-1, 1, (2,))``, scaled to the world's forward speed and turn rate limits.
Ground truth (``true_pose``, ``contacts``, ``slip_fraction``: the fraction of the step's
commanded motion the wheels lost, :meth:`envs.config.RobotConfig.slip_fraction`; the sensors'
facts such as ``visible_landmarks``, ``false_detections`` and ``distractor_detections``, one
flag per landmark) is in ``info`` only; every entry but the ``contacts`` list has a fixed
shape, so ``gym.make_vec`` can stack them. An episode terminates when the world has a
``goal`` and the robot has stood still there (else it only times out). The base
environment's reward is 0: tasks add rewards as wrappers (``agents.rl.rewards``, ``agents.rl.tasks``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.schema import ConfigError, replace_checked
from core.types import LandmarkMap
from envs.config import WorldConfig, load_world
from envs.layouts import checked_layout, layout_world
from envs.sensors import Sensor, SensorBase, build_sensor, sensor_types
from envs.state import WorldState
from envs.world import World

#: keyword overrides of world sections accepted by the env (besides the sensors, by name or type)
OVERRIDE_SECTIONS = ("robot", "crowd")
_SECTION_FIELDS = {"robot": "robot", "crowd": "crowds"}  # keyword -> WorldConfig field
#: what gym.make takes besides the world overrides (the localizer wrapper's keywords, the time limit)
MAKE_KEYWORDS = ("localizer", "localizer_params", "prior", "belief_spread", "localizer_sensor", "max_episode_steps")
#: the options ``reset`` understands
RESET_OPTIONS = ("robot_pose",)

Overlay = Callable[[Any], None]


class LocalizationEnv(gym.Env[dict[str, NDArray[np.float32]], NDArray[np.float32]]):
    """A crowded world seen through noisy sensors.

    Args:
        world: a shipped world name (``"robocup_crowded"``), a YAML path or a ``WorldConfig``.
        render_mode: ``None``, ``"rgb_array"`` or ``"human"``.
        crowd_size: number of moving obstacles (robots or people), the crowd density.
        layout: a layout seed: the world's scenery drawn by its layout generator
            (:mod:`envs.layouts`) before the overrides; None (the default) keeps the world's own.
        robot: a mapping overriding fields of the world's robot.
        crowd: a mapping from crowd name to overrides of that crowd's fields
            (``crowd={"walkers": {"count": 6}}``).
        **overrides: a sensor's name (``camera={"noise_std_rad": 0.0}``) overrides fields of
            that sensor; a registered sensor type the world lacks is added under its type
            name with its defaults and the given fields (``sonar={}`` gives a robot a
            sonar ring).

    Raises:
        ConfigError: for an unknown keyword, key or value, naming it.
    """

    metadata = {"render_modes": ["rgb_array", "human"], "render_fps": 30}

    def __init__(
        self,
        world: str | WorldConfig = "robocup_crowded",
        render_mode: str | None = None,
        crowd_size: int | None = None,
        layout: int | None = None,
        **overrides: Any,
    ) -> None:
        config = world if isinstance(world, WorldConfig) else load_world(world)
        #: the crowd size of the world as given, before the env's overrides (None without a crowd):
        #: what a world's default data is made with, whatever crowd this env runs (a scene map)
        self.file_crowd_size: int | None = config.crowd.count if config.crowd is not None else None
        #: the layout seed this world was drawn with (:mod:`envs.layouts`); None: the world's own layout
        self.layout = None if layout is None else checked_layout(layout)
        if self.layout is not None:
            config = layout_world(config, self.layout)
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
        state = self.world.snapshot()
        #: the sensors by name, in the config's order (which is also the order they draw randomness)
        self.sensors: dict[str, Sensor] = {name: build_sensor(name, sc, config, state) for name, sc in config.sensors.items()}
        # the sensors that see the commanded motion (odometry), in config order
        self._commanded = [
            s for s in self.sensors.values() if getattr(type(s), "command", SensorBase.command) is not SensorBase.command
        ]
        self.observation_space = spaces.Dict(observation_entries(self.sensors.values()))  # type: ignore[assignment]  # gym.Env types it as a generic Space
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._overlays: list[Overlay] = []
        self._renderer: Any = None
        self._world_rng = np.random.default_rng(0)
        self._sensor_rng = np.random.default_rng(1)
        self._last_obs: dict[str, NDArray[np.float32]] = {}
        self._last_info: dict[str, Any] = {}
        self._still_s = 0.0
        self._last_command = (0.0, 0.0)  # the last step's commanded (speed m/s, turn rate rad/s)
        self._slips = self.config.robot.slips  # whether any wheel slip is set

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        unknown = sorted(set(options or ()) - set(RESET_OPTIONS))
        if unknown:
            raise ValueError(f"unknown reset option {unknown[0]!r} (options: {', '.join(RESET_OPTIONS)})")
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
            problem = self.world.robot_placement_problem(float(pose[0]), float(pose[1]))
            if problem:
                raise ValueError(f"options['robot_pose'] = {given!r}: {problem}")
            self.world.set_robot_pose(pose)
        for sensor in self.sensors.values():
            sensor.reset()
        self._still_s = 0.0
        self._last_command = (0.0, 0.0)  # the robot starts at rest: a first command is an acceleration
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
        for sensor in self._commanded:
            sensor.command(commanded, self._sensor_rng)
        # wheel slip (RobotConfig.slip_fraction): the body moves and turns less than commanded
        lost = 0.0
        if self._slips:  # (nothing is drawn, nor the last command kept, when no slip is set)
            rc = self.config.robot
            last_v, last_omega = self._last_command
            self._last_command = (v, omega)
            in_contact = rc.slip_in_contact > 0 and self.world.robot_touching()
            lost = rc.slip_fraction(abs(v - last_v) / dt, abs(omega - last_omega) / dt, in_contact, self._world_rng)
        slip = 1.0 - lost
        heading = theta + half
        velocity = np.array([v * slip * math.cos(heading), v * slip * math.sin(heading)])
        self.world.step(velocity, omega * slip, self._world_rng)
        obs, info = self._observe()
        info["contacts"] = list(self.world.contacts)  # the world keeps this step's events only
        info["slip_fraction"] = lost
        terminated = self._at_goal(a_v, a_w)
        if self.render_mode == "human":
            self.render()
        return obs, 0.0, terminated, False, info

    def _at_goal(self, a_v: float, a_w: float) -> bool:
        """Whether the robot has now stood still at the world's goal for its hold time."""
        goal = self.config.goal
        if goal is None:
            return False
        x, y, _ = self.world.robot_pose
        still = abs(a_v) <= goal.still_fraction and abs(a_w) <= goal.still_fraction
        near = math.hypot(x - goal.x_m, y - goal.y_m) <= goal.radius_m
        self._still_s = self._still_s + self.config.dt_s if (still and near) else 0.0
        return self._still_s >= goal.hold_s - 1e-9

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

    def __reduce__(self) -> Any:
        # pymunk's space holds C data that cannot be pickled: say so, rather than a cffi error
        raise TypeError(
            "a crowdloc env cannot be pickled or deep-copied (its pymunk space holds C data); make another with "
            "gym.make(id, ...) instead, or pass a function that makes one (as vector envs do)"
        )

    # ------------------------------------------------------------------ extras
    def add_overlay(self, draw: Overlay) -> None:
        """Register ``draw(canvas)``, called on every rendered frame (estimates, particles)."""
        self._overlays.append(draw)

    def remove_overlay(self, draw: Overlay) -> None:
        self._overlays.remove(draw)

    @property
    def landmark_map(self) -> LandmarkMap:
        """The known map a localizer gets: landmark positions, the field's bounds, the walls and
        furniture with their heights (where the map has them: ``map_offset_m``) and the
        features' map data (a ceiling's targets), as plain values. A localizer on a range
        sensor gets it cut at the sensor's height (:func:`localizers.measurements.sensor_map`)."""
        segments = self.config.static_segments(in_map=True)  # furniture where the map has it
        features = {name: f.map_data() for name, f in self.config.features.items()}
        return LandmarkMap(
            self.world.landmark_xy.copy(),
            self.world.landmark_names,
            self.config.field_m,
            segments[:, 0:4],
            features,
            wall_heights_m=segments[:, 4:6],
            disk_cache=self.layout is None,  # a layout's tables are built in memory (core.types.LandmarkMap)
        )

    @property
    def sensor_metadata(self) -> dict[str, dict[str, Any]]:
        """Per sensor name: its ``type``, observation ``key`` and the sensor's own metadata
        (what a localizer or a recording needs to read its observations: a LIDAR's beam
        angles and maximum range, a camera's landmark count and noise). Plain values only."""
        return {name: {"type": s.config.type_name, "key": s.key, **s.metadata()} for name, s in self.sensors.items()}

    def sensor_of_type(self, type_name: str) -> Sensor | None:
        """The env's one sensor of a registered type (``"lidar"``), None without one (see
        :meth:`WorldConfig.sensor_of_type`)."""
        config = self.config.sensor_of_type(type_name)
        return None if config is None else next(s for s in self.sensors.values() if s.config is config)

    @property
    def state(self) -> WorldState:
        """The frozen snapshot of the world at the current step (ground truth: not for policies)."""
        return self.world.snapshot()

    @property
    def last_observation(self) -> dict[str, NDArray[np.float32]]:
        return self._last_obs

    @property
    def last_info(self) -> dict[str, Any]:
        return self._last_info

    def _observe(self) -> tuple[dict[str, NDArray[np.float32]], dict[str, Any]]:
        obs: dict[str, NDArray[np.float32]] = {}
        info: dict[str, Any] = {
            "true_pose": self.world.robot_pose,
            "time_s": self.world.time_s,
            "contacts": [],
            "slip_fraction": 0.0,
        }
        state = self.world.snapshot()
        for sensor in self.sensors.values():
            value, extra = sensor.observe(state, self._sensor_rng)
            if isinstance(value, dict):  # a sensor of several entries (space() is a Dict)
                obs.update(value)
            else:
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


def observation_entries(sensors: Iterable[Sensor]) -> dict[str, spaces.Space[Any]]:
    """The observation's entries by key: each sensor's ``space()`` under its ``key``, or, where
    ``space()`` is a ``spaces.Dict`` (a stereo camera's detections and, when asked for, its
    images), each of its entries under its own key (the sensor's ``key`` among them: the entry
    its ``draw`` and the localizers read).

    Raises:
        ConfigError: if two sensors write the same key, or a Dict lacks the sensor's key.
    """
    entries: dict[str, spaces.Space[Any]] = {}
    owner: dict[str, str] = {}
    for sensor in sensors:
        space = sensor.space()
        parts: dict[str, spaces.Space[Any]] = dict(space.spaces) if isinstance(space, spaces.Dict) else {sensor.key: space}
        if sensor.key not in parts:
            raise ConfigError(f"sensor {sensor.name!r}: its observation entries {sorted(parts)} lack its key {sensor.key!r}")
        for key, part in parts.items():
            if key in entries:
                raise ConfigError(
                    f"sensors {owner[key]!r} and {sensor.name!r} both write observation key {key!r}; give one of them another key"
                )
            entries[key] = part
            owner[key] = sensor.name
    return entries


def apply_overrides(config: WorldConfig, crowd_size: int | None = None, **overrides: Any) -> WorldConfig:
    """Apply env keyword overrides to a world config, checking every key and value.

    A keyword is a world section (``robot``, ``crowd``), the name of one of the world's
    sensors (its fields are overridden), a registered sensor type the world lacks (added
    under that name with its defaults and the given fields), or ``sensors``: sensor name ->
    overrides, where a name the world lacks adds a sensor of the given ``type`` (a second
    LIDAR: ``sensors={"lidar_top": {"type": "lidar", "key": "lidar_top", "height_m": 1.9}}``).

    Raises:
        ConfigError: naming an unknown keyword, an unknown key inside a section, or a bad value.
    """
    changes: dict[str, Any] = {}
    sensors: dict[str, Any] = {}
    named = overrides.pop("sensors", None)
    if named is not None:
        if not isinstance(named, Mapping):
            raise ConfigError(f"env kwarg 'sensors' must map sensor names to mappings, got {type(named).__name__} {named!r}")
        for name, value in named.items():
            if not isinstance(value, Mapping):
                raise ConfigError(f"env kwarg sensors[{name!r}] must be a mapping, got {type(value).__name__} {value!r}")
            if name not in config.sensors and "type" not in value:
                raise ConfigError(
                    f"env kwarg sensors[{name!r}]: world {config.name!r} has no sensor {name!r} (sensors: "
                    f"{', '.join(config.sensors)}); a new one needs a 'type' (one of {', '.join(sensor_types())})"
                )
            sensors[str(name)] = dict(value)
    for section, value in overrides.items():
        known = section in OVERRIDE_SECTIONS or section in config.sensors or section in sensor_types()
        if not known:
            valid = ["world", "render_mode", "crowd_size", "layout", "sensors", *OVERRIDE_SECTIONS, *config.sensors]
            added = [t for t in sensor_types() if t not in config.sensors]
            raise ConfigError(
                f"unknown env keyword {section!r} = {value!r} (valid: {', '.join(valid)}; "
                f"or a sensor type to add: {', '.join(added)}; gym.make also takes {', '.join(MAKE_KEYWORDS)})"
            )
        if value is None:
            continue
        if not isinstance(value, Mapping):
            raise ConfigError(f"env kwarg {section!r} must be a mapping of overrides, got {type(value).__name__} {value!r}")
        if section in OVERRIDE_SECTIONS:
            changes[_SECTION_FIELDS[section]] = dict(value)
        elif section in config.sensors:
            sensors[section] = dict(value)
        else:  # a sensor type the world lacks: its defaults, then the overrides
            sensors[section] = {"type": section, **value}
    if sensors:
        changes["sensors"] = sensors
    crowds = changes.get("crowds", {})
    for name, value in crowds.items():
        if name not in config.crowds:
            raise ConfigError(
                f"env kwarg crowd: world {config.name!r} has no crowd {name!r} (crowds: {', '.join(config.crowds) or 'none'})"
            )
        if not isinstance(value, Mapping):
            raise ConfigError(f"env kwarg crowd[{name!r}] must be a mapping of overrides, got {type(value).__name__} {value!r}")
    if crowd_size is not None:
        if not config.crowds:
            raise ConfigError(f"crowd_size={crowd_size!r}: world {config.name!r} has no crowd")
        first = next(iter(config.crowds))
        mine = dict(crowds.get(first, {}))
        if "count" in mine:
            raise ConfigError(
                f"give the crowd size once: crowd_size={crowd_size!r} and crowd={{{first!r}: {{'count': {mine['count']!r}}}}}"
            )
        changes["crowds"] = {**crowds, first: {**mine, "count": crowd_size}}
    if not changes:
        return config
    return replace_checked(config, changes, where=f"env kwargs for world {config.name!r}")
