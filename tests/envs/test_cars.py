"""Cars (envs.bodies.CarConfig): wheels, body and cabin by height, turning with the heading;
what a LIDAR and a camera at different heights see of a parked car (analytic ranges); the
footprint box that collides; a moving car facing its travel."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from core.schema import ConfigError
from envs.bodies import CarConfig
from envs.config import load_world
from envs.figure_model import FigureModel

STILL = np.zeros(2, dtype=np.float32)
CAR = CarConfig()  # 4.4 x 1.8 m, sill 0.3, beltline 0.95, roof 1.45, wheels r 0.32 at +-1.325, +-0.775
CAR_AT = (6.0, 4.0)  # where the tests park it, facing +x

#: a 12 m x 8 m hall: odometry, a 270 deg LIDAR (a beam straight ahead), a bearing camera, one landmark and one car
HALL = """
name: car_hall
description: "a hall with one car (tests)"
size_m: [12.0, 8.0]
dt_s: 0.05
max_episode_steps: 400
boundary_margin_m: 0.0
wall_height_m: 2.5
landmarks:
  - {name: pole, x_m: 6.0, y_m: 0.5, radius_m: 0.05}
robot:
  radius_m: 0.25
  mass_kg: 30.0
  max_speed_mps: 0.5
  max_turn_rate_rps: 1.5
  start_pose: [6.0, 7.0, -1.5707963267948966]
sensors:
  odometry: {type: odometry, alpha1: 0.0, alpha2: 0.0, alpha3: 0.0, alpha4: 0.0}
  lidar: {type: lidar, fov_rad: 4.71238898038469, beams: 1081, max_range_m: 20.0, range_std_m: 0.0, height_m: 0.2}
  camera: {type: bearing_camera, noise_std_rad: 0.0, height_m: 0.6}
crowds:
  cars:
    type: walkers
    shape: car
    count: 1
    max_count: 4
    radius_m: 2.5
    mass_kg: 1500.0
    desired_speed_mps: 2.0
