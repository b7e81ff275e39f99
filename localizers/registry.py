"""Localizers by name: ``make_localizer("candidate_sets", landmark_map, dt_s=..., params={...})``.

Each localizer's parameters live in ``configs/localizers/<name>.yaml`` (the papers' values as
defaults, each with its unit and source) and can be overridden key by key; an unknown key or
a bad value is a :class:`~core.schema.ConfigError` naming it.
"""

from __future__ import annotations

import dataclasses
import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import crowdloc_configs
from core.schema import ConfigError, from_mapping, load_yaml, merge_nested
from localizers.base import LandmarkMap, Localizer

LOCALIZER_CONFIG_DIR = crowdloc_configs.path("localizers")  # package data (configs/ in the checkout)


@dataclass(frozen=True)
class LocalizerSpec:
    """Where a localizer lives and what it consumes.

    Attributes:
        module, cls, params_cls: where its class and its parameters' class live.
        measurement: a registered measurement kind (:mod:`localizers.measurements`): "bearings", "scan", ...
        needs_prior: needs the start pose (dead reckoning and the Kalman filter of the paper).
        summary: one line for listings.
        covariance: whether ``PoseEstimate.covariance`` is the localizer's own measure of its
            uncertainty (a filter's covariance, a particle or candidate set's sample covariance,
            however heuristic), so that ``crowdloc eval`` scores its consistency (NEES); false for
            one that reports none (NaN) or a placeholder: its tables say "no covariance".
        prepare: for a localizer that needs data made from its world (a map from a drive) or
            parameters fitted to it, a function ``"module:name"`` that the env wrapper calls as
            ``prepare(env, sensor, params)`` before building it, and that returns the parameters
            to build it with (``far_landmark_pf``: the world's default scene map, made on first
            use; ``mcl_lidar``: the likelihood field in a world too large for the beam model's
            table). Named, not imported. A hook that needs code above this package (driving a
            world to map it) is given by that code, with :func:`set_prepare` (``import agents``
            gives ``far_landmark_pf`` its scene-map hook).
        fallback: a measurement kind it reads instead in a world without a sensor of
            ``measurement``'s kind (dead reckoning, which uses odometry only and merely validates
            the bearings it is given: ``"odometry"``, so that it runs in every world);
            :func:`measurement_in` resolves it.
    """

    module: str
    cls: str
    params_cls: str
    measurement: str
    needs_prior: bool
    summary: str
    covariance: bool = True
    prepare: str = ""
    fallback: str = ""


LOCALIZERS: dict[str, LocalizerSpec] = {
    "dead_reckoning": LocalizerSpec(
        "localizers.dead_reckoning",
        "DeadReckoningLocalizer",
        "DeadReckoningParams",
        "bearings",
        True,
        "odometry only, from the known start pose (paper A, baseline 1)",
        fallback="odometry",
    ),
    "resection": LocalizerSpec(
        "localizers.resection",
        "ResectionLocalizer",
        "ResectionParams",
        "bearings",
        False,
        "Cassini three-landmark resection whenever >= 3 bearings are seen (paper A, baseline 2)",
    ),
    "kalman": LocalizerSpec(
        "localizers.kalman",
        "KalmanLocalizer",
        "KalmanParams",
        "bearings",
        True,
        "constant-acceleration Kalman filter fusing dead reckoning and resection (paper A, baseline 3)",
    ),
    "mcl_bearing_paper": LocalizerSpec(
        "localizers.mcl",
        "PaperBearingMCL",
        "PaperMCLParams",
        "bearings",
        False,
        "the paper's 1000-particle MCL with deletion and re-seeding (paper A, baseline 4)",
    ),
    "mcl_bearing": LocalizerSpec(
        "localizers.mcl",
        "BearingMCL",
        "BearingMCLParams",
        "bearings",
        False,
        "reference MCL: Gaussian bearing likelihood, low-variance resampling, augmented-MCL recovery",
    ),
    "candidate_sets": LocalizerSpec(
        "localizers.candidate_sets",
        "CandidateSetLocalizer",
        "CandidateSetParams",
        "bearings",
        False,
        "the proposed two-landmark candidate-set method with K independent sets (paper A)",
    ),
    "mcl_lidar": LocalizerSpec(
        "localizers.mcl_lidar",
        "LidarMCL",
        "LidarMCLParams",
        "scan",
        True,
        "LIDAR MCL on the raw scan: beam model on a ray-cast table, alphas scaled by the sampling parameter (paper B's MCL)",
        prepare="localizers.mcl_lidar:large_map_params",
    ),
    "far_point_mcl": LocalizerSpec(
        "localizers.scan_filter",
        "FarPointMCL",
        "FarPointMCLParams",
        "scan",
        True,
        "LIDAR MCL on scans accumulated over 0.5 m of travel, far point per angular bin (paper B's method)",
        prepare="localizers.scan_filter:large_map_params",
    ),
    "ceiling_target": LocalizerSpec(
        "localizers.ceiling_target",
        "CeilingTargetLocalizer",
        "CeilingTargetParams",
        "ceiling_image",
        False,
        "ceiling colour targets through the paper's HSV pipeline, dead reckoning between them (paper C's method)",
    ),
    "far_landmark_pf": LocalizerSpec(
        "localizers.far_landmark_pf",
        "FarLandmarkPF",
        "FarLandmarkParams",
        "stereo_edges",
        True,
        "500-particle filter on stereo edges, the farthest matching one per 30 deg sector, a map of scenes (paper D's method)",
    ),
}


