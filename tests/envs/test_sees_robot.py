"""People who see the robot: the crowds' ``sees_robot`` share and
:func:`envs.crowds.steering.see_robot`.

In an open hall built here, a walker heading straight at our standing robot passes it without
touching it when it sees the robot, and walks into it and shoves it when it does not (the
invisible robot of today's crowds, which the shipped worlds keep: their pins are unchanged).
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from core.schema import ConfigError, from_mapping
from envs.config import WorldConfig
from envs.crowds.steering import SEE_BEHIND, SEE_FORCE_MPS2, SEE_GAP_M, SEE_RANGE_M, draw_seers, see_robot
from envs.world import World

ROBOT_XY = (6.0, 3.0)
ROBOT_R = 0.25
PERSON_R = 0.2


def hall(sees_robot: float, count: int = 1) -> WorldConfig:
    """A 12 m x 6 m hall with no walls inside, our robot standing in its middle and ``count``
    free walkers (:mod:`envs.crowds.walkers`) of whom ``sees_robot`` see it."""
    return from_mapping(
        WorldConfig,
        {
            "name": "open_hall",
            "description": "an open hall (test)",
            "size_m": [12.0, 6.0],
            "dt_s": 0.05,
            "max_episode_steps": 400,
            "robot": {"radius_m": ROBOT_R, "mass_kg": 30.0, "start_pose": [ROBOT_XY[0], ROBOT_XY[1], 0.0]},
            "sensors": {"odometry": {"type": "odometry"}},
            "crowds": {
                "people": {
                    "type": "walkers",
                    "count": count,
                    "max_count": max(count, 1),
                    "radius_m": PERSON_R,
                    "mass_kg": 70.0,
                    "desired_speed_mps": 1.2,
                    "sees_robot": sees_robot,
                }
            },
        },
        where="test hall",
    )


def walk_at_the_robot(sees_robot: float, offset_m: float = 0.0, seconds: float = 9.0) -> tuple[int, float, float, float]:
    """One walker from (1, 3 + offset) toward (11, 3 + offset), past the robot standing at (6, 3):
    (contacts, closest surface gap m, largest robot displacement m, farthest x the walker reached)."""
    world = World(hall(sees_robot))
    rng = np.random.default_rng(0)
    world.reset(rng)
    crowd = world.crowds["people"]
    world.place_crowd_member(0, (1.0, ROBOT_XY[1] + offset_m), hold=False)
    crowd.goals[:] = (11.0, ROBOT_XY[1] + offset_m)
    start = world.robot_pose[:2].copy()
    closest, moved, reached = np.inf, 0.0, 0.0
    for _ in range(round(seconds / world.config.dt_s)):
        world.step(np.zeros(2), 0.0, rng)
        gap = float(np.hypot(*(world.positions[1] - world.positions[0]))) - ROBOT_R - PERSON_R
        closest = min(closest, gap)
        moved = max(moved, float(np.hypot(*(world.robot_pose[:2] - start))))
        reached = max(reached, float(world.positions[1, 0]))
    return world.contact_count, closest, moved, reached


@pytest.mark.parametrize("offset_m", [0.0, 0.1, -0.3])
def test_a_walker_who_sees_the_robot_passes_it_without_contact(offset_m: float) -> None:
    contacts, closest, moved, reached = walk_at_the_robot(1.0, offset_m)
    assert reached > ROBOT_XY[0] + 2.0  # it got past (on its way, not held up in front of it)
    assert contacts == 0
    assert moved == 0.0  # never touched: the velocity-commanded robot stands exactly still
    assert closest > 0.5 * SEE_GAP_M  # it kept clear by most of the passing gap


def test_a_walker_who_does_not_see_the_robot_walks_into_it() -> None:
    contacts, closest, moved, _ = walk_at_the_robot(0.0)
    assert contacts > 0 and closest < 0.0 and moved > 0.05


def test_the_robots_force_has_helbing_and_molnars_form() -> None:
    """Standing still (no collision course), the velocity change is ``force_s A exp(-gap / B)``
    along the line from the robot, weighed ``lambda + (1 - lambda)(1 + cos phi) / 2`` by where
    the member walks: a robot behind weighs ``lambda`` of one ahead."""
    radius, force_s = np.array([0.2]), 0.5
    gap = 1.0
    robot = np.array([0.2 + ROBOT_R + gap, 0.0])
    pos = np.zeros((1, 2))
    expected = force_s * SEE_FORCE_MPS2 * np.exp(-gap / SEE_RANGE_M)
    top = np.array([10.0])

    def change(want: tuple[float, float]) -> np.ndarray:
        w = np.array([want])
        out = see_robot(pos, w, radius, np.ones(1, dtype=np.bool_), top, robot, np.zeros(2), ROBOT_R, force_s)
        return out[0] - w[0]

    walking_away = change((-0.5, 0.0))  # the robot lies behind it
    np.testing.assert_allclose(walking_away, [-SEE_BEHIND * expected, 0.0], rtol=1e-12)
    sideways = change((0.0, 0.01))  # phi = 90 deg, and too slow to meet the robot
    np.testing.assert_allclose(sideways, [-(SEE_BEHIND + 0.5 * (1 - SEE_BEHIND)) * expected, 0.0], rtol=1e-12, atol=1e-15)
    unseen = see_robot(pos, np.array([[-0.5, 0.0]]), radius, np.zeros(1, dtype=np.bool_), top, robot, np.zeros(2), ROBOT_R, 0.5)
    np.testing.assert_array_equal(unseen, [[-0.5, 0.0]])


def test_one_about_to_collide_steps_aside_or_waits() -> None:
    """Head-on toward a standing robot: turned to pass it at the clearance, at the same speed;
    toward a robot coming at it faster than it can step aside: slowed."""
    radius, top, sees = np.array([0.2]), np.array([10.0]), np.ones(1, dtype=np.bool_)
    pos, robot = np.zeros((1, 2)), np.array([2.0, 0.0])
    out = see_robot(pos, np.array([[1.0, 0.0]]), radius, sees, top, robot, np.zeros(2), ROBOT_R, 0.0)
    d = out[0] / np.hypot(*out[0])
    assert np.hypot(*out[0]) == pytest.approx(1.0)
    assert abs(robot[0] * d[1] - robot[1] * d[0]) == pytest.approx(0.2 + ROBOT_R + SEE_GAP_M)  # passes at the clearance
    charging = see_robot(pos, np.array([[0.3, 0.0]]), radius, sees, top, robot, np.array([-2.0, 0.0]), ROBOT_R, 0.0)
    assert np.hypot(*charging[0]) < 0.3  # cannot step aside in time at its speed: slows


def test_who_sees_is_drawn_per_member_from_the_seed_and_nests() -> None:
    def seers(share: float, seed: int = 3) -> np.ndarray:
        return draw_seers(np.random.default_rng(seed), 2000, share)

    assert not seers(0.0).any() and seers(1.0).all()
    half = seers(0.5)
    assert abs(half.mean() - 0.5) < 0.04
    np.testing.assert_array_equal(half, seers(0.5))  # same seed, same people
    assert not np.array_equal(half, seers(0.5, seed=4))
    assert np.all(seers(0.7)[half])  # who sees at 0.5 sees at 0.7
    rng = np.random.default_rng(5)
    before = np.random.default_rng(5).random(3)
    draw_seers(rng, 10, 0.5)
    np.testing.assert_array_equal(rng.random(3), before)  # the crowd's own stream is left as it was


@pytest.mark.parametrize(
    ("env_id", "crowd"),
    [
        ("crowdloc/CrowdedRoom-v0", "queues"),
        ("crowdloc/CrowdedRoom-v0", "walkers"),
        ("crowdloc/CeilingCorridor-v0", "corridor"),
        ("crowdloc/StereoCampus-v0", "campus"),
    ],
)
def test_bad_sees_robot_values_are_refused(env_id: str, crowd: str) -> None:
    for value in (-0.1, 1.5, float("nan"), float("inf")):
        with pytest.raises(ConfigError, match=rf"{crowd}\.sees_robot must be a share in \[0, 1\].*got {value!r}"):
            gym.make(env_id, crowd={crowd: {"sees_robot": value}})
    for value, kind in (("all", "str"), (True, "bool")):  # the loader's type check
        with pytest.raises(ConfigError, match=rf"crowds\.{crowd}\.sees_robot: expected a number, got {kind} {value!r}"):
            gym.make(env_id, crowd={crowd: {"sees_robot": value}})


def test_every_shipped_people_crowd_sees_the_robot() -> None:
    """The default: everyone in every crowd of people sees the robot."""
    from envs.config import load_world
    from envs.crowds.base import PeopleConfig

    people = 0
    for name in ("crowded_room", "ceiling_corridor", "stereo_campus"):
        for crowd in load_world(name).crowds.values():
            assert isinstance(crowd, PeopleConfig)
            assert crowd.sees_robot == 1.0
            people += 1
    assert people == 4


def test_a_share_is_deterministic_by_seed() -> None:
    def run(seed: int) -> np.ndarray:
        world = World(hall(0.5, count=8))
        rng = np.random.default_rng(seed)
        world.reset(rng)
        for _ in range(60):
            world.step(np.array([0.3, 0.0]), 0.2, rng)
        return np.concatenate([world.positions.ravel(), world.crowds["people"].sees])

    np.testing.assert_array_equal(run(7), run(7))
    assert not np.array_equal(run(7), run(8))
