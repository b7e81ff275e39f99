"""The sensor plug-in interface and its registry.

A sensor type is a config dataclass (a :class:`SensorConfig`) plus a class built from it,
registered under a type name with :func:`register_sensor`. A world YAML names its sensors
as a mapping from sensor name to a config tagged by type::

    sensors:
      odometry: {type: odometry, alpha1: 0.02}
      camera: {type: bearing_camera, noise_std_rad: 0.0175}

and the env builds whatever is named there. Each config's ``key`` is the observation key
its readings appear under (every type has a default). Adding a sensor is one module that
registers its type, imported before the world is loaded (the built-in ones are imported by
:mod:`envs.sensors`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, TypeVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from envs.plugins import Entry, Registry
from envs.state import WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig

ConfigT = TypeVar("ConfigT", bound="SensorConfig")
SensorT = TypeVar("SensorT")


class SensorConfig:
    """Base of every sensor config (a frozen dataclass with a ``key: str`` field).

    Loaded from a mapping with a ``type`` entry naming a registered sensor type; the other
    entries are that type's fields, checked by the strict loader.
    """

    type_name: ClassVar[str] = ""
    key: str

    @classmethod
    def __from_config__(cls, value: Any, where: str) -> SensorConfig:
        """Build the config of the type named by ``value["type"]`` (the strict loader's hook)."""
        return SENSORS.config_from(value, where)

    def check_world(self, world: WorldConfig, name: str) -> None:
        """Raise :class:`ConfigError` if this sensor cannot work in ``world`` (override as needed)."""

    def panel_height_px(self, frame_width_px: int) -> int:
        """The height of the panel the sensor shows under the top view of a frame ``frame_width_px``
        wide (its :meth:`Sensor.panel`; a camera's images), 0 for none (the default)."""
        return 0


class Sensor(Protocol):
    """What the env calls on a sensor.

    ``observe`` returns the observation array (inside ``space()``: float32, or uint8 for images) and a dict of
    ground-truth facts for ``info``. A sensor with several observation entries (a stereo
    camera's detections and its images) returns a ``spaces.Dict`` from ``space()``, one of
    whose keys is its ``key``, and a dict of arrays from ``observe``; the env puts each entry
    under its own key. ``command`` sees the exact commanded increment before
    every physics step (odometry records it). ``metadata`` is what a localizer or a
    recording needs to interpret the readings (plain numbers and arrays, no env objects).
    ``draw`` adds the sensor to a rendered frame; ``draw_layer`` says whether it goes
    under the bodies (``"under"``) or over them (``"over"``). ``panel`` is an image shown under
    the top view (a camera's view), for a sensor whose config asks for room
    (:meth:`SensorConfig.panel_height_px`).
    """

    name: str
    key: str
    config: Any
    draw_layer: str

    def space(self) -> spaces.Box | spaces.Dict: ...

    def reset(self) -> None: ...

    def command(self, delta: NDArray[np.float64], rng: np.random.Generator) -> None: ...

    def observe(
        self, state: WorldState, rng: np.random.Generator
    ) -> tuple[NDArray[Any] | dict[str, NDArray[Any]], dict[str, Any]]: ...

    def metadata(self) -> dict[str, Any]: ...

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[Any], info: Mapping[str, Any]) -> None: ...

    def panel(self, state: WorldState, width_px: int, height_px: int) -> NDArray[np.uint8]: ...


class SensorBase:
    """Defaults for the optional parts of :class:`Sensor` (no command hook, no metadata, drawn over the bodies)."""

    name: str
    key: str
    draw_layer = "over"

    def reset(self) -> None:
        pass

    def command(self, delta: NDArray[np.float64], rng: np.random.Generator) -> None:
        pass

    def metadata(self) -> dict[str, Any]:
        return {}

    def draw(self, canvas: Any, state: WorldState, reading: NDArray[Any], info: Mapping[str, Any]) -> None:
        pass

    def panel(self, state: WorldState, width_px: int, height_px: int) -> NDArray[np.uint8]:
        """The ``(height_px, width_px, 3)`` panel under the top view (for a config whose
        :meth:`SensorConfig.panel_height_px` is not 0)."""
        raise NotImplementedError(f"sensor {self.name!r} has no panel")


#: builds a sensor from its name, its config, the world config and the world's first state
SensorFactory = Callable[[str, Any, "WorldConfig", WorldState], Sensor]
SensorType = Entry[SensorConfig, SensorFactory]

#: the registered sensor types
SENSORS: Registry[SensorConfig, SensorFactory] = Registry("sensor", SensorConfig)


def register_sensor(type_name: str, config_cls: type[ConfigT]) -> Callable[[type[SensorT]], type[SensorT]]:
    """Class decorator: register a sensor class (``cls(name, config, world, state)``) under ``type_name``.

    Raises:
        ValueError: if the name is taken by another class, or the config is not a
            :class:`SensorConfig` dataclass with a ``key`` field.
    """
    if dataclasses.is_dataclass(config_cls) and "key" not in {f.name for f in dataclasses.fields(config_cls)}:
        raise ValueError(f"sensor type {type_name!r}: {config_cls.__name__} needs a 'key' field (its observation key)")
    return SENSORS.decorator(type_name, config_cls)


def sensor_types() -> list[str]:
    """The registered sensor type names, sorted."""
    return SENSORS.names()


def sensor_type(name: Any, where: str = "sensor type") -> SensorType:
    """The registered type ``name``, or a :class:`ConfigError` listing the known ones."""
    return SENSORS.get(name, where)


def build_sensor(name: str, config: SensorConfig, world: WorldConfig, state: WorldState) -> Sensor:
    """The sensor ``config`` describes, named ``name``."""
    return sensor_type(config.type_name, f"sensor {name!r}").build(name, config, world, state)
