"""Odometry reports the commanded motion plus alpha-model noise; pushes and slips go unreported."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.motion import to_rot_trans_rot
from envs import LocalizationEnv
from tests.envs.exact import EXACT

#: noise-free and without the world's systematic errors (the soccer worlds ship some)
NO_NOISE = {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, **EXACT}
STILL = np.zeros(2, dtype=np.float32)


def wrap(a: np.ndarray | float) -> np.ndarray | float:
    return (a + np.pi) % (2 * np.pi) - np.pi


def compose(pose: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """SE(2) composition: apply increment ``delta`` (in the frame of ``pose``) to ``pose``."""
    x, y, th = pose
    c, s = math.cos(th), math.sin(th)
    return np.array([x + c * delta[0] - s * delta[1], y + s * delta[0] + c * delta[1], wrap(th + delta[2])])


def commanded_increment(env: LocalizationEnv, action: np.ndarray) -> np.ndarray:
    dt = env.config.dt_s
    v = float(action[0]) * env.config.robot.max_speed_mps
    w = float(action[1]) * env.config.robot.max_turn_rate_rps
    return np.array([v * dt * math.cos(w * dt / 2), v * dt * math.sin(w * dt / 2), w * dt])


def test_reported_odometry_noise_follows_the_alpha_model() -> None:
    env = LocalizationEnv("robocup_static", crowd_size=0, odometry=EXACT)  # no TimeLimit: one long episode
    alphas = env.config.sensors["odometry"].alphas
    assert min(alphas) > 0
    action = np.array([0.5, 0.5], dtype=np.float32)
    clean = to_rot_trans_rot(commanded_increment(env, action))
    env.reset(seed=21)
    n = 10_000
    reported = np.empty((n, 3))
    for i in range(n):
        obs, *_ = env.step(action)
        reported[i] = obs["odometry"]
    noise = to_rot_trans_rot(reported) - clean
    noise[:, [0, 2]] = wrap(noise[:, [0, 2]])
    rot1, trans, rot2 = clean
    a1, a2, a3, a4 = alphas
    variances = np.array([a1 * rot1**2 + a2 * trans**2, a3 * trans**2 + a4 * (rot1**2 + rot2**2), a1 * rot2**2 + a2 * trans**2])
    mean = noise.mean(axis=0)
    var = noise.var(axis=0, ddof=1)
    # 5 standard errors of the mean and of the sample variance
    assert np.all(np.abs(mean) <= 5 * np.sqrt(variances / n)), (mean, variances)
    assert np.all(np.abs(var - variances) <= 5 * variances * math.sqrt(2 / (n - 1))), (var, variances)
    # the three parts are drawn independently
    corr = np.corrcoef(noise.T)
    assert np.all(np.abs(corr[np.triu_indices(3, 1)]) < 5 / math.sqrt(n))


def test_noise_free_odometry_equals_the_command_and_the_pose_integrates_it() -> None:
    env = LocalizationEnv("robocup_static", crowd_size=0, odometry=NO_NOISE)
    start = np.array([2.5, 5.0, 0.3])
    _, info = env.reset(seed=0, options={"robot_pose": start})
    np.testing.assert_allclose(info["true_pose"], start, rtol=0, atol=1e-12)
    # gentle random commands keep the robot well clear of walls and poles
    actions = (0.3 * np.random.default_rng(1).uniform(-1, 1, size=(150, 2))).astype(np.float32)
    pose = start.copy()
    from_reports = start.copy()
    for action in actions:
        previous = env.world.robot_pose
        obs, _, _, _, info = env.step(action)
        assert info["contacts"] == []
        delta = commanded_increment(env, action)
        np.testing.assert_allclose(obs["odometry"], delta.astype(np.float32), rtol=1e-6, atol=1e-9)
        # one step: the body moved by exactly the commanded increment
        np.testing.assert_allclose(info["true_pose"], compose(previous, delta), rtol=0, atol=1e-12)
        pose = compose(pose, delta)
        from_reports = compose(from_reports, obs["odometry"].astype(np.float64))
    np.testing.assert_allclose(info["true_pose"], pose, rtol=0, atol=1e-9)
    np.testing.assert_allclose(info["true_pose"], from_reports, rtol=0, atol=1e-5)  # float32 reports
    assert np.linalg.norm(info["true_pose"][:2] - start[:2]) > 0.1  # it really went somewhere


@pytest.mark.parametrize("action", [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (1.0, 1.0), (-0.5, 0.8)])
def test_noise_free_single_step_for_extreme_commands(action: tuple[float, float]) -> None:
    env = LocalizationEnv("robocup_static", crowd_size=0, odometry=NO_NOISE)
    start = np.array([2.5, 5.0, -1.2])
    env.reset(seed=0, options={"robot_pose": start})
    a = np.array(action, dtype=np.float32)
    obs, _, _, _, info = env.step(a)
    delta = commanded_increment(env, a)
    np.testing.assert_allclose(obs["odometry"], delta, rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(info["true_pose"], compose(start, delta), atol=1e-12)
    assert env.observation_space["odometry"].contains(obs["odometry"])


def test_a_push_moves_the_robot_without_odometry() -> None:
    env = LocalizationEnv("robocup_static", crowd_size=1, odometry=NO_NOISE)
    start = np.array([2.5, 5.0, 0.0])
    env.reset(seed=0, options={"robot_pose": start})
    world = env.world
    # a wanderer next to the robot, heading through it to a target on the far side
    world.place_crowd_member(0, (1.9, 5.0), hold=False)
    world.crowds["soccer"].send(0, np.array([4.5, 5.0]), until_s=1e9)
    odometry = np.zeros(3)
    contacts = []
    for _ in range(45):  # 1.5 s
        obs, _, _, _, info = env.step(STILL)
        odometry = compose(odometry, obs["odometry"].astype(np.float64))
        contacts += info["contacts"]
    moved = np.linalg.norm(info["true_pose"][:2] - start[:2])
    assert moved > 0.05, info["true_pose"]
    assert info["true_pose"][0] > start[0]  # pushed in the pusher's direction
    np.testing.assert_allclose(odometry, 0.0, atol=1e-12)
    crowd_contacts = [c for c in contacts if c.other == "crowd"]
    assert crowd_contacts, contacts
    assert crowd_contacts[0].other_index == 0
    assert 1 <= crowd_contacts[0].step <= 45
    # the contact point lies between the two bodies, on the robot's rim
    point = np.array(crowd_contacts[0].position_xy_m)
    assert abs(np.linalg.norm(point - start[:2]) - env.config.robot.radius_m) < 0.05


def test_a_slip_moves_the_robot_less_than_reported() -> None:
    slipping = {"slip_probability": 1.0, "slip_max_fraction": 0.5}
    env = LocalizationEnv("robocup_static", crowd_size=0, odometry=NO_NOISE, robot=slipping)
    start = np.array([2.5, 5.0, 0.0])
    env.reset(seed=0, options={"robot_pose": start})
    action = np.array([0.5, 0.0], dtype=np.float32)
    reported = 0.0
    for _ in range(30):
        obs, _, _, _, info = env.step(action)
        reported += float(obs["odometry"][0])
    travelled = info["true_pose"][0] - start[0]
    expected = 30 * commanded_increment(env, action)[0]
    assert reported == pytest.approx(expected, rel=1e-5)
    # every step loses U(0, 0.5) of the motion: about a quarter on average
    assert 0.5 * expected < travelled < 0.95 * expected
