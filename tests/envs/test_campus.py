"""The campus crowd (envs.crowds.campus) on the stereo campus: walkers on walkways, groups by the
doors, cars on their lanes keeping gaps and stopping for people and the robot, parked cars that
never move, the count split, the crowd sizes, bad configs, and what a LIDAR sees of a car."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from core.schema import ConfigError
from envs.bodies import CarConfig
from envs.config import load_world
from envs.crowds.campus import CampusConfig, CampusCrowd
from envs.crowds.campus.traffic import box_disc_gap, boxes_overlap
from envs.localization_env import LocalizationEnv

ID = "crowdloc/StereoCampus-v0"
STILL = np.zeros(2, dtype=np.float32)
CAR = CarConfig()
EASTBOUND_Y, WESTBOUND_Y = 21.75, 25.25


def campus(env: gym.Env[Any, Any]) -> CampusCrowd:
    crowd = env.unwrapped.world.crowds["campus"]  # type: ignore[attr-defined]
    assert isinstance(crowd, CampusCrowd)
    return crowd


def members(env: gym.Env[Any, Any]) -> tuple[np.ndarray, np.ndarray]:
    """The campus crowd's member positions ``(M, 2)`` and headings ``(M,)`` now."""
    world = env.unwrapped.world  # type: ignore[attr-defined]
    rows = campus(env).member_rows
    return world.positions[rows].copy(), world.angles[rows].copy()


def car_boxes(env: gym.Env[Any, Any]) -> list[np.ndarray]:
    crowd = campus(env)
    pos, angles = members(env)
    return [CAR.footprint(x, y, a) for (x, y), a in zip(pos[crowd.first_car :], angles[crowd.first_car :])]


def walkway_offset(crowd: CampusCrowd, points: np.ndarray) -> np.ndarray:
    """``(P,)`` how far each point lies outside the nearest walkway (negative: inside it)."""
    best = np.full(points.shape[0], np.inf)
    for walkway in crowd.c.walkways:
        line = np.asarray(walkway.points_m, dtype=np.float64)
        for a, b in zip(line, line[1:]):
            d = b - a
            t = np.clip((points - a) @ d / (d @ d), 0.0, 1.0)
            gap = np.hypot(*(a + t[:, None] * d - points).T) - 0.5 * walkway.width_m
            best = np.minimum(best, gap)
    return best


def run(env: gym.Env[Any, Any], steps: int, action: np.ndarray = STILL) -> list[dict[str, Any]]:
    infos = []
    for _ in range(steps):
        *_, info = env.step(action)
        infos.append(info)
    return infos


def test_the_same_seed_moves_the_campus_alike_and_another_seed_differently() -> None:
    a, b, c = (gym.make(ID, crowd_size=60) for _ in range(3))
    a.reset(seed=5)
    b.reset(seed=5)
    c.reset(seed=6)
    start = members(a)[0]
    for _ in range(200):
        for env in (a, b, c):
            env.step(np.array([0.5, 0.2], dtype=np.float32))
        np.testing.assert_array_equal(a.unwrapped.world.positions, b.unwrapped.world.positions)  # type: ignore[attr-defined]
    assert not np.array_equal(members(a)[0], start)  # they moved
    assert not np.array_equal(members(a)[0], members(c)[0])
    # a reset with the seed replays the episode
    end = members(a)[0]
    a.reset(seed=5)
    run(a, 200, np.array([0.5, 0.2], dtype=np.float32))
    np.testing.assert_array_equal(members(a)[0], end)


def test_walkers_stay_on_the_walkways_at_their_own_speeds() -> None:
    env = gym.make(ID, crowd_size=150)
    env.reset(seed=1)
    crowd = campus(env)
    w = crowd.walkers
    assert w > 90
    speeds = []
    for _ in range(40):
        run(env, 10)
        pos, _ = members(env)
        outside = walkway_offset(crowd, pos[:w])
        assert outside.max() < 0.3, outside.max()  # inside a walkway, less than a person's pushes
        speeds.append(np.hypot(*env.unwrapped.world.velocities[crowd.member_rows][:w].T))  # type: ignore[attr-defined]
    # each walks at its own desired speed, N(1.3, 0.2) clipped to [0.8, 1.8]
    assert 0.8 <= crowd.desired_mps.min() and crowd.desired_mps.max() <= 1.8
    assert abs(crowd.desired_mps.mean() - 1.3) < 0.06 and crowd.desired_mps.std() > 0.1
    assert 1.0 < float(np.median(speeds)) < 1.5
    # they spread over the network: most walkways carry someone
    assert len(set(crowd.way.tolist())) >= 12


