"""The metric plug-in of the ``bearings`` kind: the landmark search and the posterior Cramer-Rao bound.

Per episode, for localizers that consume identified landmark bearings:

- ``third_landmark_s``: time since reset until bearings of three distinct landmarks have been
  in view (not necessarily at once): the search, the policy's part of the first fix (NaN if
  it never happened); ``fix_after_third_s``: ``first_fix_s`` minus it, the localizer's part
  (negative when a fix came from two landmarks and motion);
- ``bound_rmse_m``: RMS over the same steps as the errors of the posterior Cramer-Rao bound on
  position RMSE along the true path (the truly visible landmarks of each step from
  ``info["visible_landmarks"]``, the bearing camera's noise and the odometry sensor's alphas
  from their metadata; prior: the known start pose for localizers that get it, else one as
  vague as the field);
- ``error_bound_ratio``: RMS position error over that RMS bound
  (:func:`agents.evaluate.metrics.error_bound_ratio`; >= 1 for an unbiased estimator in expectation).

Per step it keeps ``visible`` ``(T, L)`` and computes ``bound_rmse_m`` ``(T,)`` (``Episode.series``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import agents.evaluate.metrics as metrics
from agents.evaluate.plugins import EpisodeContext, MetricInfo, MetricPlugin, PluginOutput, Track, register_metrics
from agents.experiments.replay import bound_rmse_along
from localizers.measurements import find_sensor


def bearing_metrics(track: Track, visible: ArrayLike, bound_rmse_m: ArrayLike) -> dict[str, float]:
    """The plug-in's values of one episode (see the module docstring).

    Args:
        track: the core arrays; visible: ``(T, L)`` landmarks in the camera's sight;
        bound_rmse_m: ``(T,)`` the bound along the true path.
    """
    t0, pos = track.fix_index, track.position_errors
    t3 = metrics.distinct_seen(visible, 3)
    third_s = float(track.time_s[t3] - track.time_s[0]) if t3 is not None else math.nan
    return {
        "third_landmark_s": third_s,
        "fix_after_third_s": track.first_fix_s - third_s,
        "bound_rmse_m": metrics.rms(bound_rmse_m, t0, np.isfinite(pos)),
        "error_bound_ratio": metrics.error_bound_ratio(pos, bound_rmse_m, t0),
    }


def _collect(info: Mapping[str, Any], context: EpisodeContext) -> dict[str, NDArray[np.bool_]]:
    return {"visible": np.array(info["visible_landmarks"], dtype=bool)}


def _compute(track: Track, collected: Mapping[str, NDArray[Any]], context: EpisodeContext) -> PluginOutput:
    camera = context.sensors[find_sensor("bearings", context.sensors, "the bearing metrics")]
    lmap = context.landmark_map
    bound = bound_rmse_along(
        track.true_pose,
        track.odometry,
        collected["visible"],
        lmap.positions_xy_m,
        float(camera["noise_std_rad"]),
        tuple(context.sensor_of_type("odometry")["alphas"]),
        known_start=context.known_start,
        bounds_m=lmap.bounds_m,
    )
    return bearing_metrics(track, collected["visible"], bound), {"bound_rmse_m": bound}


BEARING_METRICS = register_metrics(
    "bearings",
    MetricPlugin(
        "search_and_bound",
        (
            MetricInfo("third_landmark_s", "third landmark seen [s]", "{:.2f}", in_table=False, after="first_fix_distance_m"),
            MetricInfo(
                "fix_after_third_s", "first fix after the third landmark [s]", "{:.2f}", in_table=False, after="third_landmark_s"
            ),  # fmt: skip
            MetricInfo("bound_rmse_m", "bound RMSE [m]", "{:.3f}", in_table=False, after="episode_return"),
            MetricInfo("error_bound_ratio", "error / bound", "{:.2f}", after="bound_rmse_m"),
        ),
        _collect,
        _compute,
        note="error / bound (bearing localizers): RMS position error over the RMS posterior Cramer-Rao bound along "
        "the true path, over the same steps (>= 1 for an unbiased estimator).",
    ),
)
