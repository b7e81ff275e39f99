"""Scenario drivers: the Exp 1 open-loop path, the Exp 2 soccer play, the shove."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents.experiments.replay import record
from agents.experiments.scenarios import PatrolDriver, ShoveDriver, SoccerDriver, exp1_driver, kidnap
from agents.policies.paths import EXP1_VERTICES, polygon_commands
from core.geometry import compose, wrap_angle
from tests.envs.exact import EXACT

DT = 1.0 / 30.0


def integrate(commands: list, start: np.ndarray) -> np.ndarray:
    """``(T, 3)`` poses from exact integration of the commands (straight or in-place only)."""
    poses = [np.asarray(start, dtype=np.float64)]
    for c in commands:
        for _ in range(c.steps):
            poses.append(compose(poses[-1], [c.v_mps * DT, 0.0, c.omega_rps * DT]))
    return np.array(poses)


def test_polygon_commands_hit_every_vertex_exactly() -> None:
    vertices = list(EXP1_VERTICES.values())
    commands = polygon_commands(vertices, 0.0, speed_mps=0.5, turn_rate_rps=1.0, dt_s=DT)
    assert all(c.v_mps == 0.0 or c.omega_rps == 0.0 for c in commands)  # straight lines and turns in place
    assert all(0 < c.v_mps <= 0.5 for c in commands if c.v_mps) and all(abs(c.omega_rps) <= 1.0 for c in commands)
    poses = integrate(commands, np.array([*vertices[0], 0.0]))
    for v in vertices:
        assert np.min(np.hypot(*(poses[:, :2] - v).T)) < 1e-9, v
    np.testing.assert_allclose(poses[-1], [*vertices[0], 0.0], atol=1e-9)


def test_exp1_driver_closes_the_path_in_the_simulator() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0")
    driver = exp1_driver(env.unwrapped)
    rec = record("crowdloc/RoboCupStatic-v0", driver, seed=0, max_steps=10_000)
    env.close()
    assert driver.done and rec.steps == driver.total_steps + 1
    assert rec.contacts.sum() == 0
    truth = rec.true_pose
    for name, v in EXP1_VERTICES.items():
        assert np.min(np.hypot(*(truth[:, :2] - v).T)) < 0.01, name
    start = np.array([2.5, 8.0, 0.0])
    np.testing.assert_allclose(truth[0], start, atol=1e-9)
    # nothing touches the robot: the body follows the recorded commands exactly
    assert rec.commanded.shape == (rec.steps - 1, 3)
    pose = truth[0]
    for t, inc in enumerate(rec.commanded, start=1):
        pose = compose(pose, inc)
        assert np.hypot(*(pose[:2] - truth[t, :2])) < 1e-5 and abs(wrap_angle(pose[2] - truth[t, 2])) < 1e-5
    assert np.hypot(*(truth[-1, :2] - start[:2])) < 0.01
    assert abs(wrap_angle(truth[-1, 2] - start[2])) < math.radians(0.5)


def test_exp1_path_loses_l5_only_on_d_to_h() -> None:
    l5 = np.array([5.0, 10.0])
    in_range = {name: bool(np.hypot(*(np.asarray(v) - l5)) <= 4.6) for name, v in EXP1_VERTICES.items()}
    assert in_range == {"a": True, "b": True, "c": True, "d": True, "e": False, "f": False, "g": False, "h": False}


def soccer_recording(seconds: float = 20.0):  # noqa: ANN201
    driver = SoccerDriver(seed=0)
    rec = record(
        "crowdloc/RoboCupCrowded-v0",
        driver,
        seed=0,
        max_steps=round(seconds / DT),
        env_kwargs={"crowd_size": 1},
        reset_options={"robot_pose": [0.0, 3.0, 0.0]},
    )
    return driver, rec


def test_soccer_driver_plays_chases_and_shoots() -> None:
    driver, rec = soccer_recording()
    assert driver.plays >= 2 and driver.shots >= 1
    np.testing.assert_allclose(rec.true_pose[0], [0.0, 3.0, 0.0], atol=1e-9)
    speeds = np.hypot(*np.diff(rec.true_pose[:, :2], axis=0).T) / DT
    assert 0.5 < speeds.mean() < 1.5  # the paper's field robot averaged 0.941 m/s
    assert np.percentile(speeds, 95) <= 1.76  # the command limit; only contacts (the keeper) push it faster
    xy = rec.true_pose[:, :2]
    assert np.all((xy > -0.05) & (xy < 5.05))  # it stays on the field


def test_soccer_driver_puts_the_ball_in_front_of_the_keeper() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=1)
    env.reset(seed=1, options={"robot_pose": [0.0, 3.0, 0.0]})
    base = env.unwrapped
    SoccerDriver(seed=1).reset(base)
    world = base.world
    keeper, ball = world.positions[1], world.positions[world.ball_row]
    np.testing.assert_allclose(keeper, [2.5, 4.5], atol=1e-9)
    assert ball[0] == pytest.approx(keeper[0]) and 4.0 < ball[1] < keeper[1]
    env.close()


def test_shove_moves_the_robot_without_odometry_seeing_it() -> None:
    kwargs = {
        "crowd_size": 2,
        "crowd": {"soccer": {"ball": False}},
        "odometry": {"alpha1": 0, "alpha2": 0, "alpha3": 0, "alpha4": 0, **EXACT},
    }
    push_at = 3.0
    driver = ShoveDriver(PatrolDriver([(1.2, 1.2), (3.8, 1.2), (3.8, 3.5), (1.2, 3.5)]), push_at, duration_s=2.0)
    rec = record("crowdloc/RoboCupCrowded-v0", driver, seed=0, max_steps=round(6.0 / DT), env_kwargs=kwargs,
                 reset_options={"robot_pose": [1.2, 1.2, 0.0]})  # fmt: skip
    k = round(push_at / DT)
    # with noise-free odometry, dead reckoning is exact except for what the shove did
    pose = rec.true_pose[k - 1]
    for t in range(k, rec.steps):
        pose = compose(pose, rec.odometry[t])
    before = rec.true_pose[k - 1]
    dr_before = rec.true_pose[0]
    for t in range(1, k):
        dr_before = compose(dr_before, rec.odometry[t])
    assert np.hypot(*(dr_before[:2] - before[:2])) < 1e-3  # nothing touched the robot before
    assert np.hypot(*(pose[:2] - rec.true_pose[-1, :2])) > 0.3
    assert rec.contacts[k:].sum() >= 1


def test_kidnap_carries_the_robot_far_to_a_free_pose_and_odometry_does_not_see_it() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=10)
    env.reset(seed=4)
    world = env.unwrapped.world
    rng = np.random.default_rng(0)
    for _ in range(20):
        before = world.robot_pose.copy()
        pose = kidnap(world, rng, 2.0)
        np.testing.assert_allclose(world.robot_pose, pose, atol=1e-9)
        assert np.hypot(*(pose[:2] - before[:2])) >= 2.0
        assert world.robot_placement_problem(pose[0], pose[1]) is None
        gaps = np.hypot(*(world.positions[1:] - pose[:2]).T) - world.radii_m[1:] - world.radii_m[0]
        assert gaps.min() >= 0.0
    obs, *_ = env.step(np.zeros(2, dtype=np.float32))
    np.testing.assert_allclose(obs["odometry"], 0.0, atol=1e-6)  # standing still after the jump: no motion read
    with pytest.raises(ValueError, match="no free pose at least 50 m"):
        kidnap(world, rng, 50.0, attempts=20)
    with pytest.raises(ValueError, match="min_distance_m must be a finite"):
        kidnap(world, rng, float("nan"))
    env.close()


def test_a_short_kidnap_translates_the_robot_by_the_given_distances_and_the_default_draws_as_before() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    env.reset(seed=4)
    world = env.unwrapped.world
    # the defaults draw what they drew before max_distance_m and keep_heading existed (poses recorded then)
    got = [kidnap(world, np.random.default_rng(0), 2.0)]
    np.testing.assert_allclose(got[0], [3.139814654603079, 3.87697936590399, 0.27410390540137985], atol=1e-12)
    rng = np.random.default_rng(1)
    for _ in range(20):  # a short kidnap: 2-5 m, pure translation
        before = world.robot_pose.copy()
        pose = kidnap(world, rng, 2.0, max_distance_m=5.0, keep_heading=True)
        assert 2.0 <= np.hypot(*(pose[:2] - before[:2])) <= 5.0
        assert pose[2] == pytest.approx(before[2], abs=1e-9)
        np.testing.assert_allclose(world.robot_pose, pose, atol=1e-9)
    with pytest.raises(ValueError, match="max_distance_m must be above min_distance_m 2.0, got 1.0"):
        kidnap(world, rng, 2.0, max_distance_m=1.0)
    with pytest.raises(ValueError, match="max_distance_m must be above min_distance_m 2.0, got nan"):
        kidnap(world, rng, 2.0, max_distance_m=float("nan"))
    env.close()


def test_a_kidnap_lands_on_the_floor_the_robot_can_reach() -> None:
    """The corridor's walls close pockets between them and the field's edge (x 1..1.6 m beside the
    door recesses): a kidnap once left the robot there (1.31, 2.87) for a whole recovery window."""
    env = gym.make("crowdloc/CeilingCorridor-v0")
    env.reset(seed=0)
    world = env.unwrapped.world
    rng = np.random.default_rng(0)
    for _ in range(400):
        x, y, _ = kidnap(world, rng, 2.0)
        alcove = -1.6 < y < 0.0 or 9.5 < y < 11.5 if x > 0 else 11.5 < y < 13.5
        assert abs(x) < 1.1 or alcove, (x, y)  # the corridor, a door recess or an alcove
    env.close()