def test_groups_stand_by_the_doors_facing_their_centre_and_stay() -> None:
    env = gym.make(ID, crowd_size=100)
    env.reset(seed=2)
    crowd = campus(env)
    assert crowd.sizes and all(2 <= s <= 4 for s in crowd.sizes)
    doors = crowd.doors
    for centre in crowd.group_centre:
        # out from one of the doors, beside its way out (door_distance_m, door_side_m)
        rel = centre - doors[:, :2]
        out = rel[:, 0] * np.cos(doors[:, 2]) + rel[:, 1] * np.sin(doors[:, 2])
        along = np.abs(-rel[:, 0] * np.sin(doors[:, 2]) + rel[:, 1] * np.cos(doors[:, 2]))
        near = (out >= 1.5) & (out <= 4.0 + 0.8) & (along >= doors[:, 3] + 1.5) & (along <= doors[:, 3] + 6.0 + 0.8)
        assert near.any(), centre
    spots = crowd.spot.copy()
    pos, _ = members(env)
    np.testing.assert_allclose(pos[crowd.walkers : crowd.first_car], spots)
    facing = crowd.facing_rad(env.unwrapped.state)  # type: ignore[attr-defined]
    w = crowd.walkers
    to_centre = crowd.group_centre[crowd.group_of] - spots
    np.testing.assert_allclose(facing[w:], np.arctan2(to_centre[:, 1], to_centre[:, 0]))
    for _ in range(10):
        run(env, 30)
        pos, _ = members(env)
        drift = np.hypot(*(pos[w : crowd.first_car] - spots).T)
        assert drift.max() < crowd.c.fidget_m + 0.1, drift.max()  # fidgeting around their spots
    assert drift.max() > 0.0


def test_parked_cars_never_move() -> None:
    env = gym.make(ID, crowd_size=60)
    env.reset(seed=3)
    crowd = campus(env)
    spots = np.asarray(crowd.c.parked)
    assert len(spots) == 8
    for _ in range(5):
        run(env, 100, np.array([1.0, 0.3], dtype=np.float32))
        pos, angles = members(env)
        np.testing.assert_array_equal(pos[crowd.first_parked :], spots[:, :2])
        np.testing.assert_allclose(angles[crowd.first_parked :], spots[:, 2], atol=1e-12)


def test_cars_follow_their_lanes_facing_their_travel() -> None:
    env = gym.make(ID, crowd_size=40, crowd={"campus": {"car_share": 0.5}})  # 20 cars, 20 people
    env.reset(seed=4)
    crowd = campus(env)
    assert crowd.cars == 20
    world = env.unwrapped.world  # type: ignore[attr-defined]
    cars = slice(crowd.first_car, crowd.first_parked)
    _, angles = members(env)
    lanes_y = np.where(crowd.lane == 0, EASTBOUND_Y, WESTBOUND_Y)
    # placed on their lanes, facing along them, at least car_gap_m apart bumper to bumper
    np.testing.assert_allclose(members(env)[0][cars, 1], lanes_y)
    np.testing.assert_allclose(np.cos(angles[cars]), np.where(crowd.lane == 0, 1.0, -1.0), atol=1e-12)
    moved = np.zeros(crowd.cars)
    for _ in range(60):
        before = members(env)[0][cars].copy()
        run(env, 10)
        pos, angles = members(env)
        lanes_y = np.where(crowd.lane == 0, EASTBOUND_Y, WESTBOUND_Y)
        assert np.abs(pos[cars, 1] - lanes_y).max() < 0.05
        v = world.velocities[crowd.member_rows][cars]
        fast = np.hypot(*v.T) > 1.0
        heading_error = np.abs((np.arctan2(v[:, 1], v[:, 0]) - angles[cars] + math.pi) % (2 * math.pi) - math.pi)
        assert np.all(heading_error[fast] < 0.05)
        assert np.hypot(*v.T).max() <= crowd.c.car_speed_mps + 1e-6
        step = np.abs(pos[cars, 0] - before[:, 0])
        moved += np.where(step < 20, step, 0.0)  # (a car re-entering jumps)
    assert moved.min() > 100  # every car drove on, at about the speed limit
    # the whole time, no car touched another
    boxes = car_boxes(env)
    assert not any(boxes_overlap(a, b, 0.0) for i, a in enumerate(boxes) for b in boxes[:i])


