"""The 2.5-D bodies (envs.bodies): a person's sections by height, the gait, and what range
sensors at different heights see of them (analytic ranges)."""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from core.schema import ConfigError
from envs.bodies import CROTCH_FRACTION, HIP_FRACTION, SHOULDER_FRACTION, PersonConfig
from envs.config import load_world
from envs.figure_model import FigureModel
from envs.world import World

STILL = np.zeros(2, dtype=np.float32)
#: one exact adult: every range collapsed to a value
EXACT = PersonConfig(
    height_m=(1.70, 1.70),
    leg_radius_m=(0.06, 0.06),
    hip_half_width_m=(0.10, 0.10),
    torso_radius_m=(0.18, 0.18),
    head_radius_m=(0.09, 0.09),
)
EXACT_KW = {k: list(v) for k, v in dataclasses.asdict(EXACT).items() if isinstance(v, tuple)}


def one_person(heading: float, velocity: tuple[float, float] = (0.0, 0.0)) -> tuple[FigureModel, np.ndarray]:
    model = FigureModel([("person", 0.18, math.inf, True, EXACT)])
    positions = np.array([[0.0, 0.0], [1.0, 2.0]])
    model.reset(np.random.default_rng(0), np.zeros((2, 2)))
    model.heading[1] = heading
    model.advance(np.array([[0.0, 0.0], velocity]), 0.0)
    return model, positions


def test_a_standing_person_is_two_legs_a_torso_and_a_head_by_height() -> None:
    model, positions = one_person(heading=0.0)  # facing +x: the hips lie along y
    figures = model.pose(positions)
    legs = figures.section(0.2)
    np.testing.assert_allclose(legs.centres, [[1.0, 2.1], [1.0, 1.9]], atol=1e-12)  # left, then right
    np.testing.assert_allclose(legs.radii, [0.06, 0.06])
    assert legs.rows.tolist() == [1, 1]
    torso = figures.section(1.2)
    np.testing.assert_allclose(torso.centres, [[1.0, 2.0]])
    np.testing.assert_allclose(torso.radii, [0.18])
    head = figures.section(1.65)
    np.testing.assert_allclose(head.radii, [0.09])
    assert figures.section(1.75).centres.shape == (0, 2)  # above the head: nothing
    # the boundaries follow the proportions of the stature
    assert figures.section(CROTCH_FRACTION * 1.7 - 1e-9).radii.tolist() == [0.06, 0.06]
    assert figures.section(SHOULDER_FRACTION * 1.7 - 1e-9).radii.tolist() == [0.18]


def test_walking_legs_swing_and_their_gap_changes_with_the_gait_phase() -> None:
    model, positions = one_person(heading=0.0)
    speed, dt = 1.2, 0.01
    gaps, spreads = [], []
    for _ in range(200):  # 2 s: several steps at 1.8 steps/s
        model.advance(np.array([[0.0, 0.0], [speed, 0.0]]), dt)
        legs = model.pose(positions).section(0.2)
        (lx, ly), (rx, ry) = legs.centres
        spreads.append(lx - rx)  # along the heading (+x)
        gaps.append(math.hypot(lx - rx, ly - ry) - 2 * 0.06)
        assert ly == pytest.approx(2.1) and ry == pytest.approx(1.9)  # the hips stay put sideways
    hip = HIP_FRACTION * 1.7
    step = speed / EXACT.cadence_hz
    reach = (hip - 0.2) * math.tan(math.asin(step / (2 * hip)))  # each leg's largest shift at 0.2 m
    assert max(spreads) == pytest.approx(2 * reach, rel=0.02)
    assert min(spreads) == pytest.approx(-2 * reach, rel=0.02)
    assert max(gaps) - min(gaps) > 0.2  # the gap opens and closes as the person walks
    # standing still: the legs come together and stay put
    model.advance(np.zeros((2, 2)), 0.05)
    first = model.pose(positions).section(0.2).centres
    np.testing.assert_allclose(first, [[1.0, 2.1], [1.0, 1.9]], atol=1e-12)
    model.advance(np.zeros((2, 2)), 0.5)
    np.testing.assert_array_equal(model.pose(positions).section(0.2).centres, first)


def test_sizes_are_drawn_per_person_within_the_ranges_and_from_the_seed() -> None:
    person = PersonConfig()
    model = FigureModel([("person", 0.18, math.inf, True, person)] * 40)
    model.reset(np.random.default_rng(3), np.zeros((41, 2)))
    statures = model.layout.z_hi[model.layout.kind == 2]  # the heads' tops
    assert statures.min() >= person.height_m[0] and statures.max() <= person.height_m[1]
    assert np.unique(statures).size == 40
    again = FigureModel([("person", 0.18, math.inf, True, person)] * 40)
    again.reset(np.random.default_rng(3), np.zeros((41, 2)))
    np.testing.assert_array_equal(again.layout.z_hi, model.layout.z_hi)


