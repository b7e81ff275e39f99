"""Metric rows, the core arrays every metric may use, and metric plug-ins by measurement kind.

The core metrics (:data:`CORE_METRICS`, computed by :func:`agents.evaluate.episode.episode_metrics`)
apply to every localizer. Metrics that only make sense for one measurement kind come from a
:class:`MetricPlugin` registered for that kind with :func:`register_metrics`; an episode gets
the plug-ins of its localizer's kind (``localizers.registry.spec(name).measurement``) and
nothing else, so a kind without a plug-in simply has no such values (NaN in the tables).

A plug-in declares

- ``metrics``: its :class:`MetricInfo` rows (``after`` places a row right after a core row or
  an earlier row of the same plug-in in the tables; without it the row goes at the end);
- ``collect(info, context)``: what it keeps from each step's ``info`` (the reset's too), a
  mapping name -> value; the values of each name are stacked into a ``(T, ...)`` array;
- ``compute(track, collected, context)``: its per-episode values (exactly its metric keys)
  and any further per-step arrays (e.g. a bound), from the core :class:`Track`, its
  collected arrays and the :class:`EpisodeContext`.

The collected and computed arrays end up in ``Episode.series``. Register a plug-in when a
module is imported that the evaluation's worker processes import too (with ``workers > 1`` or
Ray a plug-in registered only in the calling process computes nothing there).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

import agents.evaluate.metrics as metrics
from localizers.base import LandmarkMap
from localizers.measurements import measurement_kind

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MetricInfo:
    """How a per-episode metric is labelled and printed.

    Attributes:
        after: the row it follows in the tables.
        covariance: the metric measures the reported covariance; the tables say "no covariance"
            for a localizer that reports none (``LocalizerSpec.covariance`` false).
    """

    key: str
    label: str
    fmt: str
    in_table: bool = True
    after: str | None = None
    covariance: bool = False


#: the metrics of every localizer, in table order (plug-in rows are placed among them)
CORE_METRICS: tuple[MetricInfo, ...] = (
    MetricInfo("position_error_mean_m", "pos. error mean [m]", "{:.3f}"),
    MetricInfo("position_error_rms_m", "pos. error RMS [m]", "{:.3f}"),
    MetricInfo("heading_error_mean_deg", "heading error mean [deg]", "{:.2f}"),
    MetricInfo("heading_error_rms_deg", "heading error RMS [deg]", "{:.2f}"),
    # no NEES mean: one step with a singular covariance (a collapsed particle set) makes it inf. The share of
    # such steps takes the mean's old place among the consistency rows, which keeps every other row's bootstrap
    # stream (agents.evaluate.stats.summarize) and so its interval as it was
    MetricInfo("singular_share", "singular covariance (share of steps)", "{:.3f}", covariance=True),
    MetricInfo("nees_median", "NEES median (consistent: 2.37)", "{:.2f}", covariance=True),
    MetricInfo("inside_95", "inside 95% region (consistent: 0.95)", "{:.3f}", covariance=True),
    MetricInfo("covariance_missing", "valid steps without a usable covariance", "{:.3f}", in_table=False, covariance=True),
    MetricInfo("failure_rate", "failure rate (>= 1 m)", "{:.3f}"),
    MetricInfo("availability", "availability", "{:.3f}"),
    MetricInfo("fixed", "share of episodes with a fix", "{:.2f}", in_table=False),
    MetricInfo("first_fix_s", "first fix [s]", "{:.2f}"),
    MetricInfo("first_fix_distance_m", "first fix [m travelled]", "{:.2f}"),
    MetricInfo("collisions", "collisions", "{:.1f}"),
    MetricInfo("episode_return", "episode return", "{:.1f}"),
)


@dataclass(frozen=True)
class Track:
    """The core per-step arrays of one episode, ``T = steps + 1`` rows (row 0 is the reset).

    Attributes:
        time_s: ``(T,)`` simulated time.
        true_pose: ``(T, 3)`` ground truth.
        estimates: ``(T, 3)`` the localizer's poses, NaN rows where it had none.
        valid: ``(T,)`` whether it had one.
        contacts: ``(T,)`` contact events of our robot that began in each step.
        odometry: ``(T - 1, 3)`` odometry increments of steps 1..T-1.
        rewards: ``(T - 1,)`` active-localization rewards.
        covariances: ``(T, 3, 3)`` the covariances the localizer reported with its poses, NaN
            where it had none (default: NaN throughout, no covariance reported).
    """

    time_s: Array
    true_pose: Array
    estimates: Array
    valid: NDArray[np.bool_]
    contacts: NDArray[np.int64]
    odometry: Array
    rewards: Array
    covariances: Array | None = None

    def __post_init__(self) -> None:  # lists from Python callers become arrays of the documented types
        for name, dtype in (("time_s", np.float64), ("true_pose", np.float64), ("estimates", np.float64),
                            ("valid", np.bool_), ("contacts", np.int64), ("rewards", np.float64)):  # fmt: skip
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=dtype))
        object.__setattr__(self, "odometry", np.asarray(self.odometry, dtype=np.float64).reshape(-1, 3))
        steps = self.time_s.shape[0]
        cov = np.full((steps, 3, 3), np.nan) if self.covariances is None else np.asarray(self.covariances, dtype=np.float64)
        if cov.shape != (steps, 3, 3):
            raise ValueError(f"Track.covariances must have shape ({steps}, 3, 3), one per step, got {cov.shape}")
        object.__setattr__(self, "covariances", cov)

    @functools.cached_property
    def fix_index(self) -> int | None:
        """``t0``: the first step with a valid estimate (the first fix), None if there was none."""
        return metrics.first_fix(self.valid)

    @functools.cached_property
    def first_fix_s(self) -> float:
        """Time from the reset to the first fix (NaN without one)."""
        t0 = self.fix_index
        return float(self.time_s[t0] - self.time_s[0]) if t0 is not None else math.nan

    @functools.cached_property
    def position_errors(self) -> Array:
        """``(T,)`` position errors, NaN where the estimate is not valid."""
        est = np.where(self.valid[:, None], self.estimates, np.nan)
        return metrics.position_errors(est, self.true_pose)

    @functools.cached_property
    def heading_errors_deg(self) -> Array:
        """``(T,)`` heading errors in degrees, NaN where the estimate is not valid."""
        est = np.where(self.valid[:, None], self.estimates, np.nan)
        return np.degrees(metrics.heading_errors(est, self.true_pose))

    @functools.cached_property
    def nees(self) -> Array:
        """``(T,)`` NEES of the pose (3 dof) against the reported covariance; NaN where the
        estimate is not valid or its covariance not usable (:func:`agents.evaluate.metrics.pose_nees`)."""
        est = np.where(self.valid[:, None], self.estimates, np.nan)
        assert self.covariances is not None  # set in __post_init__
        return metrics.pose_nees(est, self.true_pose, self.covariances)

    @functools.cached_property
    def position_spreads_m(self) -> Array:
        """``(T,)`` reported position spread, sqrt of the trace of the position covariance (NaN where not valid)."""
        cov = self.covariances
        assert cov is not None  # set in __post_init__
        spread = np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1], 0.0))  # NaN stays NaN
        return np.where(self.valid, spread, np.nan)


@dataclass(frozen=True)
class EpisodeContext:
    """What a plug-in knows of an episode's env, read once after the reset (plain values).

    Attributes:
        sensors: sensor name -> its metadata (``type``, ``key``, ...; ``LocalizationEnv.sensor_metadata``).
        landmark_map: the map the localizer gets.
        dt_s: the time step.
        known_start: whether the localizer gets the true start pose.
    """

    sensors: Mapping[str, Mapping[str, Any]]
    landmark_map: LandmarkMap
    dt_s: float
    known_start: bool

    def sensor_of_type(self, type_name: str) -> Mapping[str, Any]:
        """The metadata of the one sensor of ``type_name`` (a ValueError if there is none or several)."""
        found = [meta for meta in self.sensors.values() if meta.get("type") == type_name]
        if len(found) != 1:
            raise ValueError(f"expected one {type_name} sensor, found {len(found)} among {sorted(self.sensors)}")
        return found[0]


#: ``(values, arrays)`` of one plug-in for one episode
PluginOutput = tuple[Mapping[str, float], Mapping[str, NDArray[Any]]]


@dataclass(frozen=True)
class MetricPlugin:
    """Metrics for the localizers of one measurement kind (see the module docstring).

    Attributes:
        name: names the plug-in within its kind.
        metrics: its rows; keys unique among all registered metrics.
        collect: ``collect(info, context) -> {name: value}`` per step (reset included).
        compute: ``compute(track, collected, context) -> (values, arrays)``.
        note: one sentence for the summary page's legend (what its metrics mean).
    """

    name: str
    metrics: tuple[MetricInfo, ...]
    collect: Callable[[Mapping[str, Any], EpisodeContext], Mapping[str, Any]]
    compute: Callable[[Track, Mapping[str, NDArray[Any]], EpisodeContext], PluginOutput]
    note: str = ""

    @property
    def keys(self) -> tuple[str, ...]:
        return tuple(m.key for m in self.metrics)


_PLUGINS: dict[str, dict[str, MetricPlugin]] = {}  # measurement kind -> plug-in name -> plug-in


def register_metrics(kind: str, plugin: MetricPlugin) -> MetricPlugin:
    """Register ``plugin`` for the localizers of measurement kind ``kind`` (again the same: fine).

    Raises:
        ConfigError: for an unknown measurement kind.
        ValueError: if the name is taken within the kind by another plug-in, a metric key is
            a core key or another plug-in's with another row, or an ``after`` names neither a
            core row nor an earlier row of the plug-in.
    """
    measurement_kind(kind)  # raises, naming the registered kinds
    current = _PLUGINS.get(kind, {}).get(plugin.name)
    if current is not None:
        if current != plugin:
            raise ValueError(f"metric plug-in {plugin.name!r} is already registered for {kind!r}")
        return plugin
    core = {m.key for m in CORE_METRICS}
    others = {m.key: m for p in all_plugins() for m in p.metrics}
    anchors = set(core)
    for row in plugin.metrics:
        if row.key in core or others.get(row.key, row) != row:
            raise ValueError(f"metric plug-in {plugin.name!r}: metric key {row.key!r} is taken")
        if row.after is not None and row.after not in anchors:
            raise ValueError(
                f"metric plug-in {plugin.name!r}: {row.key!r} after {row.after!r}, neither a core nor an earlier row"
            )
        anchors.add(row.key)
    if len(set(plugin.keys)) != len(plugin.keys):
        raise ValueError(f"metric plug-in {plugin.name!r}: metric keys repeat: {list(plugin.keys)}")
    _PLUGINS.setdefault(kind, {})[plugin.name] = plugin
    return plugin


def unregister_metrics(kind: str, name: str) -> None:
    """Remove a registered plug-in (tests; a missing one is fine)."""
    _PLUGINS.get(kind, {}).pop(name, None)


def metric_plugins(kind: str) -> tuple[MetricPlugin, ...]:
    """The plug-ins of measurement kind ``kind``, in registration order (none: ``()``)."""
    return tuple(_PLUGINS.get(kind, {}).values())


def all_plugins() -> tuple[MetricPlugin, ...]:
    """Every registered plug-in, kind by kind in registration order."""
    return tuple(p for by_name in _PLUGINS.values() for p in by_name.values())


def plugins_for(kinds: Iterable[str] | None = None) -> tuple[MetricPlugin, ...]:
    """The plug-ins of ``kinds`` (default: every registered kind), kind by kind."""
    return all_plugins() if kinds is None else tuple(p for k in dict.fromkeys(kinds) for p in metric_plugins(k))


def localizer_kind(localizer: str, sensors: Mapping[str, Mapping[str, Any]] | None = None) -> str:
    """The measurement kind a registered localizer consumes (in a world with these ``sensors``:
    its fallback where it has none of its own, ``localizers.registry.measurement_in``)."""
    from localizers.registry import measurement_in, spec

    return spec(localizer).measurement if sensors is None else measurement_in(localizer, sensors)


def metric_infos(kinds: Iterable[str] | None = None) -> tuple[MetricInfo, ...]:
    """The core rows and those of the plug-ins of ``kinds`` (default: every registered kind), in table order."""
    plugins = plugins_for(kinds)
    order = list(CORE_METRICS)
    placed: set[str] = set()
    for row in (m for p in plugins for m in p.metrics):
        if row.key in placed:  # a row two kinds share
            continue
        keys = [m.key for m in order]
        if row.after is None or row.after not in keys:
            order.append(row)
        else:
            i = keys.index(row.after) + 1
            while i < len(order) and order[i].key in placed:  # after plug-in rows placed there before
                i += 1
            order.insert(i, row)
        placed.add(row.key)
    return tuple(order)


def localizer_metrics(localizers: Iterable[str]) -> tuple[MetricInfo, ...]:
    """The metric rows of a grid of these localizers: the core ones and their kinds' plug-ins'."""
    return metric_infos(localizer_kind(name) for name in localizers)
