"""Strict conversion of plain mappings (parsed YAML, keyword overrides) into frozen dataclasses.

A leaf module shared by the world configs (``envs.config``) and the localizer parameter
files (``configs/localizers/*.yaml``). Every error names the offending key, the value and
where it came from; nothing is silently coerced (an integer is accepted where a ``float``
is declared, and numpy's numbers where Python's are; nothing else is widened).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
import types
import typing
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value is missing, unknown, mistyped or out of range."""


class _Loader(yaml.SafeLoader):
    """Safe loading with YAML 1.2 floats: ``1e-3`` is a number (PyYAML's 1.1 rules make it a string)."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def parse_yaml(text: str) -> Any:
    """Parse a YAML document or scalar (``"1e-3"`` -> ``0.001``, ``"[2, 4]"`` -> a list)."""
    return yaml.load(text, Loader=_Loader)  # noqa: S506 (a SafeLoader subclass)


def load_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML file whose top level is a mapping.

    Raises:
        ConfigError: if the file is missing, is not valid YAML or is not a mapping.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"config file {str(p)!r} does not exist")
    try:
        data = parse_yaml(p.read_text())
    except yaml.YAMLError as exc:
        raise ConfigError(f"{p}: not valid YAML: {exc}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{p}: top level must be a mapping, got {type(data).__name__}")
    return data


def from_mapping(cls: type[T], data: Any, where: str) -> T:
    """Build dataclass ``cls`` from ``data``, checking every key and type recursively.

    A class that defines a ``__from_config__(value, where)`` classmethod itself (not through a
    base class) builds itself from the value: a base config whose ``type`` entry names the
    registered subclass to load (a world's sensors and crowds).

    Args:
        cls: a dataclass type whose fields have concrete annotations.
        data: a mapping of field names to values.
        where: a human-readable origin (a file name, ``"env kwarg 'camera'"``) used in errors.

    Raises:
        ConfigError: naming the key, the value and ``where``.
    """
    return _convert(cls, data, where)


def merge_nested(base: Mapping[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` updated by ``extra``, mapping values merged key by key (neither is changed)."""
    out = dict(base)
    for key, value in extra.items():
        current = out.get(key)
        out[key] = merge_nested(current, value) if isinstance(current, Mapping) and isinstance(value, Mapping) else value
    return out


def replace_checked(obj: T, overrides: Mapping[str, Any], where: str) -> T:
    """``dataclasses.replace`` with the same checks as :func:`from_mapping`.

    Nested dataclass fields may be overridden by a mapping, which is merged field by field;
    a mapping field (``env_kwargs``) is merged key by key (:func:`merge_nested`), so that an
    override of one key keeps the others; a dataclass inside a mapping field (a world's
    sensors) is again merged field by field.
    """
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise TypeError(f"replace_checked needs a dataclass instance, got {type(obj).__name__}")
    if not isinstance(overrides, Mapping):
        raise ConfigError(f"{where}: overrides must be a mapping, got {type(overrides).__name__} {overrides!r}")
    cls = type(obj)
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    changes: dict[str, Any] = {}
    for key, value in overrides.items():
        if key not in names:
            raise ConfigError(f"{where}: unknown key {key!r} for {cls.__name__} (valid keys: {', '.join(sorted(names))})")
        current = getattr(obj, key)
        if dataclasses.is_dataclass(current) and isinstance(value, Mapping):
            changes[key] = replace_checked(current, value, f"{where}.{key}")
        elif isinstance(current, Mapping) and isinstance(value, Mapping):
            # entries that are dataclasses (a world's sensors) take their overrides field by field
            value = {
                k: replace_checked(current[k], v, f"{where}.{key}.{k}")
                if dataclasses.is_dataclass(current.get(k)) and isinstance(v, Mapping)
                else v
                for k, v in value.items()
            }
            changes[key] = _convert(hints[key], merge_nested(current, value), f"{where}.{key}")
        else:
            changes[key] = _convert(hints[key], value, f"{where}.{key}")
    try:
        return dataclasses.replace(obj, **changes)
    except (ValueError, TypeError) as exc:
        raise ConfigError(f"{where}: {exc}") from exc


def _type_name(tp: Any) -> str:
    return getattr(tp, "__name__", None) or str(tp).replace("typing.", "")


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if tp is Any:
        return value
    if isinstance(tp, type) and "__from_config__" in vars(tp):
        # a type that builds itself (its own hook, not a base class's), e.g. a base config
        # whose ``type`` entry names the registered subclass to build
        return typing.cast(Any, tp).__from_config__(value, where)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ConfigError as exc:
                errors.append(str(exc))
        raise ConfigError(f"{where}: {value!r} matches none of {_type_name(tp)}: " + "; ".join(errors))
    if origin is typing.Literal:
        if value not in args:
            raise ConfigError(f"{where}: {value!r} is not one of {', '.join(map(repr, args))}")
        return value
    if dataclasses.is_dataclass(tp) and isinstance(tp, type):
        if isinstance(value, tp):
            return value
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: expected a mapping for {tp.__name__}, got {type(value).__name__} {value!r}")
        hints = typing.get_type_hints(tp)
        fields = {f.name: f for f in dataclasses.fields(tp) if f.init}
        for key in value:
            if key not in fields:
                raise ConfigError(f"{where}: unknown key {key!r} for {tp.__name__} (valid keys: {', '.join(sorted(fields))})")
        kwargs = {}
        for name, field in fields.items():
            if name in value:
                kwargs[name] = _convert(hints[name], value[name], f"{where}.{name}")
            elif field.default is dataclasses.MISSING and field.default_factory is dataclasses.MISSING:
                raise ConfigError(f"{where}: missing required key {name!r} for {tp.__name__}")
        try:
            return tp(**kwargs)
        except (ValueError, TypeError) as exc:
            raise ConfigError(f"{where}: {exc}") from exc
    if origin in (Mapping, dict):
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: expected a mapping, got {type(value).__name__} {value!r}")
        key_type, value_type = args or (str, Any)
        return {_convert(key_type, k, f"{where} key"): _convert(value_type, v, f"{where}.{k}") for k, v in value.items()}
    if origin is tuple:
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: expected a list, got {type(value).__name__} {value!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(f"{where}: expected {len(args)} values, got {len(value)}: {value!r}")
        return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value)))
    if tp is float:  # any real number, numpy's included (np.float32(0.5), np.int64(2)); never a bool
        if not is_real(value):
            raise ConfigError(f"{where}: expected a number, got {type(value).__name__} {value!r}")
        try:
            return float(value)
        except OverflowError:  # an integer beyond any float (10**400)
            raise ConfigError(f"{where}: {value!r} is too large for a number") from None
    if tp is int:  # any integer, numpy's included (np.int64(5): a count taken from an array); never a bool
        if not is_int(value):
            raise ConfigError(f"{where}: expected an integer, got {type(value).__name__} {value!r}")
        return int(value)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {type(value).__name__} {value!r}")
        return value
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {type(value).__name__} {value!r}")
        return value
    raise TypeError(f"{where}: unsupported annotation {tp!r}")


