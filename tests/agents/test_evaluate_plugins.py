"""``crowdloc eval`` on any world: core metrics for every localizer, metric plug-ins by measurement kind."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from agents.evaluate import (
    CORE_METRICS,
    METRIC_KEYS,
    EpisodeContext,
    EvalSpec,
    MetricInfo,
    MetricPlugin,
    PluginOutput,
    Track,
    evaluate,
    metric_infos,
    register_metrics,
    summary_markdown,
    unregister_metrics,
    write_tables,
)
from core.schema import ConfigError
from envs.config import world_path

CORE_KEYS = [m.key for m in CORE_METRICS]
BEARING_ONLY = ("third_landmark_s", "fix_after_third_s", "bound_rmse_m", "error_bound_ratio")


def test_a_scan_localizer_on_the_crowded_room_has_the_core_metrics_only(tmp_path: Path) -> None:
    spec = EvalSpec(env_id="crowdloc/CrowdedRoom-v0", policies=("random_walk", "patrol"), localizers=("far_point_mcl",),
                    crowd_sizes=(8,), seeds=1, episode_steps=40)  # fmt: skip
    assert spec.world().name == "crowded_room" and spec.world().crowd.count == 16
    assert [m.key for m in spec.metrics] == CORE_KEYS
    result = evaluate(spec, workers=1, progress=False)
    for episode in result.episodes:
        assert list(episode.metrics) == CORE_KEYS and episode.series == {}
        assert episode.true_pose.shape == (41, 3) and episode.odometry.shape == (40, 3)
        assert episode.metrics["fixed"] == 1.0 and episode.metrics["availability"] == 1.0  # it gets the start pose
        assert np.isfinite(episode.metrics["position_error_rms_m"]) and episode.metrics["position_error_rms_m"] < 1.0
        with pytest.raises(AttributeError, match="no attribute or series 'visible'"):
            _ = episode.visible
    table = summary_markdown(result)
    assert "| random_walk | far_point_mcl | 8 |" in table and "error / bound" not in table
    write_tables(result, tmp_path)
    with open(tmp_path / "episodes.csv") as f:
        assert list(csv.DictReader(f))[0].keys() == {"policy", "localizer", "crowd_size", "seed", "steps", *CORE_KEYS}


def test_a_grid_of_both_kinds_has_nan_where_a_kind_has_no_such_metric(tmp_path: Path) -> None:
    spec = EvalSpec(policies=("spin",), localizers=("candidate_sets", "mcl_lidar"), crowd_sizes=(2,), seeds=1,
                    episode_steps=15, env_kwargs={"lidar": {"beams": 90}})  # fmt: skip
    assert [m.key for m in spec.metrics] == list(METRIC_KEYS)  # the bearings plug-in's rows among the core ones
    result = evaluate(spec, workers=1, progress=False)
    bearing, scan = result.episodes
    assert bearing.visible.shape == (16, 8) and bearing.bound_rmse_m.shape == (16,)
    assert all(np.isfinite(bearing.metrics[k]) for k in ("third_landmark_s", "bound_rmse_m", "error_bound_ratio"))
    assert not set(BEARING_ONLY) & set(scan.metrics)
    write_tables(result, tmp_path)
    with open(tmp_path / "episodes.csv") as f:
        rows = {r["localizer"]: r for r in csv.DictReader(f)}
    assert all(math.isnan(float(rows["mcl_lidar"][k])) for k in BEARING_ONLY)
    assert all(math.isfinite(float(rows["mcl_lidar"][k])) for k in ("position_error_mean_m", "availability"))
    with open(tmp_path / "summary.csv") as f:
        summary = {r["localizer"]: r for r in csv.DictReader(f)}
    assert summary["mcl_lidar"]["error_bound_ratio_n"] == "0" and summary["candidate_sets"]["error_bound_ratio_n"] == "1"
    assert "| spin | mcl_lidar | 2 |" in summary_markdown(result) and summary_markdown(result).endswith("| – |")


def test_a_world_yaml_in_env_kwargs_replaces_the_id_s_world(tmp_path: Path) -> None:
    room = str(world_path("crowded_room"))
    spec = EvalSpec(policies=("spin",), localizers=("mcl_lidar",), crowd_sizes=(20,), seeds=1, episode_steps=5,
                    env_kwargs={"world": room})  # fmt: skip
    assert spec.world().name == "crowded_room" and spec.world().crowd.max_count == 30  # not the RoboCup world's 14
    with pytest.raises(ConfigError, match=r"crowd size 31 out of range 0\.\.30 for world 'crowded_room'"):
        EvalSpec(policies=("spin",), localizers=("mcl_lidar",), crowd_sizes=(31,), env_kwargs={"world": room})
    (episode,) = evaluate(spec, workers=1, progress=False).episodes
    assert episode.true_pose.shape == (6, 3) and 0.0 < episode.time_s[-1] < 0.2  # the room's 40 Hz, not 30 Hz
    with pytest.raises(ConfigError, match="does not exist"):
        EvalSpec(policies=("spin",), env_kwargs={"world": str(tmp_path / "missing.yaml")})


def _travelled_collect(info: Mapping[str, Any], context: EpisodeContext) -> dict[str, Any]:
    return {"x_m": float(info["true_pose"][0]), "beams": len(context.sensors["lidar"]["beam_angles_rad"])}


def _travelled_compute(track: Track, collected: Mapping[str, Any], context: EpisodeContext) -> PluginOutput:
    span = float(np.ptp(collected["x_m"]))
    return {"x_span_m": span, "beam_count": float(collected["beams"][0])}, {"x_offset_m": collected["x_m"] - collected["x_m"][0]}


@pytest.fixture
def scan_plugin() -> Iterator[MetricPlugin]:
    plugin = MetricPlugin(
        "test_span",
        (MetricInfo("x_span_m", "x span [m]", "{:.3f}", after="first_fix_s"), MetricInfo("beam_count", "beams", "{:.0f}")),
        _travelled_collect,
        _travelled_compute,
        note="x span: how far the robot got along x.",
    )
    register_metrics("scan", plugin)
    yield plugin
    unregister_metrics("scan", "test_span")


def test_a_plugin_registered_for_a_kind_shows_its_metrics(scan_plugin: MetricPlugin, tmp_path: Path) -> None:
    keys = [m.key for m in metric_infos(["scan"])]
    after = CORE_KEYS.index("first_fix_s") + 1
    assert keys == [*CORE_KEYS[:after], "x_span_m", *CORE_KEYS[after:], "beam_count"]  # after first_fix_s; the other at the end
    assert "x_span_m" not in [m.key for m in metric_infos(["bearings"])]
    assert register_metrics("scan", scan_plugin) is scan_plugin  # again the same: fine
    spec = EvalSpec(env_id="crowdloc/CrowdedRoom-v0", policies=("random_walk",), localizers=("mcl_lidar",),
                    crowd_sizes=(4,), seeds=2, episode_steps=12)  # fmt: skip
    result = evaluate(spec, workers=1, progress=False)
    for episode in result.episodes:
        assert episode.metrics["beam_count"] == 1081.0 and episode.metrics["x_span_m"] >= 0.0
        assert episode.x_offset_m.shape == (13,) and episode.x_offset_m[0] == 0.0
        np.testing.assert_allclose(np.ptp(episode.x_offset_m), episode.metrics["x_span_m"])
        assert episode.series["x_m"].shape == (13,)
    assert "| x span [m] |" in summary_markdown(result) and "| 1081 [1081, 1081] |" in summary_markdown(result)
    (row,) = result.summary
    assert row.stats["x_span_m"].n == 2


def test_the_registry_refuses_clashing_or_misplaced_metrics(scan_plugin: MetricPlugin) -> None:
    def plugin(*rows: MetricInfo, name: str = "other") -> MetricPlugin:
        return MetricPlugin(name, rows, _travelled_collect, _travelled_compute)

    with pytest.raises(ValueError, match="'test_span' is already registered for 'scan'"):
        register_metrics("scan", plugin(MetricInfo("y", "y", "{}"), name="test_span"))
    with pytest.raises(ValueError, match="metric key 'availability' is taken"):
        register_metrics("scan", plugin(MetricInfo("availability", "a", "{}")))
    with pytest.raises(ValueError, match="metric key 'x_span_m' is taken"):
        register_metrics("bearings", plugin(MetricInfo("x_span_m", "another label", "{}")))
    with pytest.raises(ValueError, match="'z' after 'nowhere', neither a core nor an earlier row"):
        register_metrics("scan", plugin(MetricInfo("z", "z", "{}", after="nowhere")))
    with pytest.raises(ConfigError, match="unknown measurement kind 'smell'"):
        register_metrics("smell", plugin(MetricInfo("z", "z", "{}")))
