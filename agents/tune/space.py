"""The search space of ``crowdloc tune``: ``configs/tuning/<localizer>.yaml`` and its checks.

Per parameter ``{low, high[, log][, step]}`` or ``{choices: [...]}``; dotted names reach nested
parameters (``mcl.hit_std_m``). Parameters not in the space keep their YAML defaults. A
``sum_to_one:`` list names groups of searched weights that must sum to 1 (the LIDAR beam
model's mixture weights): each member is drawn as a raw weight in its range and the group is
divided by its sum before it reaches the localizer (:meth:`SearchSpace.applied`). A range's
``at_most: OTHER`` caps it by the value drawn for another searched parameter of the file (the
candidate sets' ``abort_error_rad`` is at most their ``prune_error_rad``: above it, it has no effect).

A localizer is *tunable* when it has a search-space file; the shipped localizers without one
are in :data:`UNTUNED` with the reason, and ``crowdloc tune`` refuses them with it.
"""

from __future__ import annotations

import dataclasses
import importlib
import math
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import optuna

import crowdloc_configs
from agents.common.util import nest
from core.schema import ConfigError, is_int, is_real, load_yaml
from localizers.registry import LOCALIZERS, load_params, spec

TUNING_CONFIG_DIR = crowdloc_configs.path("tuning")  # package data (configs/ in the checkout)
_SPEC_KEYS = ("low", "high", "log", "step", "choices", "at_most")
_TOP_KEYS = ("parameters", "sum_to_one")
#: a group that already sums to 1 within this is applied unchanged (the params' own check allows 1e-6)
_SUM_TOL = 1e-12

#: shipped localizers deliberately without a search space, and why (``crowdloc tune`` says so)
UNTUNED: dict[str, str] = {
    "dead_reckoning": "it has nothing to tune: it integrates the odometry from the known start pose, and its "
    "parameters (the covariance growth) change the reported spread, never the pose",
    "ceiling_target": "its colour thresholds are fitted by `crowdloc fit ceiling_target`; under the paper's reset "
    "fusion the fix sds and drift rates change the covariance only; and its recordings (a 320 x 240 colour image "
    "per step, ~230 MB a minute) do not fit tune's record-once-replay-every-trial design",
}


@dataclass(frozen=True)
class ParamRange:
    """One searched parameter.

    Attributes:
        name: the parameter, dotted for nested ones (``mcl.hit_std_m``).
        kind: ``"float"``, ``"int"`` or ``"categorical"``.
        low, high: bounds (``float``/``int`` kinds), ``low < high``.
        log: sample on a log scale.
        step: discretization step (optional, not with ``log``).
        choices: the values of a categorical parameter.
        at_most: another searched parameter whose drawn value caps ``high`` (None: no cap).
    """

    name: str
    kind: str
    low: float | None = None
    high: float | None = None
    log: bool = False
    step: float | None = None
    choices: tuple[Any, ...] = ()
    at_most: str | None = None

    def top(self, drawn: Mapping[str, Any]) -> Any:
        """The upper bound given the values ``drawn`` so far: ``high``, capped by ``at_most``'s value."""
        assert self.high is not None
        return self.high if self.at_most is None else min(self.high, drawn[self.at_most])

    def suggest(self, trial: optuna.Trial, drawn: Mapping[str, Any]) -> Any:
        """Draw this parameter for ``trial`` (``drawn``: the values drawn before it)."""
        if self.kind == "categorical":
            return trial.suggest_categorical(self.name, list(self.choices))
        assert self.low is not None
        high = self.top(drawn)
        if self.kind == "int":
            return trial.suggest_int(self.name, int(self.low), int(high), step=int(self.step or 1), log=self.log)
        return trial.suggest_float(self.name, self.low, high, step=self.step, log=self.log)

    def contains(self, value: Any, drawn: Mapping[str, Any]) -> bool:
        """Whether ``value`` is a point of this range beside the values ``drawn`` (for enqueueing the defaults)."""
        if self.kind == "categorical":
            return value in self.choices
        assert self.low is not None
        if not self.low <= value <= self.top(drawn):
            return False
        if self.step is not None:
            k = (value - self.low) / self.step
            return abs(k - round(k)) < 1e-9
        return True

    def describe(self) -> str:
        """Human-readable range, e.g. ``[0.5, 60] log``."""
        if self.kind == "categorical":
            return "{" + ", ".join(map(repr, self.choices)) + "}"
        text = f"[{self.low:g}, {self.high:g}]"
        if self.log:
            text += " log"
        if self.step is not None:
            text += f" step {self.step:g}"
        if self.at_most is not None:
            text += f", at most {self.at_most}"
        return text