def test_cars_leaving_come_back_in_at_a_lane_start_facing_along_it_at_their_speed() -> None:
    env = gym.make(ID, crowd_size=1, crowd={"campus": {"car_share": 1.0}})
    env.reset(seed=0)
    crowd = campus(env)
    world = env.unwrapped.world  # type: ignore[attr-defined]
    world.place_crowd_member(crowd.first_car, (143.5, EASTBOUND_Y), hold=False, angle=0.0)
    starts = {0: (5.0, EASTBOUND_Y, 0.0), 1: (145.0, WESTBOUND_Y, math.pi)}
    seen = []
    car = crowd.first_car
    for _ in range(600):
        before = members(env)[0][car]
        speed = float(np.hypot(*world.velocities[crowd.member_rows][car]))
        run(env, 1)
        pos, angles = members(env)
        if np.hypot(*(pos[car] - before)) > 2.0:  # it left: where did it come in?
            x, y, heading = starts[int(crowd.lane[0])]
            assert pos[car, 1] == pytest.approx(y, abs=1e-9)
            assert abs(pos[car, 0] - x) <= speed * 0.1 + 1e-9  # the entry step driven at its speed
            assert math.cos(angles[car] - heading) > 1 - 1e-9
            after = world.velocities[crowd.member_rows][car]
            assert float(np.hypot(*after)) == pytest.approx(speed, abs=1e-6)
            seen.append(int(crowd.lane[0]))
    assert len(seen) >= 2  # it left and came back in, again and again
    assert world.contact_count == 0


def test_cars_queue_behind_a_person_in_their_lane_keeping_their_gaps() -> None:
    # one person and 20 cars: the person held standing in the eastbound lane
    env = gym.make(ID, crowd_size=21, crowd={"campus": {"car_share": 20 / 21}})
    env.reset(seed=1)
    crowd = campus(env)
    assert crowd.walkers == 1 and crowd.cars == 20
    world = env.unwrapped.world  # type: ignore[attr-defined]
    person = np.array([70.0, EASTBOUND_Y])
    world.place_crowd_member(0, tuple(person), hold=True)
    cars = slice(crowd.first_car, crowd.first_parked)
    for _ in range(80):
        run(env, 10)
        pos, _ = members(env)
        np.testing.assert_allclose(pos[0], person, atol=1e-9)
        boxes = car_boxes(env)[: crowd.cars]
        gaps = np.array([box_disc_gap(box, person) for box in boxes])
        assert gaps.min() > crowd.c.radius_m  # no car touches the person
        east = np.sort(pos[cars][(crowd.lane == 0), 0])
        queue = east[east < person[0]]
        bumpers = np.diff(queue) - CAR.length_m
        assert bumpers.size == 0 or bumpers.min() > crowd.c.car_gap_m - 0.3, bumpers
    # the queue formed: the first car stopped car_stop_gap_m before the person, the others car_gap_m apart
    v = np.hypot(*world.velocities[crowd.member_rows][cars].T)
    east_cars = np.flatnonzero(crowd.lane == 0)
    waiting = east_cars[(pos[cars][east_cars, 0] < person[0]) & (pos[cars][east_cars, 0] > person[0] - 40)]
    assert waiting.size >= 3 and np.all(v[waiting] < 0.05)
    front = pos[cars][waiting, 0].max() + 0.5 * CAR.length_m
    assert person[0] - crowd.c.radius_m - front == pytest.approx(crowd.c.car_stop_gap_m, abs=0.3)
    queue = np.sort(pos[cars][waiting, 0])
    np.testing.assert_allclose(np.diff(queue) - CAR.length_m, crowd.c.car_gap_m, atol=0.3)