"""


@pytest.fixture(scope="module")
def hall(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("worlds") / "car_hall.yaml"
    path.write_text(HALL)
    return path


def parked(hall: Path, pose: list[float], **overrides: Any) -> tuple[gym.Env, dict[str, np.ndarray]]:
    """The hall with its car parked (held) at CAR_AT facing +x and the robot at ``pose``, after one still step."""
    env = gym.make("crowdloc/CrowdedRoom-v0", world=str(hall), **overrides)
    env.reset(seed=0, options={"robot_pose": pose})
    env.unwrapped.world.place_crowd_member(0, CAR_AT, hold=True, angle=0.0)
    obs, *_ = env.step(STILL)
    return env, obs


def ray_ahead(env: gym.Env, obs: dict[str, np.ndarray]) -> float:
    """The LIDAR reading straight ahead of the robot."""
    angles = env.unwrapped.sensor_metadata["lidar"]["beam_angles_rad"]
    return float(obs["lidar"][int(np.argmin(np.abs(angles)))])


def box_extent(a: np.ndarray, b: np.ndarray) -> tuple[float, float, float, float]:
    points = np.vstack([a, b])
    return (*points.min(axis=0), *points.max(axis=0))


def test_a_car_is_four_wheels_below_the_sill_its_body_above_and_its_cabin_to_the_roof() -> None:
    model = FigureModel([("car", CAR.bounding_radius_m, math.inf, True, CAR)])
    figures = model.pose(np.array([[0.0, 0.0], [6.0, 4.0]]), np.array([0.0, 0.0]))
    low = figures.section(0.2)
    assert low.centres.shape == (0, 2) and low.seg_a.shape == (16, 2)  # four wheels, four sides each
    assert low.seg_rows.tolist() == [1] * 16
    chord = math.sqrt(0.32**2 - (0.2 - 0.32) ** 2)  # a wheel's half length at 0.2 m
    wheels = sorted(box_extent(low.seg_a[i : i + 4], low.seg_b[i : i + 4]) for i in range(0, 16, 4))
    expected = sorted(
        (6.0 + f - chord, 4.0 + s - 0.1, 6.0 + f + chord, 4.0 + s + 0.1) for f in (-1.325, 1.325) for s in (-0.775, 0.775)
    )
    np.testing.assert_allclose(wheels, expected, atol=1e-12)
    body = figures.section(0.6)
    np.testing.assert_allclose(box_extent(body.seg_a, body.seg_b), (3.8, 3.1, 8.2, 4.9), atol=1e-12)
    cabin = figures.section(1.2)  # 2.4 x 1.6 m, its centre 0.2 m behind the car's
    np.testing.assert_allclose(box_extent(cabin.seg_a, cabin.seg_b), (4.6, 3.2, 7.0, 4.8), atol=1e-12)
    assert figures.section(1.5).seg_a.shape == (0, 2)  # over the roof: nothing
    # the sides close: each box's segments run corner to corner around it
    np.testing.assert_allclose(np.roll(body.seg_b, 1, axis=0), body.seg_a, atol=1e-12)


def test_the_boxes_turn_with_the_cars_heading() -> None:
    model = FigureModel([("car", CAR.bounding_radius_m, math.inf, True, CAR)])
    figures = model.pose(np.array([[0.0, 0.0], [6.0, 4.0]]), np.array([0.0, math.pi / 2]))  # facing +y
    body = figures.section(0.6)
    np.testing.assert_allclose(box_extent(body.seg_a, body.seg_b), (5.1, 1.8, 6.9, 6.2), atol=1e-12)
    cabin = figures.section(1.2)  # behind the centre: toward -y now
    np.testing.assert_allclose(box_extent(cabin.seg_a, cabin.seg_b), (5.2, 2.6, 6.8, 5.0), atol=1e-12)
    np.testing.assert_allclose(CAR.footprint(6.0, 4.0, math.pi / 2).min(axis=0), (5.1, 1.8), atol=1e-12)


def test_a_car_that_does_not_occlude_is_no_occluder() -> None:
    model = FigureModel([("car", CAR.bounding_radius_m, math.inf, False, CAR)])
    figures = model.pose(np.zeros((2, 2)), np.zeros(2))
    assert figures.section(0.6).seg_a.shape == (4, 2)
    assert figures.occluders(0.6).seg_a.shape == (0, 2)


def test_posing_cars_without_their_headings_is_refused() -> None:
    model = FigureModel([("car", CAR.bounding_radius_m, math.inf, True, CAR)])
    with pytest.raises(ValueError, match="pass angles"):
        model.pose(np.zeros((2, 2)))


@pytest.mark.parametrize(
    ("height_m", "x", "expected"),
    [
        (0.2, 6.0, 7.0),  # between the wheels: under the car to the far wall (y = 0)
        (0.2, 7.325, 7.0 - 4.875),  # at the front left wheel: its outer face at y = 4 + 0.775 + 0.1
        (0.6, 6.0, 7.0 - 4.9),  # the body's side at y = 4.9
        (1.2, 6.0, 7.0 - 4.8),  # the cabin's side at y = 4.8
        (1.2, 7.6, 7.0),  # ahead of the cabin (it ends at x = 7.0): over the bonnet to the far wall
        (1.9, 6.0, 7.0),  # over the roof
    ],
)
def test_a_lidar_sees_of_a_parked_car_what_stands_at_its_height(hall: Path, height_m: float, x: float, expected: float) -> None:
    env, obs = parked(hall, [x, 7.0, -math.pi / 2], lidar={"height_m": height_m})
    assert ray_ahead(env, obs) == pytest.approx(expected, abs=1e-6)
    env.close()


@pytest.mark.parametrize(("height_m", "visible"), [(0.6, False), (1.2, False), (1.6, True)])
def test_a_parked_car_hides_a_landmark_from_a_camera_below_its_roof(hall: Path, height_m: float, visible: bool) -> None:
    env, _ = parked(hall, [6.0, 7.0, -math.pi / 2], camera={"height_m": height_m})  # the pole at (6, 0.5) is behind the car
    assert bool(env.unwrapped.last_info["visible_landmarks"][0]) is visible
    env.close()


def test_the_footprint_box_collides_not_the_disc_around_it(hall: Path) -> None:
    env, _ = parked(hall, [6.0, 7.0, -math.pi / 2])
    world = env.unwrapped.world
    for _ in range(85):  # 4.25 s toward the car's side at 0.5 m/s: it meets it after 3.7 s
        env.step(np.array([1.0, 0.0], dtype=np.float32))
    x, y, _ = world.robot_pose
    assert x == pytest.approx(6.0, abs=0.01)
    # stopped at the box's side, 1.15 m from its centre line (pymunk lets a velocity-driven body
    # sink a few cm into what it presses on, as at the walls)
    assert y == pytest.approx(CAR_AT[1] + 0.9 + 0.25, abs=0.05)
    assert y < CAR_AT[1] + CAR.bounding_radius_m - 1.0  # well inside the disc that would have stopped it
    car_x, car_y = world.positions[1]
    assert math.hypot(car_x - CAR_AT[0], car_y - CAR_AT[1]) < 0.02  # 30 kg hardly moves 1.5 t
    env.close()


def test_a_moving_car_faces_its_direction_of_travel(hall: Path) -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", world=str(hall))
    env.reset(seed=3)
    world = env.unwrapped.world
    errors = []
    for _ in range(300):
        env.step(STILL)
        v = world.velocities[1]
        if math.hypot(*v) > 0.5:
            errors.append(abs((math.atan2(v[1], v[0]) - world.angles[1] + math.pi) % (2 * math.pi) - math.pi))
    assert len(errors) > 50  # it drove
    assert np.median(errors) < math.radians(5)
    env.close()


def test_a_car_world_is_deterministic_and_draws_the_car(hall: Path) -> None:
    def run() -> tuple[np.ndarray, np.ndarray]:
        env = gym.make("crowdloc/CrowdedRoom-v0", world=str(hall), render_mode="rgb_array")
        env.reset(seed=5)
        actions = np.random.default_rng(1).uniform(-1, 1, (60, 2)).astype(np.float32)
        scans = [env.step(a)[0]["lidar"] for a in actions]
        frame = env.render()
        env.close()
        return np.array(scans), frame

    (scans_a, frame_a), (scans_b, frame_b) = run(), run()
    np.testing.assert_array_equal(scans_a, scans_b)
    np.testing.assert_array_equal(frame_a, frame_b)
    assert frame_a.ndim == 3


def test_a_car_crowds_radius_must_cover_its_box(tmp_path: Path) -> None:
    path = tmp_path / "small.yaml"
    path.write_text(HALL.replace("radius_m: 2.5", "radius_m: 1.0"))
    with pytest.raises(
        ConfigError, match=r"cars: crowd.radius_m 1.0 is too small for shape 'car'.*at least car.bounding_radius_m 2.377"
    ):
        load_world(path)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"wheelbase_m": 4.0}, "must lie inside the body"),
        ({"sill_m": 1.0}, "sill_m 1.0 < beltline_m"),
        ({"sill_m": 0.7, "beltline_m": 0.9}, "above the wheels' tops"),
        ({"cabin_length_m": 4.4}, "the cabin"),
        ({"length_m": math.nan}, "car.length_m must be finite"),
    ],
)
def test_impossible_cars_are_refused(change: dict[str, float], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        dataclasses.replace(CAR, **change)


def test_a_car_placed_with_a_non_finite_heading_is_refused(hall: Path) -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", world=str(hall))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="place_body: angle must be finite, got nan"):
        env.unwrapped.world.place_crowd_member(0, CAR_AT, angle=math.nan)
    env.close()
