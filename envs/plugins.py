"""One registry shape for every plug-in kind of the worlds (sensors, crowds).

A plug-in type is a config dataclass plus a factory, registered under a type name. A world
YAML names its plug-ins as a mapping from name to a config tagged by ``type``; the strict
loader (:mod:`core.schema`) calls the base config's ``__from_config__`` hook, which
asks the registry for the tagged class and loads the remaining keys into it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from core.schema import ConfigError, from_mapping

C = TypeVar("C")
F = TypeVar("F")


@dataclass(frozen=True)
class Entry(Generic[C, F]):
    """A registered plug-in type: its name, config class and factory."""

    name: str
    config_cls: type[C]
    build: F


class Registry(Generic[C, F]):
    """Plug-in types of one kind (``what``: "sensor", "crowd"), by type name."""

    def __init__(self, what: str, base: type[C]) -> None:
        self.what = what
        self.base = base
        self._entries: dict[str, Entry[C, F]] = {}

    def register(self, type_name: str, config_cls: type[C], build: F) -> Entry[C, F]:
        """Register ``build`` for configs of ``config_cls`` under ``type_name`` (again with the same pair: no-op).

        Raises:
            ValueError: if the config is not a dataclass subclass of the base, or the name is taken.
        """
        if not (dataclasses.is_dataclass(config_cls) and issubclass(config_cls, self.base)):  # type: ignore[arg-type]
            raise ValueError(
                f"{self.what} type {type_name!r}: {config_cls.__name__} must be a dataclass subclassing {self.base.__name__}"
            )
        current = self._entries.get(type_name)
        if current is not None and (current.build is not build or current.config_cls is not config_cls):
            owner = getattr(current.build, "__qualname__", repr(current.build))
            raise ValueError(f"{self.what} type {type_name!r} is already registered by {current.build.__module__}.{owner}")  # type: ignore[attr-defined]
        config_cls.type_name = type_name  # type: ignore[attr-defined]
        entry: Entry[C, F] = Entry(type_name, config_cls, build)
        self._entries[type_name] = entry
        return entry

    def decorator(self, type_name: str, config_cls: type[C]) -> Callable[[Any], Any]:
        """Class decorator form of :meth:`register` (the class is the factory)."""

        def decorate(cls: Any) -> Any:
            self.register(type_name, config_cls, cls)
            return cls

        return decorate

    def names(self) -> list[str]:
        """The registered type names, sorted."""
        return sorted(self._entries)

    def get(self, type_name: Any, where: str) -> Entry[C, F]:
        """The registered type, or a :class:`ConfigError` naming it, ``where`` and the known types."""
        if not isinstance(type_name, str) or type_name not in self._entries:
            raise ConfigError(f"{where}: unknown {self.what} type {type_name!r} (registered: {', '.join(self.names())})")
        return self._entries[type_name]

    def config_from(self, value: Any, where: str) -> C:
        """Load a config tagged by ``type`` (a mapping), or pass a ready config through."""
        if isinstance(value, self.base):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: expected a mapping with a 'type' (one of {', '.join(self.names())}), got {value!r}")
        if "type" not in value:
            raise ConfigError(f"{where}: a {self.what} needs a 'type' (one of {', '.join(self.names())})")
        entry = self.get(value["type"], where)
        return from_mapping(entry.config_cls, {k: v for k, v in value.items() if k != "type"}, where)