def is_real(value: Any, *, finite: bool = False) -> bool:
    """Whether ``value`` is a real number: a Python or numpy integer or float (any ``numbers.Real``),
    never a bool (YAML's ``true`` is no number, though Python counts it as 1); with ``finite``, not
    NaN or infinite either.

    The one test of "a number" for config and argument checks; each caller adds its range and names
    the value in its own message."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        return False
    return math.isfinite(value) if finite else True


def is_int(value: Any) -> bool:
    """Whether ``value`` is a Python or numpy integer (any ``numbers.Integral``), never a bool: the
    integer counterpart of :func:`is_real`."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check(condition: bool, message: str) -> None:
    """Raise :class:`ConfigError` with ``message`` unless ``condition`` holds.

    Used in dataclass ``__post_init__`` range checks.
    """
    if not condition:
        raise ConfigError(message)


def check_ranges(
    obj: object,
    where: str,
    *,
    positive: Iterable[str] = (),
    non_negative: Iterable[str] = (),
    positive_or_inf: Iterable[str] = (),
) -> None:
    """Raise :class:`ConfigError` unless each field of ``obj`` named in ``positive`` is a finite
    number > 0, each in ``non_negative`` a finite number >= 0 and each in ``positive_or_inf`` a
    number > 0 where ``inf`` means no limit (a time after which a localizer is lost: never), naming
    ``where.field`` and its value.

    Used in dataclass ``__post_init__`` range checks (``where``: the class or section name).
    """
    rules = (
        (positive, True, lambda v: v > 0, "finite and > 0"),
        (non_negative, True, lambda v: v >= 0, "finite and >= 0"),
        (positive_or_inf, False, lambda v: v > 0, "> 0 (inf: no limit)"),
    )
    for names, finite, holds, bound in rules:
        for name in names:
            value = getattr(obj, name)
            check(
                is_real(value, finite=finite) and holds(value),  # NaN fails holds
                f"{where}.{name} must be {bound}, got {value!r}",
            )


def check_rgb(value: Any, where: str) -> None:
    """Raise :class:`ConfigError` unless ``value`` is an RGB colour: three integers 0-255 (``where`` names it)."""
    check(
        isinstance(value, (tuple, list)) and len(value) == 3 and all(is_int(c) and 0 <= c <= 255 for c in value),
        f"{where} must be three integers 0-255, got {value!r}",
    )


def check_at_most(obj: object, where: str, limits: Mapping[str, float], why: str) -> None:
    """Raise :class:`ConfigError` unless each field of ``obj`` named in ``limits`` is at most its limit,
    naming ``where.field``, its value, the limit and ``why`` (what the bound protects: memory, a
    sensor's resolution).

    Used in dataclass ``__post_init__`` range checks beside :func:`check_ranges` (which checks the
    lower end and finiteness): a size of ``10**9`` is refused here, before anything is allocated.
    """
    for name, limit in limits.items():
        value = getattr(obj, name)
        check(value <= limit, f"{where}.{name} must be at most {limit:,} ({why}), got {value!r}")