#: the localizers crowdloc ships (plug-ins registered later are not among them)
BUILTIN_LOCALIZERS: tuple[str, ...] = tuple(LOCALIZERS)


def register_localizer(name: str, entry: LocalizerSpec) -> LocalizerSpec:
    """Add a localizer to the registry (a plug-in: its module, classes and measurement kind).

    Its parameters are read from ``configs/localizers/<name>.yaml`` when that file exists,
    else the params class's defaults apply.

    Raises:
        ConfigError: if ``name`` is taken by another entry or the measurement kind is unknown.
    """
    from localizers.measurements import measurement_kind

    measurement_kind(entry.measurement)  # raises, naming the registered kinds
    current = LOCALIZERS.get(name)
    if current is not None and current != entry:
        raise ConfigError(f"localizer {name!r} is already registered ({current.module}.{current.cls})")
    LOCALIZERS[name] = entry
    return entry


def set_prepare(name: str, hook: str) -> None:
    """Give the registered localizer ``name`` its preparation hook, ``"module:function"``
    (:attr:`LocalizerSpec.prepare`): the package that holds the hook registers it.

    Raises:
        ConfigError: if ``name`` is not registered or ``hook`` is not of the form ``module:function``.
    """
    module, sep, function = hook.partition(":")
    if not (sep and module and function):
        raise ConfigError(f"prepare hook for {name!r} must be 'module:function', got {hook!r}")
    LOCALIZERS[name] = dataclasses.replace(spec(name), prepare=hook)


def spec(name: str) -> LocalizerSpec:
    """The registry entry of ``name``, or a ConfigError listing the known names."""
    try:
        return LOCALIZERS[name]
    except KeyError:
        raise ConfigError(f"unknown localizer {name!r}; known localizers: {', '.join(sorted(LOCALIZERS))}") from None


def measurement_in(name: str, sensors: Mapping[str, Mapping[str, Any]]) -> str:
    """The measurement kind localizer ``name`` reads in a world with these ``sensors`` (name ->
    metadata with a ``type``): its own, or its :attr:`LocalizerSpec.fallback` where the world has
    no sensor of its own kind."""
    from localizers.measurements import measurement_kind

    s = spec(name)
    if s.fallback:
        own = measurement_kind(s.measurement).sensor_type
        if not any(meta.get("type") == own for meta in sensors.values()):
            return s.fallback
    return s.measurement


def _attr(module: str, name: str) -> Any:
    return getattr(importlib.import_module(module), name)


def params_path(name: str) -> Path:
    return LOCALIZER_CONFIG_DIR / f"{name}.yaml"


def load_params(name: str, overrides: Mapping[str, Any] | None = None) -> Any:
    """The parameters of localizer ``name``: its YAML defaults with ``overrides`` applied."""
    s = spec(name)
    path = params_path(name)
    data = load_yaml(path) if path.is_file() else {}
    where = str(path)
    check_overrides(name, overrides)
    if overrides:
        data = merge_nested(data, overrides)
        where = f"{path} with localizer_params {dict(overrides)!r}"
    return from_mapping(_attr(s.module, s.params_cls), data, where=where)


def check_overrides(name: str, overrides: Any, *, ready: bool = False) -> None:
    """Raise a ConfigError unless ``overrides`` (localizer ``name``'s ``localizer_params``) is None
    or a mapping (with ``ready``, or a ready params object of the localizer)."""
    if overrides is None or isinstance(overrides, Mapping):
        return
    if ready and isinstance(overrides, _attr(spec(name).module, spec(name).params_cls)):
        return
    raise ConfigError(f"localizer_params for {name!r} must be a mapping, got {type(overrides).__name__} {overrides!r}")


def prepared_params(name: str, env: Any, sensor: str, params: Mapping[str, Any] | None) -> Mapping[str, Any] | None:
    """``params`` after the localizer's preparation hook (:attr:`LocalizerSpec.prepare`), if it has one."""
    check_overrides(name, params, ready=True)
    hook = spec(name).prepare
    if not hook:
        return params
    module, _, function = hook.partition(":")
    prepared: Mapping[str, Any] = _attr(module, function)(env, sensor, params)
    return prepared


def make_localizer(name: str, landmarks: LandmarkMap, *, dt_s: float, params: Mapping[str, Any] | Any | None = None) -> Localizer:
    """Build localizer ``name``; ``params`` is a mapping of overrides or a ready params object."""
    s = spec(name)
    params_cls = _attr(s.module, s.params_cls)
    p = params if isinstance(params, params_cls) else load_params(name, params)
    localizer: Localizer = _attr(s.module, s.cls)(landmarks, p, dt_s=dt_s)
    return localizer