@dataclass(frozen=True)
class SearchSpace:
    """A localizer's search space (:func:`load_search_space`)."""

    localizer: str
    path: Path
    params: tuple[ParamRange, ...]
    sum_to_one: tuple[tuple[str, ...], ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    def suggest(self, trial: optuna.Trial) -> dict[str, Any]:
        """Draw every parameter: ``{dotted name: raw value}`` (Optuna's ``trial.params``; see :meth:`applied`).

        A capped parameter (``at_most``) is drawn after the one that caps it, which comes earlier in the file.
        """
        drawn: dict[str, Any] = {}
        for p in self.params:
            drawn[p.name] = p.suggest(trial, drawn)
        return drawn

    def contains(self, values: Mapping[str, Any]) -> bool:
        """Whether ``values`` (``{dotted name: value}``, every searched parameter) is a point of the space."""
        return all(p.contains(values[p.name], values) for p in self.params)

    def applied(self, raw: Mapping[str, Any]) -> dict[str, Any]:
        """The values a localizer gets for drawn values ``raw``: each ``sum_to_one`` group divided by its sum.

        A group that already sums to 1 (the defaults) is passed unchanged, bit for bit.

        Raises:
            ConfigError: a group whose raw weights sum to 0.
        """
        out = dict(raw)
        for group in self.sum_to_one:
            total = math.fsum(float(raw[name]) for name in group)
            if not total > 0:
                raise ConfigError(f"{self.path}: sum_to_one group {list(group)} drew weights summing to {total!r}; need > 0")
            if abs(total - 1.0) > _SUM_TOL:
                for name in group:
                    out[name] = float(raw[name]) / total
        return out

    def defaults(self) -> dict[str, Any]:
        """The YAML defaults of the searched parameters: ``{dotted name: value}``."""
        params = load_params(self.localizer)
        out = {}
        for name in self.names:
            value: Any = params
            for part in name.split("."):
                value = getattr(value, part)
            out[name] = value
        return out


def _unwrap_optional(tp: Any) -> Any:
    args = typing.get_args(tp)
    if typing.get_origin(tp) in (typing.Union, types.UnionType) and type(None) in args:
        rest = [a for a in args if a is not type(None)]
        return rest[0] if len(rest) == 1 else tp
    return tp


def _field_type(params_cls: type, name: str, where: str, localizer: str) -> Any:
    """The annotation of dotted parameter ``name`` of ``params_cls``, or a ConfigError naming it."""
    cls: Any = params_cls
    tp: Any = None
    for i, part in enumerate(name.split(".")):
        fields = {f.name for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else set()
        if part not in fields:
            prefix = ".".join(name.split(".")[:i])
            valid = ", ".join(sorted(f"{prefix}.{f}" if prefix else f for f in fields))
            raise ConfigError(
                f"{where}: {name!r} is not a parameter of localizer {localizer!r} ({params_cls.__name__}; valid: {valid})"
            )
        tp = _unwrap_optional(typing.get_type_hints(cls)[part])
        cls = tp
    return tp


def _number(value: Any, integer: bool) -> bool:
    if integer:
        return is_int(value)
    return is_real(value, finite=True)


def _parse_range(name: str, entry: Any, tp: Any, where: str) -> ParamRange:
    """Check one search-space entry against the parameter's type; bounds are checked by the caller."""
    here = f"{where}: {name}"
    if not isinstance(entry, Mapping):
        raise ConfigError(f"{here}: expected a mapping like {{low: 1, high: 10}} or {{choices: [...]}}, got {entry!r}")
    unknown = sorted(set(entry) - set(_SPEC_KEYS))
    if unknown:
        raise ConfigError(f"{here}: unknown key {unknown[0]!r} (valid: {', '.join(_SPEC_KEYS)})")
    if "choices" in entry:
        if set(entry) != {"choices"}:
            raise ConfigError(f"{here}: give either choices or low/high, not both")
        choices = entry["choices"]
        if not isinstance(choices, list) or len(choices) < 2:
            raise ConfigError(f"{here}: choices must be a list of at least 2 values, got {choices!r}")
        for c in choices:
            if c is not None and not isinstance(c, (bool, int, float, str)):
                raise ConfigError(f"{here}: choice {c!r} is not a number, string, bool or null")
        if len(set(map(repr, choices))) != len(choices):
            raise ConfigError(f"{here}: choices {choices!r} repeat a value")
        return ParamRange(name, "categorical", choices=tuple(choices))
    if tp not in (int, float):
        raise ConfigError(f"{here}: a {getattr(tp, '__name__', tp)} parameter needs choices: [...], not low/high")
    at_most = entry.get("at_most")
    if at_most is not None and not isinstance(at_most, str):
        raise ConfigError(f"{here}: at_most must name another searched parameter, got {at_most!r}")
    missing = [k for k in ("low", "high") if k not in entry]
    if missing:
        raise ConfigError(f"{here}: missing {missing[0]!r}")
    integer = tp is int
    kind = "int" if integer else "float"
    for key in ("low", "high", "step"):
        if key in entry and not _number(entry[key], integer):
            raise ConfigError(f"{here}: {key} must be {'an integer' if integer else 'a finite number'}, got {entry[key]!r}")
    low, high = entry["low"], entry["high"]
    if low >= high:
        raise ConfigError(f"{here}: low ({low!r}) must be < high ({high!r})")
    log = entry.get("log", False)
    if not isinstance(log, bool):
        raise ConfigError(f"{here}: log must be true or false, got {log!r}")
    if log and low <= 0:
        raise ConfigError(f"{here}: a log range needs low > 0, got {low!r}")
    step = entry.get("step")
    if step is not None:
        if step <= 0:
            raise ConfigError(f"{here}: step must be > 0, got {step!r}")
        if log:
            raise ConfigError(f"{here}: step and log cannot be combined")
    return ParamRange(name, kind, float(low) if not integer else low, float(high) if not integer else high, log,
                      None if step is None else (step if integer else float(step)), at_most=at_most)  # fmt: skip


def space_path(localizer: str) -> Path:
    """``configs/tuning/<localizer>.yaml``."""
    return TUNING_CONFIG_DIR / f"{localizer}.yaml"


def tunable_localizers() -> tuple[str, ...]:
    """The registered localizers with a shipped search space, in registry order."""
    return tuple(name for name in LOCALIZERS if space_path(name).is_file())


def _parse_groups(p: Path, value: Any, ranges: Mapping[str, ParamRange]) -> tuple[tuple[str, ...], ...]:
    """Check the ``sum_to_one`` groups: lists of >= 2 searched float parameters, none in two groups."""
    if not isinstance(value, list):
        raise ConfigError(f"{p}: sum_to_one must be a list of parameter-name lists, got {value!r}")
    groups, seen = [], set()
    for group in value:
        if not isinstance(group, list) or len(group) < 2 or not all(isinstance(n, str) for n in group):
            raise ConfigError(f"{p}: each sum_to_one group must list at least 2 parameter names, got {group!r}")
        for name in group:
            r = ranges.get(name)
            if r is None:
                raise ConfigError(f"{p}: sum_to_one names {name!r}, which is not searched under parameters")
            if r.kind != "float" or r.low is None or r.low < 0:
                raise ConfigError(f"{p}: sum_to_one member {name!r} must be a float range with low >= 0, got {r.describe()}")
            if name in seen:
                raise ConfigError(f"{p}: {name!r} is in two sum_to_one groups")
            seen.add(name)
        groups.append(tuple(group))
    return tuple(groups)


def _check_caps(p: Path, ranges: list[ParamRange]) -> None:
    """Each ``at_most`` names a numeric parameter searched earlier in the file, of the same kind,
    whose lowest value is above this range's ``low`` (so the capped range is never empty)."""
    earlier: dict[str, ParamRange] = {}
    for r in ranges:
        cap = earlier.get(r.at_most) if r.at_most is not None else None
        if r.at_most is not None:
            if cap is None:
                raise ConfigError(f"{p}: {r.name}: at_most {r.at_most!r} must name a parameter searched before it in the file")
            assert cap.low is not None and r.low is not None
            if cap.kind != r.kind or cap.low <= r.low:
                raise ConfigError(f"{p}: {r.name}: at_most {r.at_most!r} must be a {r.kind} range whose low is above "
                                  f"{r.name}'s low {r.low!r}, got {cap.describe()}")  # fmt: skip
        earlier[r.name] = r


def _check_bounds(localizer: str, p: Path, space: SearchSpace) -> None:
    """Every bound and choice is a valid value of its parameter, the others at their defaults
    (a ``sum_to_one`` member with the rest of its group at their defaults, the group normalized)."""
    defaults = space.defaults()
    grouped = {name: g for g in space.sum_to_one for name in g}
    for r in space.params:
        points = r.choices if r.kind == "categorical" else (r.low, r.top(defaults))
        for value in points:
            group = grouped.get(r.name, (r.name,))
            raw = {**{n: defaults[n] for n in group}, r.name: value}
            # a parameter capped by this one, at its default clipped to the cap
            raw |= {c.name: min(defaults[c.name], value) for c in space.params if c.at_most == r.name}
            try:
                applied = space.applied(raw) if len(group) > 1 else raw
                load_params(localizer, nest(applied))
            except ConfigError as exc:
                raise ConfigError(f"{p}: {r.name} = {value!r} is not a valid value: {exc}") from None


def load_search_space(localizer: str, path: str | Path | None = None) -> SearchSpace:
    """Read and check a localizer's search space.

    The file's top level is ``parameters:``, a mapping of parameter name (dotted for nested
    parameters) to ``{low, high, log?, step?}`` or ``{choices: [...]}``, and optionally
    ``sum_to_one:``, a list of groups (lists of searched float parameters) normalized to sum 1
    before they are applied. Integer parameters need integer bounds. Every bound and choice
    must itself be a valid value of the parameter (checked by building the localizer's
    parameters with it).

    Args:
        localizer: a registered localizer name.
        path: the YAML file (default ``configs/tuning/<localizer>.yaml``).

    Raises:
        ConfigError: one line naming the localizer, file, parameter or bound at fault.
    """
    s = spec(localizer)
    p = Path(path) if path is not None else space_path(localizer)
    if path is None and not p.is_file():
        if localizer in UNTUNED:
            raise ConfigError(f"localizer {localizer!r} is not tunable: {UNTUNED[localizer]} (tunable: "
                              f"{', '.join(tunable_localizers())})")  # fmt: skip
        raise ConfigError(f"no search space for localizer {localizer!r}: write {p} (see configs/tuning/candidate_sets.yaml)")
    data = load_yaml(p)
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise ConfigError(f"{p}: unknown top-level key {unknown[0]!r} (valid: {', '.join(_TOP_KEYS)})")
    entries = data.get("parameters")
    if not isinstance(entries, Mapping) or not entries:
        raise ConfigError(f"{p}: 'parameters' must be a non-empty mapping of parameter name to range")
    params_cls = getattr(importlib.import_module(s.module), s.params_cls)
    ranges = []
    for name, entry in entries.items():
        if not isinstance(name, str):
            raise ConfigError(f"{p}: parameter names must be strings, got {name!r}")
        ranges.append(_parse_range(name, entry, _field_type(params_cls, name, str(p), localizer), str(p)))
    _check_caps(p, ranges)
    groups = _parse_groups(p, data["sum_to_one"], {r.name: r for r in ranges}) if "sum_to_one" in data else ()
    space = SearchSpace(localizer, p, tuple(ranges), groups)
    _check_bounds(localizer, p, space)
    return space