def test_cars_stop_for_the_robot_in_their_lane() -> None:
    # the robot stands in the westbound lane from the start (the cars are placed around it)
    env = gym.make(ID, crowd_size=10, crowd={"campus": {"car_share": 1.0}}, robot={"start_pose": [60.0, WESTBOUND_Y, 0.0]})
    env.reset(seed=2)
    crowd = campus(env)
    infos = run(env, 600)
    assert not [c for info in infos for c in info["contacts"]]
    world = env.unwrapped.world  # type: ignore[attr-defined]
    pos, _ = members(env)
    west = pos[crowd.first_car : crowd.first_parked][crowd.lane == 1]
    # the westbound cars queue east of the robot, the first car_stop_gap_m from it
    nearest = west[west[:, 0] > 60.0, 0].min() - 0.5 * CAR.length_m - 60.0 - world.radii_m[0]
    assert nearest == pytest.approx(crowd.c.car_stop_gap_m, abs=0.3)


def test_crowd_sizes_from_0_to_150_are_placed_without_overlap() -> None:
    for size in (0, 1, 2, 7, 30, 75, 150):
        env = gym.make(ID, crowd_size=size)
        env.reset(seed=size)
        crowd = campus(env)
        walkers, sizes, cars = crowd.c.split
        assert walkers + sum(sizes) + cars == size
        assert crowd.count == size + (8 if size else 0)  # the parked cars on top, none in the empty campus
        pos, _ = members(env)
        people = pos[: crowd.first_car]
        d = np.hypot(*(people[:, None] - people[None]).T)
        np.fill_diagonal(d, np.inf)
        assert d.min(initial=np.inf) > 2 * crowd.c.radius_m, size
        boxes = car_boxes(env)
        assert not any(boxes_overlap(a, b, 0.0) for i, a in enumerate(boxes) for b in boxes[:i])
        robot = env.unwrapped.world.positions[0]  # type: ignore[attr-defined]
        for box in boxes:
            assert all(box_disc_gap(box, p) > crowd.c.radius_m for p in people)
            assert box_disc_gap(box, robot) > 0.3
        assert np.all(np.hypot(*(people - robot).T) > 0.55)
        infos = run(env, 20)
        assert all(np.all(np.isfinite(i["true_pose"])) for i in infos)
    with pytest.raises(ConfigError, match="201"):
        gym.make(ID, crowd_size=201)


@pytest.mark.parametrize(
    ("count", "car_share", "group_share", "split"),
    [
        (30, 0.1, 0.2, (22, (3, 2), 3)),  # the default: 3 cars, 27 people, 5 of them in 2 groups
        (25, 0.1, 0.2, (18, (4,), 3)),  # 2.5 cars: rounded half up; 4.4 -> 4 grouped: a 3 and a lone one make a 4
        (110, 10 / 110, 0.2, (80, (3, 2, 4, 3, 2, 4, 2), 10)),  # 100 people, 20 in groups
        (10, 0.0, 0.0, (10, (), 0)),
        (10, 1.0, 0.5, (0, (), 10)),
        (12, 0.0, 0.25, (9, (3,), 0)),
        (9, 0.0, 0.5, (4, (3, 2), 0)),  # 4.5 -> 5 grouped
    ],
)
def test_the_count_splits_into_walkers_groups_and_cars(
    count: int, car_share: float, group_share: float, split: tuple[int, tuple[int, ...], int]
) -> None:
    config = CampusConfig(count=count, car_share=car_share, group_share=group_share)
    assert config.split == split
    assert sum(split[1]) + split[0] + split[2] == count


def test_the_bodies_are_people_and_cars() -> None:
    env = LocalizationEnv("stereo_campus", crowd_size=30)
    crowd = campus(env)
    shapes = [b.shape for b in crowd.bodies()]
    assert shapes == ["person"] * 27 + ["car"] * 11  # 22 walkers, 5 standing; 3 cars and 8 parked
    np.testing.assert_allclose(crowd.member_mass_kg, [70.0] * 27 + [1300.0] * 11)
    np.testing.assert_allclose(crowd.radii_m, [0.25] * 27 + [CAR.bounding_radius_m] * 11)
    # the world's time step is bounded by every kind of body
    speeds = dict((name, (speed, radius)) for name, speed, radius in crowd.c.top_speeds())
    assert speeds["walkers"] == (pytest.approx(1.3 * 1.8), 0.25)
    assert speeds["cars"] == (5.5, pytest.approx(CAR.bounding_radius_m))
    with pytest.raises(ConfigError, match=r"dt_s = 0.11 .*crowd 'campus': walkers"):
        LocalizationEnv(dataclass_replace(load_world("stereo_campus"), dt_s=0.11))


