"""The map-feature plug-in interface: static scenery a sensor renders and a localizer may know.

A feature type is a frozen config dataclass subclassing :class:`FeatureConfig`, registered
under a type name with :func:`register_feature`. A world YAML names its features as a
mapping from name to a config tagged by type::

    features:
      ceiling: {type: ceiling, height_m: 2.5, targets: [...]}

Features have no physics (walls and poles stay in ``walls`` and ``landmarks``). They say what
a localizer's map holds of them (:meth:`FeatureConfig.map_data`, plain values, which the env
puts in :attr:`localizers.base.LandmarkMap.features`) and how the top view draws them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, TypeVar

from envs.plugins import Registry

if TYPE_CHECKING:
    from envs.config import WorldConfig

ConfigT = TypeVar("ConfigT", bound="FeatureConfig")


class FeatureConfig:
    """Base of every feature config (a frozen dataclass), loaded from a mapping with a ``type``."""

    type_name: ClassVar[str] = ""

    @classmethod
    def __from_config__(cls, value: Any, where: str) -> FeatureConfig:
        """Build the config of the type named by ``value["type"]`` (the strict loader's hook)."""
        return FEATURES.config_from(value, where)

    def check_world(self, world: WorldConfig, name: str) -> None:
        """Raise :class:`ConfigError` if this feature does not fit ``world`` (override as needed)."""

    def map_data(self) -> dict[str, Any]:
        """What a localizer's map holds of this feature: plain numbers, strings and arrays."""
        return {}

    def draw(self, canvas: Any, world: WorldConfig) -> None:
        """Draw the feature on the top view of ``world`` (the background layer)."""


#: the registered feature types; a feature is its config (the factory is the config class)
FEATURES: Registry[FeatureConfig, Callable[..., Any]] = Registry("feature", FeatureConfig)


def register_feature(type_name: str) -> Callable[[type[ConfigT]], type[ConfigT]]:
    """Class decorator: register a :class:`FeatureConfig` dataclass under ``type_name``."""

    def decorate(cls: type[ConfigT]) -> type[ConfigT]:
        FEATURES.register(type_name, cls, cls)
        return cls

    return decorate


def feature_types() -> list[str]:
    """The registered feature type names, sorted."""
    return FEATURES.names()
