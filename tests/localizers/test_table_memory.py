"""Map tables whose size grows with the world: their memory is estimated before anything is
allocated and a table above its bound is refused; mcl_lidar in a world too large for the beam model's
ray-cast table gets the campus reference's likelihood field instead."""

from __future__ import annotations

import logging
from types import SimpleNamespace

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers the env ids)
from core.schema import ConfigError
from localizers import mcl_lidar, range_table
from localizers.base import LandmarkMap
from localizers.mcl_lidar import LARGE_MAP_PARAMS, LidarMCL, LidarMCLParams, beam_model, large_map_params
from localizers.mcl_lidar import params as mcl_lidar_params
from localizers.mcl_lidar.beam_model import LikelihoodFieldModel
from localizers.range_table import MAX_TABLE_MB, build_range_table, check_table_size, wall_distance_field
from localizers.registry import spec
from localizers.scan_filter import large_map_params as far_point_large_map_params
from tests.localizers.campus import campus_walls

CAMPUS = LandmarkMap(np.zeros((0, 2)), (), (0.0, 0.0, 150.0, 100.0), campus_walls(np.random.default_rng(1), count=50))
ROOM = LandmarkMap(
    np.zeros((0, 2)), (), (0.0, 0.0, 7.0, 7.0), np.array([[0, 0, 7, 0], [7, 0, 7, 7], [7, 7, 0, 7], [0, 7, 0, 0]], float)
)