def dataclass_replace(config: Any, **changes: Any) -> Any:
    import dataclasses

    return dataclasses.replace(config, **changes)


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        ({"walkways": [{"points_m": [[10, 31], [20, 31]], "widht_m": 3.0}]}, ["'widht_m'", "WalkwayConfig"]),
        ({"walkways": [{"points_m": [[10, 31], [20, 31]], "width_m": -1.0}]}, ["width_m", "-1.0"]),
        ({"walkways": [{"points_m": [[10, 31], [20, 31]], "width_m": 0.5}]}, ["width_m 0.5", "too narrow"]),
        ({"walkways": [{"points_m": [[10, 31], [200, 31]]}]}, ["[200.0, 31.0]", "outside the field"]),
        ({"lanes": [{"name": "stub", "points_m": [[5.0, 21.75]]}]}, ["'stub'", "at least two points"]),
        ({"car_share": 1.5}, ["car_share", "1.5"]),
        ({"car_share": -0.1}, ["car_share", "-0.1"]),
        ({"group_share": 2.0}, ["group_share", "2.0"]),
        ({"parked": [[160.0, 7.0, 0.0]]}, ["(160.0, 7.0, 0.0)", "outside the field"]),
        ({"parked": [[95.0, 7.0, 0.0], [96.0, 7.5, 0.0]]}, ["overlap"]),
        ({"shape": "column"}, ["campus.shape", "'column'"]),
        ({"group_sizes": [1]}, ["group_sizes", "(1,)"]),
        ({"lanes": []}, ["3 cars need lanes"]),
        ({"walkways": []}, ["22 walkers need walkways"]),
    ],
)
def test_a_bad_config_is_refused_naming_the_value(overrides: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(ConfigError) as error:
        LocalizationEnv("stereo_campus", crowd={"campus": overrides})
    for word in words:
        assert word in str(error.value), (word, str(error.value))


def test_a_lidar_sees_a_parked_cars_wheel_low_and_its_body_higher() -> None:
    # parked car 0 at (95, 7) nose to -y (its left is +x): its wheels at x = 95 -+ 0.775,
    # y = 7 -+ 1.325, 0.2 m wide; the robot 4 m west of the front wheels, facing +x
    wheel_y = 7.0 - 1.325
    pose = [91.0, wheel_y, 0.0]
    alone = {"car_share": 0.0, "group_share": 0.0}  # one walker, and the parked cars
    low = gym.make(ID, crowd_size=1, crowd={"campus": alone}, lidar={"height_m": 0.2, "range_std_m": 0.0})
    high = gym.make(ID, crowd_size=1, crowd={"campus": alone}, lidar={"height_m": 0.6, "range_std_m": 0.0})
    readings = []
    for env in (low, high):
        env.reset(seed=0, options={"robot_pose": pose})
        obs, *_ = env.step(STILL)
        angles = env.unwrapped.sensor_metadata["lidar"]["beam_angles_rad"]  # type: ignore[attr-defined]
        ahead = int(np.argmin(np.abs(angles)))
        readings.append(float(obs["lidar"][ahead]) * math.cos(float(angles[ahead])))
        if env is low:
            # a beam at the car's middle passes under it between the wheels
            gap = int(np.argmin(np.abs(angles - math.atan2(7.0 - wheel_y, 4.0))))
            assert obs["lidar"][gap] > 5.0
    wheel_face = 95.0 - 0.775 - 0.1 - 91.0
    body_side = 95.0 - 0.9 - 91.0
    assert readings[0] == pytest.approx(wheel_face, abs=2e-3)
    assert readings[1] == pytest.approx(body_side, abs=2e-3)


def test_the_robot_cannot_be_placed_inside_a_building_or_a_pole() -> None:
    env = LocalizationEnv("stereo_campus", crowd_size=0)
    buildings = env.config.features["buildings"].solids()
    inside = buildings[0].corners.mean(axis=0)
    with pytest.raises(ValueError, match=f"inside building {buildings[0].name!r}"):
        env.reset(seed=0, options={"robot_pose": [float(inside[0]), float(inside[1]), 0.0]})
    pole = env.config.features["poles"].items[0]
    with pytest.raises(ValueError, match="would overlap wall|inside pole"):
        env.reset(seed=0, options={"robot_pose": [pole.x_m, pole.y_m, 0.0]})
    env.reset(seed=0, options={"robot_pose": list(env.config.robot.start_pose)})  # the route's start is free