def test_a_ball_is_a_sphere_and_a_robot_a_column() -> None:
    model = FigureModel([("ball", 0.11, math.inf, False, None), ("column", 0.23, 0.8, True, None)])
    figures = model.pose(np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]))
    low = figures.section(0.05)
    np.testing.assert_allclose(low.radii, [math.sqrt(0.11**2 - 0.06**2), 0.23])
    assert figures.section(0.5).rows.tolist() == [2]  # over the ball
    assert figures.section(0.9).rows.size == 0  # over the robot
    assert figures.occluders(0.05).rows.tolist() == [2]  # the ball does not block the camera


def room_with_one_person(height_m: float) -> gym.Env:
    env = gym.make(
        "crowdloc/CrowdedRoom-v0",
        crowd_size=1,
        lidar={"range_std_m": 0.0, "height_m": height_m},
        crowd={"queues": {"person": EXACT_KW}},
    )
    env.reset(seed=0, options={"robot_pose": [2.0, 3.0, 0.0]})
    world = env.unwrapped.world
    world.place_crowd_member(0, (4.0, 3.0))
    world.figure_model.heading[int(world.member_rows[0])] = math.pi  # facing the robot: hips along y
    return env


def beam(env: gym.Env, angle: float) -> int:
    lidar = env.unwrapped.config.sensors["lidar"]
    return int(np.argmin(np.abs(np.linspace(*lidar.relative_angles_rad, lidar.beams) - angle)))


def test_a_lidar_at_leg_height_sees_two_legs_with_a_gap_between_them() -> None:
    env = room_with_one_person(0.2)
    obs, *_ = env.step(STILL)
    scan = obs["lidar"]
    assert scan[beam(env, 0.0)] == pytest.approx(5.0, abs=1e-4)  # between the legs, to the far wall at x = 7
    lidar = env.unwrapped.config.sensors["lidar"]
    angles = np.linspace(*lidar.relative_angles_rad, lidar.beams)
    for side in (1.0, -1.0):  # the legs at (4, 3 +- 0.1)
        i = beam(env, math.atan2(side * 0.1, 2.0))
        t = angles[i]
        # ray from (2, 3) along t against the disc of radius 0.06 at (4, 3 + side 0.1)
        w = np.array([2.0, side * 0.1])
        d = np.array([math.cos(t), math.sin(t)])
        proj = w @ d
        expected = proj - math.sqrt(0.06**2 - (w @ w - proj**2))
        assert scan[i] == pytest.approx(expected, abs=1e-5)
    env.close()


def test_a_lidar_at_torso_height_sees_one_torso_and_one_above_the_head_sees_over_it() -> None:
    env = room_with_one_person(1.2)
    obs, *_ = env.step(STILL)
    assert obs["lidar"][beam(env, 0.0)] == pytest.approx(2.0 - 0.18, abs=1e-5)
    env.close()
    env = room_with_one_person(1.9)  # the person is 1.70 m tall
    obs, *_ = env.step(STILL)
    assert obs["lidar"][beam(env, 0.0)] == pytest.approx(5.0, abs=1e-4)
    env.close()


def test_a_sensor_above_a_wall_sees_over_it() -> None:
    config = dataclasses.replace(load_world("crowded_room"), wall_height_m=1.0, walls=((5.0, 0.5, 5.0, 6.5),), furniture=())
    state = World(config).snapshot()
    assert state.walls_at(0.2).all()
    assert not state.walls_at(1.5).any()


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("height_m", [1.9, 1.6], "person.height_m must be a range"),
        ("leg_radius_m", [0.0, 0.05], "person.leg_radius_m must be a range"),
        ("cadence_hz", 0.0, "person.cadence_hz must be in"),
        ("hip_half_width_m", [0.02, 0.03], "the legs would overlap"),
    ],
)
def test_bad_person_sizes_are_refused(field: str, value: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        gym.make("crowdloc/CrowdedRoom-v0", crowd={"queues": {"person": {field: value}}})


def test_an_unknown_shape_is_refused() -> None:
    with pytest.raises(ConfigError, match="crowd.shape must be one of column, person, car, got 'cube'"):
        gym.make("crowdloc/CrowdedRoom-v0", crowd={"queues": {"shape": "cube"}})