@pytest.fixture
def no_allocation(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail if a table's fill kernel runs (the refusal must come before any allocation)."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the table was built")

    monkeypatch.setattr(range_table, "_fill_range_table", refuse)
    monkeypatch.setattr(range_table, "_fill_distance_field", refuse)


def test_the_estimate_names_the_shape_the_size_and_the_bound() -> None:
    assert check_table_size("a table", (10, 10), 4, 1.0, "advice") == pytest.approx(400 / 1e6)
    with pytest.raises(
        ConfigError, match=r"a table of 3,000 x 2,000 x 720 entries would need about 17,280 MB, above .* 1,024 MB.*: do"
    ):
        check_table_size("a table", (3000, 2000, 720), 4, MAX_TABLE_MB, "do")


@pytest.mark.usefixtures("no_allocation")
def test_a_campus_sized_range_table_is_refused_before_it_is_built(tmp_path: object) -> None:
    with pytest.raises(ConfigError, match=r"ray-cast table .* 3,000 x 2,000 x 720 .* 17,280 MB.*likelihood_field"):
        build_range_table(CAMPUS, resolution_m=0.05, directions=720, max_range_m=100.0, cache=tmp_path)  # type: ignore[arg-type]


@pytest.mark.usefixtures("no_allocation")
def test_the_beam_model_on_a_campus_is_refused_when_the_filter_is_made() -> None:
    with pytest.raises(ConfigError, match=r"17,280 MB.*max_table_mb"):
        LidarMCL(CAMPUS, LidarMCLParams(), dt_s=0.1)


@pytest.mark.usefixtures("no_allocation")
def test_a_likelihood_field_too_fine_for_its_map_is_refused_naming_the_resolution() -> None:
    params = LidarMCLParams(model="likelihood_field", table_resolution_m=0.005)
    with pytest.raises(ConfigError, match=r"likelihood field .* 30,400 x 20,400 .*table_resolution_m than 0.005"):
        LikelihoodFieldModel(CAMPUS, params)
    with pytest.raises(ConfigError, match="wall-distance field"):
        wall_distance_field(CAMPUS.walls_m, (0.0, 0.0), 0.001, (150_000, 100_000))


def test_the_bound_is_max_table_mb() -> None:
    params = LidarMCLParams(model="likelihood_field", table_resolution_m=0.5, max_table_mb=0.1)
    with pytest.raises(ConfigError, match="0 MB|max_table_mb"):
        LikelihoodFieldModel(CAMPUS, params)
    assert LikelihoodFieldModel(CAMPUS, LidarMCLParams(model="likelihood_field", table_resolution_m=0.5)).distance_m.shape == (
        304,
        204,
    )
    assert beam_model._FIELD_BYTES_PER_CELL == 12


def _env(landmarks: LandmarkMap) -> SimpleNamespace:
    return SimpleNamespace(landmark_map=landmarks, sensor_metadata={"lidar": {"type": "lidar"}})


@pytest.fixture(autouse=True)
def nothing_told(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each test starts as a fresh process would: no large-map choice logged yet."""
    monkeypatch.setattr(mcl_lidar_params, "_told", set())


def test_a_large_world_gets_the_campus_references_likelihood_field(caplog: pytest.LogCaptureFixture) -> None:
    assert spec("mcl_lidar").prepare == "localizers.mcl_lidar:large_map_params"
    with caplog.at_level(logging.WARNING, logger=mcl_lidar.__name__):
        chosen = large_map_params(_env(CAMPUS), "lidar", None)
    assert chosen == LARGE_MAP_PARAMS
    assert "3000 x 2000 cells x 720 directions (17280 MB" in caplog.text and "likelihood_field" in caplog.text
    # said once a process: the next env of the same world (a benchmark's next episode) is told at debug level
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger=mcl_lidar.__name__):
        assert large_map_params(_env(CAMPUS), "lidar", None) == LARGE_MAP_PARAMS
    assert caplog.text == ""
    # the user's own values are kept over the large-map ones
    assert large_map_params(_env(CAMPUS), "lidar", {"sampling": 0.5}) == {**LARGE_MAP_PARAMS, "sampling": 0.5}
    # a model the user names is left alone (the beam model is then refused when the filter is made)
    assert large_map_params(_env(CAMPUS), "lidar", {"model": "beam"}) == {"model": "beam"}


def test_a_room_keeps_its_parameters() -> None:
    params = {"n_particles": 200}
    assert large_map_params(_env(ROOM), "lidar", params) is params
    assert large_map_params(_env(ROOM), "lidar", None) is None


def test_far_point_mcl_gets_the_same_choice_in_its_mcl_section(caplog: pytest.LogCaptureFixture) -> None:
    assert spec("far_point_mcl").prepare == "localizers.scan_filter:large_map_params"
    with caplog.at_level(logging.WARNING, logger=mcl_lidar.__name__):
        chosen = far_point_large_map_params(_env(CAMPUS), "lidar", {"filter": {"travel_m": 1.0}})
    assert chosen == {"filter": {"travel_m": 1.0}, "mcl": LARGE_MAP_PARAMS}
    assert "far_point_mcl: the beam model's ray-cast table" in caplog.text
    assert far_point_large_map_params(_env(CAMPUS), "lidar", {"mcl": {"sampling": 0.5}}) == {
        "mcl": {**LARGE_MAP_PARAMS, "sampling": 0.5}
    }
    named = {"mcl": {"model": "beam"}}
    assert far_point_large_map_params(_env(CAMPUS), "lidar", named) is named
    params = {"mcl": {"n_particles": 200}}
    assert far_point_large_map_params(_env(ROOM), "lidar", params) is params
    assert far_point_large_map_params(_env(ROOM), "lidar", None) is None


@pytest.mark.slow
@pytest.mark.parametrize("name", ["mcl_lidar", "far_point_mcl"])
def test_lidar_mcls_run_on_the_campus(name: str) -> None:
    env = gym.make("crowdloc/StereoCampus-v0", localizer=name, crowd_size=5)
    try:
        _, info = env.reset(seed=0)
        for _ in range(20):
            _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
        loc = env.get_wrapper_attr("localizer")
        mcl = loc.params if name == "mcl_lidar" else loc.params.mcl
        assert mcl.model == "likelihood_field" and mcl.table_resolution_m == 0.1
        assert info["estimate"].valid
    finally:
        env.close()
