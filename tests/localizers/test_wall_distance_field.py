"""localizers.range_table.wall_distance_field: bit for bit the full-grid numpy computation it
replaced (kept here as the reference) on the shipped worlds' maps and on random maps, and fast
enough for a campus (150 m x 100 m at 5 cm, 1,000 walls)."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import envs
from localizers.base import LandmarkMap
from localizers.mcl_lidar import LidarMCLParams
from localizers.mcl_lidar.beam_model import LikelihoodFieldModel
from localizers.measurements import sensor_map
from localizers.range_table import wall_distance_field
from tests.localizers.campus import campus_walls


def reference_field(
    walls_m: np.ndarray, origin_xy_m: tuple[float, float], resolution_m: float, shape: tuple[int, int]
) -> np.ndarray:
    """The original implementation: every wall against the whole grid, O(cells x walls)."""
    walls = np.asarray(walls_m, dtype=np.float64).reshape(-1, 4)
    nx, ny = shape
    cx = origin_xy_m[0] + (np.arange(nx) + 0.5) * resolution_m
    cy = origin_xy_m[1] + (np.arange(ny) + 0.5) * resolution_m
    px, py = np.meshgrid(cx, cy, indexing="ij")
    best = np.full(shape, np.inf)
    for x1, y1, x2, y2 in walls:
        ex, ey = x2 - x1, y2 - y1
        length2 = ex * ex + ey * ey
        t = np.zeros(shape) if length2 == 0.0 else np.clip(((px - x1) * ex + (py - y1) * ey) / length2, 0.0, 1.0)
        np.minimum(best, np.hypot(px - (x1 + t * ex), py - (y1 + t * ey)), out=best)
    return best


def assert_same(walls: np.ndarray, origin: tuple[float, float], res: float, shape: tuple[int, int]) -> None:
    got = wall_distance_field(walls, origin, res, shape)
    want = reference_field(walls, origin, res, shape)
    assert got.shape == want.shape == shape and got.dtype == np.float64
    assert np.array_equal(got, want), f"max difference {np.nanmax(np.abs(got - want))}"


#: worlds whose whole grid the numpy reference can check in a test's time (O(cells x walls)); the
#: campus is checked on windows (test_the_campus_map_matches_the_reference_on_windows)
SMALL_WORLDS = ("ceiling_corridor", "crowded_room", "robocup_crowded", "robocup_static")


def shipped_maps() -> list[tuple[str, LandmarkMap]]:
    """Every small shipped world's map as the likelihood field gets it: cut at the height of each
    range sensor (the wrapper's ``sensor_map``), the crowded room also at the reference LIDAR's 1.9 m."""
    out = []
    assert set(SMALL_WORLDS) <= set(envs.available_worlds())
    for world in SMALL_WORLDS:
        env = envs.LocalizationEnv(world)
        out.append((world, env.landmark_map))
        for name, meta in env.sensor_metadata.items():
            if meta.get("height_m") is not None:
                out.append((f"{world} {name}", sensor_map(env.landmark_map, meta)))
        if world == "crowded_room":
            out.append((f"{world} at 1.9 m", env.landmark_map.at_height(1.9)))
        env.close()
    return out


@pytest.mark.parametrize("resolution_m", [0.05, 0.1, 0.02])
def test_likelihood_fields_of_the_shipped_maps_are_unchanged(resolution_m: float) -> None:
    # LikelihoodFieldModel's own grid (the map bounds plus its margin) at the shipped resolution and others
    maps = shipped_maps()
    assert {"crowded_room lidar", "robocup_static", "robocup_crowded"} <= {name for name, _ in maps}
    for _, landmarks in maps:
        model = LikelihoodFieldModel(landmarks, LidarMCLParams(model="likelihood_field", table_resolution_m=resolution_m))
        want = reference_field(landmarks.walls_m, model.origin_xy_m, resolution_m, model.distance_m.shape)
        assert np.array_equal(model.distance_m, want)


def test_the_crowded_rooms_lidar_map_is_the_one_the_wrapper_gives_the_localizer() -> None:
    from envs.wrappers import LocalizationObservation

    env = LocalizationObservation(
        envs.LocalizationEnv("crowded_room"), "mcl_lidar", localizer_params={"model": "likelihood_field"}
    )
    cut = sensor_map(env.unwrapped.landmark_map, env.unwrapped.sensor_metadata["lidar"])
    assert env.landmark_map.walls_m.shape[0] < env.unwrapped.landmark_map.walls_m.shape[0]  # the table's top is cut away
    np.testing.assert_array_equal(env.landmark_map.walls_m, cut.walls_m)
    env.close()


def test_a_campus_window_matches_the_reference() -> None:
    walls = campus_walls(np.random.default_rng(3))
    for origin in [(-1.0, -1.0), (40.0, 30.0), (148.5, 98.7)]:
        assert_same(walls, origin, 0.05, (240, 170))
    assert_same(walls, (-1.0, -1.0), 0.5, (305, 205))  # the whole campus, coarse


def test_the_campus_map_matches_the_reference_on_windows() -> None:
    env = envs.LocalizationEnv("stereo_campus")
    walls = sensor_map(env.landmark_map, env.sensor_metadata["lidar"]).walls_m
    env.close()
    assert walls.shape[0] > 300
    for origin in [(-1.0, -1.0), (45.0, 28.0), (100.0, 60.0)]:  # a corner, the route's turn, buildings
        assert_same(walls, origin, 0.05, (200, 160))


def test_no_walls_is_inf_everywhere_and_empty_grids_are_empty() -> None:
    field = wall_distance_field(np.zeros((0, 4)), (0.0, 0.0), 0.1, (3, 4))
    assert field.shape == (3, 4) and np.all(np.isposinf(field))
    assert wall_distance_field([[0.0, 0.0, 1.0, 0.0]], (0.0, 0.0), 0.1, (0, 5)).shape == (0, 5)
    assert_same(np.zeros((0, 4)), (0.0, 0.0), 0.1, (1, 1))


def test_degenerate_grids_and_cells_far_from_every_wall() -> None:
    walls = np.array([[0.0, 0.0, 1.0, 0.0], [2.0, 2.0, 2.0, 2.0], [0.5, 0.5, 0.5, 3.0]])
    for origin, res, shape in [
        ((0.3, 0.2), 0.1, (1, 1)),
        ((-5.0, 0.0), 0.25, (1, 40)),
        ((0.0, -7.0), 0.25, (40, 1)),
        ((-1000.0, 500.0), 3.0, (50, 60)),  # far outside: every wall is about as far
        ((1e4, -1e4), 0.05, (70, 33)),
    ]:
        assert_same(walls, origin, res, shape)


def test_zero_length_walls_are_points() -> None:
    walls = np.array([[1.0, 1.0, 1.0, 1.0], [1.0, 1.0, 1.0, 1.0], [3.0, 0.5, 3.0, 0.5]])
    assert_same(walls, (0.0, 0.0), 0.1, (50, 20))
    field = wall_distance_field(walls[:1], (0.0, 0.0), 0.5, (4, 4))
    assert field[1, 1] == math.hypot(0.25, 0.25)


@pytest.mark.parametrize("seed", range(6))
def test_random_maps_match_the_reference(seed: int) -> None:
    rng = np.random.default_rng(seed)
    count = int(rng.integers(1, 120))
    a = rng.uniform(-10.0, 10.0, (count, 2))
    b = a + rng.normal(0.0, rng.choice([0.05, 1.0, 8.0]), (count, 2))
    zero = rng.random(count) < 0.15
    b[zero] = a[zero]  # zero-length walls
    walls = np.hstack([a, b])
    res = float(rng.choice([0.05, 0.13, 0.5]))
    shape = (int(rng.integers(1, 160)), int(rng.integers(1, 160)))
    origin = (float(rng.uniform(-15.0, 5.0)), float(rng.uniform(-15.0, 5.0)))
    assert_same(walls, origin, res, shape)


coordinate = st.floats(-20.0, 20.0, allow_nan=False, allow_infinity=False)


@settings(max_examples=150, deadline=None)
@given(
    walls=st.lists(
        st.one_of(
            st.tuples(coordinate, coordinate, coordinate, coordinate),
            coordinate.flatmap(lambda x: coordinate.map(lambda y: (x, y, x, y))),  # zero length
            st.tuples(coordinate, coordinate, st.floats(-0.1, 0.1), st.floats(-0.1, 0.1)).map(
                lambda w: (w[0], w[1], w[0] + w[2], w[1] + w[3])
            ),  # short, pole-like
        ),
        max_size=40,
    ),
    origin=st.tuples(st.floats(-40.0, 40.0), st.floats(-40.0, 40.0)),
    res=st.sampled_from([0.01, 0.05, 0.3, 1.0, 7.0]),
    shape=st.tuples(st.integers(1, 70), st.integers(1, 70)),
)
def test_any_map_matches_the_reference(
    walls: list[tuple[float, float, float, float]], origin: tuple[float, float], res: float, shape: tuple[int, int]
) -> None:
    assert_same(np.asarray(walls, dtype=np.float64).reshape(-1, 4), origin, res, shape)


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_walls_are_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="finite walls"):
        wall_distance_field([[0.0, 0.0, bad, 1.0]], (0.0, 0.0), 0.1, (3, 3))
    with pytest.raises(ValueError, match="resolution > 0"):
        wall_distance_field([[0.0, 0.0, 1.0, 1.0]], (0.0, 0.0), -0.1, (3, 3))


def test_a_campus_field_takes_seconds_not_minutes() -> None:
    # 150 m x 100 m at 5 cm plus the likelihood field's 1 m margin (6.2 M cells), 1,000 walls:
    # about 0.4 s on one core (the reference: about 2 min); a generous bound for a busy machine
    walls = campus_walls(np.random.default_rng(0))
    wall_distance_field(walls[:10], (0.0, 0.0), 0.05, (10, 10))  # compiled (or loaded) before timing
    shape = (math.ceil(152.0 / 0.05 - 1e-9), math.ceil(102.0 / 0.05 - 1e-9))
    start = time.perf_counter()
    field = wall_distance_field(walls, (-1.0, -1.0), 0.05, shape)
    elapsed = time.perf_counter() - start
    assert field.shape == (3040, 2040) and np.isfinite(field).all()
    assert elapsed < 10.0, elapsed
