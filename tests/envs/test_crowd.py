"""Crowd behaviour: the goalkeeper keeps its line, queue heads change queues, nobody leaves the arena."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs
from envs.config import load_world
from envs.crowds import QueueCrowd, WalkerCrowd
from envs.crowds.soccer import CHASER, KEEPER, WANDERER, soccer_targets

ENV_IDS = sorted(envs.ENV_WORLDS)
STILL = np.zeros(2, dtype=np.float32)


def persistent_random_actions(seed: int, steps: int, hold: int = 30) -> np.ndarray:
    """Random actions held for ``hold`` steps each, so the robot really roams (and bumps into things)."""
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(-1, 1, size=(steps // hold + 1, 2)), hold, axis=0)[:steps].astype(np.float32)


def run_keeper(crowd_size: int, seed: int, steps: int = 900) -> np.ndarray:
    """Keeper positions ``(steps, 2)`` while our robot stands still near the other goal."""
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=crowd_size)
    env.reset(seed=seed, options={"robot_pose": [2.5, 0.6, 0.0]})
    world = env.unwrapped.world
    assert world.crowds["soccer"].roles[0] == KEEPER
    # posts (1.5, 5) and (3.5, 5), keeper_offset_m 0.5: the keeper's line is y = 4.5, in the field
    np.testing.assert_allclose(world.positions[1], [2.5, 4.5], atol=1e-9)
    keeper = np.empty((steps, 2))
    for i in range(steps):
        env.step(STILL)
        keeper[i] = world.positions[1]
    env.close()
    return keeper


def on_station(keeper: np.ndarray, r: float) -> np.ndarray:
    """Steps where the keeper is within a body radius of its line and of the span between the posts."""
    return (np.abs(keeper[:, 1] - 4.5) <= r) & (keeper[:, 0] >= 1.5 - r) & (keeper[:, 0] <= 3.5 + r)


def test_a_lone_goalkeeper_keeps_its_line() -> None:
    r = load_world("robocup_crowded").crowd.radius_m
    keeper = run_keeper(1, seed=1)  # 30 s, nobody to push it
    assert on_station(keeper, r).all(), keeper[~on_station(keeper, r)][:5]
    assert np.median(np.abs(keeper[:, 1] - 4.5)) < 0.01
    assert np.ptp(keeper[:, 0]) > 0.2  # it moved along its line


@pytest.mark.parametrize("seed", [1, 2, 6])
def test_goalkeeper_keeps_its_line_among_chasers(seed: int) -> None:
    # crowd members are equally strong physical bodies: chasers dribbling at the goal may
    # shove the keeper a few centimetres past its station for a moment, never for long
    r = load_world("robocup_crowded").crowd.radius_m
    keeper = run_keeper(6, seed=seed)
    station = on_station(keeper, r)
    assert station.mean() >= 0.95, station.mean()
    assert np.median(np.abs(keeper[:, 1] - 4.5)) < 0.01
    assert np.ptp(keeper[:, 0]) > 0.2


def test_goalkeeper_returns_to_its_line_in_a_full_crowd() -> None:
    # 13 other robots, 6 of them dribbling at this goal, shove the keeper off station for
    # moments (a body pushes with its commanded speed); it must be back on station nearly always
    r = load_world("robocup_crowded").crowd.radius_m
    keeper = run_keeper(14, seed=14)
    station = on_station(keeper, r)
    assert station.mean() > 0.9, station.mean()
    assert station[-60:].any()  # on station again within the last 2 s
    assert np.median(np.abs(keeper[:, 1] - 4.5)) < 0.01


@pytest.mark.parametrize(
    ("ball_xy", "expected"),
    [((2.2, 1.0), (2.2, 4.5)), ((0.3, 3.0), (1.5, 4.5)), ((4.9, 4.9), (3.5, 4.5)), ((3.5, 2.0), (3.5, 4.5))],
)
def test_goalkeeper_target_is_the_ball_x_clipped_to_the_posts(ball_xy: tuple[float, float], expected: tuple) -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=1)
    env.reset(seed=0)
    crowd = env.unwrapped.world.crowds["soccer"]
    targets, *_ = soccer_targets(
        np.array([[2.5, 4.5]]),
        crowd.roles,
        crowd.wander,
        np.array(ball_xy),
        crowd.goal,
        crowd.post_a,
        crowd.post_b,
        crowd.soccer.keeper_offset_m,
        crowd.reach_m,
        crowd.wander_until,
        0.0,
    )
    np.testing.assert_allclose(targets[0], expected, atol=1e-12)
    env.close()


def test_goalkeeper_follows_the_ball_along_its_line() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=6)
    env.reset(seed=4, options={"robot_pose": [2.5, 0.6, 0.0]})
    world = env.unwrapped.world
    keeper_x, ball_x = [], []
    for _ in range(1200):
        env.step(STILL)
        keeper_x.append(world.positions[1, 0])
        ball_x.append(world.positions[world.ball_row, 0])
    wanted = np.clip(np.asarray(ball_x), 1.5, 3.5)
    assert np.ptp(wanted) > 0.5  # the ball went places
    assert np.corrcoef(keeper_x, wanted)[0, 1] > 0.8
    env.close()


@pytest.mark.parametrize("crowd_size", [0, 1, 7, 14])
def test_every_crowd_size_builds_and_steps_on_the_crowded_field(crowd_size: int) -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=crowd_size)
    obs, _ = env.reset(seed=crowd_size)
    world = env.unwrapped.world
    assert world.crowds["soccer"].count == crowd_size
    assert world.body_count == 1 + crowd_size + 1  # robot, crowd, ball
    roles = world.crowds["soccer"].roles.tolist()
    if crowd_size:
        assert roles[0] == KEEPER
        chasers = int(round(0.5 * (crowd_size - 1)))
        assert roles[1:] == [CHASER] * chasers + [WANDERER] * (crowd_size - 1 - chasers)
    # nobody overlaps anybody at the start
    xy, radii = world.positions, world.radii_m
    gaps = np.linalg.norm(xy[:, None] - xy[None], axis=-1) - (radii[:, None] + radii[None])
    assert np.all(gaps[~np.eye(len(radii), dtype=bool)] > 0)
    start = world.positions.copy()
    for a in persistent_random_actions(crowd_size, 150):
        obs, *_ = env.step(a)
        assert env.observation_space.contains(obs)
    if crowd_size:
        assert not np.allclose(world.positions[1 : 1 + crowd_size], start[1 : 1 + crowd_size])
    env.close()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_crowd_size_zero_works_for_every_world(env_id: str) -> None:
    env = gym.make(env_id, crowd_size=0)
    obs, info = env.reset(seed=0)
    assert env.unwrapped.world.member_rows.size == 0
    for a in persistent_random_actions(0, 60):
        obs, _, _, _, info = env.step(a)
        assert env.observation_space.contains(obs)
        assert not [c for c in info["contacts"] if c.other == "crowd"]
    env.close()


def test_queue_heads_walk_over_to_the_other_queue() -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0")
    env.reset(seed=0)
    world = env.unwrapped.world
    crowd = world.crowds["queues"]
    q = env.unwrapped.config.crowds["queues"]
    n = crowd.count
    assert n == 16 and isinstance(crowd, QueueCrowd) and crowd.rows.tolist() == list(range(1, 17))
    # members alternate between the queues; 0 and 1 are the heads
    assert crowd.queue_id.tolist() == [0, 1] * 8
    assert crowd.slot.tolist() == [i // 2 for i in range(n)]
    np.testing.assert_allclose(world.positions[1:3], [[q.left_x_m, q.head_y_m], [q.right_x_m, q.head_y_m]], atol=1e-9)
    first_shift_s = crowd.next_shift_s
    assert 0.0 <= first_shift_s < q.step_period_s
    while world.time_s < q.step_period_s:  # 5 s: the first shift has happened
        env.step(STILL)
    assert crowd.queue_id[:2].tolist() == [1, 0]  # each head joined the other queue ...
    assert crowd.slot[:2].min() >= 6  # ... at its end
    assert sorted(crowd.slot[crowd.queue_id == 0].tolist()) == list(range(8))
    assert sorted(crowd.slot[crowd.queue_id == 1].tolist()) == list(range(8))
    assert world.positions[1, 0] > q.left_x_m + 0.5 and world.positions[2, 0] < q.right_x_m - 0.5  # they left
    # the walk is about 6.6 m at walk_speed_mps (1 m/s): both arrive within 6.6 s plus 2 s to spare
    deadline_s = first_shift_s + 6.6 / q.walk_speed_mps + 2.0
    arrived = np.zeros(2, dtype=bool)
    while world.time_s < deadline_s and not arrived.all():
        env.step(STILL)
        arrived |= [world.positions[1, 0] > q.right_x_m - 0.3, world.positions[2, 0] < q.left_x_m + 0.3]
    assert arrived.all(), (world.time_s, world.positions[1:3])
    env.close()


def test_walkers_are_added_after_the_queuers() -> None:
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=4, crowd={"walkers": {"count": 3}})
    env.reset(seed=1)
    crowds = env.unwrapped.world.crowds
    assert list(crowds) == ["queues", "walkers"] and isinstance(crowds["walkers"], WalkerCrowd)
    assert crowds["queues"].rows.tolist() == [1, 2, 3, 4] and crowds["walkers"].rows.tolist() == [5, 6, 7]
    previous = env.unwrapped.world.positions[5:8].copy()
    path = np.zeros(3)
    for _ in range(80):  # 2 s
        env.step(STILL)
        current = env.unwrapped.world.positions[5:8].copy()
        path += np.linalg.norm(current - previous, axis=1)
        previous = current
    assert np.all(path > 1.0), path  # walkers walk, at about 1 m/s
    env.close()


@pytest.mark.parametrize(
    ("env_id", "kwargs"),
    [
        ("crowdloc/CrowdedRoom-v0", {"crowd": {"walkers": {"count": 6}}}),
        ("crowdloc/RoboCupCrowded-v0", {"crowd_size": 14}),
        ("crowdloc/RoboCupStatic-v0", {"crowd_size": 8}),
    ],
)
def test_everyone_stays_inside_the_walls(env_id: str, kwargs: dict) -> None:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=2)
    world = env.unwrapped.world
    xmin, ymin, xmax, ymax = env.unwrapped.config.arena_m
    radii = world.radii_m
    for step, a in enumerate(persistent_random_actions(2, 1200)):  # the robot roams and bumps into people
        env.step(a)
        xy = world.positions
        # every body's centre stays inside the boundary walls, by most of its radius
        inside = (xy[:, 0] > xmin + 0.5 * radii) & (xy[:, 0] < xmax - 0.5 * radii)
        inside &= (xy[:, 1] > ymin + 0.5 * radii) & (xy[:, 1] < ymax - 0.5 * radii)
        assert inside.all(), (step, np.flatnonzero(~inside), xy[~inside])
    env.close()
