"""Wheel slip that grows with acceleration and contact (``RobotConfig.slip_fraction``): it only
ever shortens the motion, odometry still reads the command, and it is deterministic."""

from __future__ import annotations

import math

import numpy as np
import pytest

from core.schema import ConfigError
from envs import LocalizationEnv
from envs.config import RobotConfig
from tests.envs.exact import EXACT

#: noise-free and without the world's systematic errors (the soccer worlds ship some)
NO_NOISE = {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, **EXACT}
CENTRE = (2.5, 5.0, 0.0)  # robocup_static: 5 m x 10 m, nothing within 2.5 m
SLIPPY = {
    "slip_per_accel_s2": 0.01,
    "slip_per_angular_accel_s2": 0.005,
    "slip_in_contact": 0.3,
    "slip_probability": 0.3,
    "slip_max_fraction": 0.4,
    "slip_max_total": 0.6,
}


def make(robot: dict, crowd_size: int = 0) -> LocalizationEnv:
    return LocalizationEnv("robocup_static", crowd_size=crowd_size, odometry=NO_NOISE, robot=robot)


def drive(env: LocalizationEnv, actions: list[tuple[float, float]], pose: tuple[float, float, float] = CENTRE, seed: int = 0):
    """Poses ``(T + 1, 3)`` (the start first), lost fractions ``(T,)`` and odometry readings ``(T, 3)``."""
    _, info = env.reset(seed=seed, options={"robot_pose": list(pose)})
    poses, lost, odometry = [info["true_pose"].copy()], [], []
    for a in actions:
        obs, _, _, _, info = env.step(np.asarray(a, dtype=np.float32))
        poses.append(info["true_pose"].copy())
        lost.append(info["slip_fraction"])
        odometry.append(obs["odometry"].astype(np.float64))
    return np.array(poses), np.array(lost), np.array(odometry)


def along(poses: np.ndarray, actions: list[tuple[float, float]], env: LocalizationEnv) -> tuple[np.ndarray, np.ndarray]:
    """Per step: the true displacement along the commanded chord direction, and the commanded length."""
    dt, rc = env.config.dt_s, env.config.robot
    a = np.asarray(actions, dtype=np.float32).astype(np.float64)  # as the env reads them
    v, w = a[:, 0] * rc.max_speed_mps, a[:, 1] * rc.max_turn_rate_rps
    heading = poses[:-1, 2] + 0.5 * w * dt
    step = np.diff(poses[:, :2], axis=0)
    return step[:, 0] * np.cos(heading) + step[:, 1] * np.sin(heading), v * dt


def test_slip_only_shortens_motion_never_lengthens_it() -> None:
    env = make(SLIPPY)
    cap = env.config.robot.slip_max_total
    rng = np.random.default_rng(3)
    fractions = []
    for episode in range(12):
        actions = [tuple(a) for a in rng.uniform(-1.0, 1.0, size=(25, 2))]
        poses, lost, odometry = drive(env, actions, seed=episode)
        assert env.world.contact_count == 0  # free space: the slip is the only loss
        true_s, commanded_s = along(poses, actions, env)
        # same sign, never longer, never shorter than (1 - cap) of the command
        assert np.all(np.abs(true_s) <= np.abs(commanded_s) + 1e-9)
        assert np.all(np.abs(true_s) >= (1.0 - cap) * np.abs(commanded_s) - 1e-9)
        assert np.all(true_s * commanded_s >= 0)
        np.testing.assert_allclose(true_s, (1.0 - lost) * commanded_s, atol=1e-9)
        # the turn is shortened by the same fraction
        w = np.asarray(actions, dtype=np.float32)[:, 1].astype(np.float64) * env.config.robot.max_turn_rate_rps * env.config.dt_s
        turned = np.angle(np.exp(1j * np.diff(poses[:, 2])))
        np.testing.assert_allclose(turned, (1.0 - lost) * w, atol=1e-9)
        # odometry reads the command, not the shortened motion
        np.testing.assert_allclose(odometry[:, 2], w, atol=1e-6)
        fractions.append(lost)
    lost = np.concatenate(fractions)
    assert np.all((lost >= 0) & (lost <= cap))
    assert lost.mean() > 0.2 and np.any(lost == cap)  # random commands accelerate hard: the cap binds


def test_no_slip_at_constant_velocity_in_free_space() -> None:
    env = make({k: v for k, v in SLIPPY.items() if k not in ("slip_probability", "slip_max_fraction")})
    actions = [(0.6, 0.3)] * 30
    poses, lost, _ = drive(env, actions)
    true_s, commanded_s = along(poses, actions, env)
    # the first step starts from rest (an acceleration); after that nothing is lost
    rc, dt = env.config.robot, env.config.dt_s
    first = rc.slip_per_accel_s2 * 0.6 * rc.max_speed_mps / dt + rc.slip_per_angular_accel_s2 * 0.3 * rc.max_turn_rate_rps / dt
    assert lost[0] == pytest.approx(min(rc.slip_max_total, first), rel=1e-6)
    assert np.all(lost[1:] == 0.0)
    np.testing.assert_allclose(true_s[1:], commanded_s[1:], rtol=1e-9)


def test_slip_grows_with_acceleration_a_hard_start_slips_more_than_a_ramp() -> None:
    env = make({"slip_per_accel_s2": 0.01})
    dt, v_max = env.config.dt_s, env.config.robot.max_speed_mps
    hard = [(1.0, 0.0)] * 45
    ramp = [(min(1.0, (t + 1) / 30), 0.0) for t in range(45)]  # 0 to full speed in 1 s: 1.75 m/s^2
    hard_poses, hard_lost, _ = drive(env, hard)
    ramp_poses, ramp_lost, _ = drive(env, ramp)
    # the fraction is proportional to the commanded acceleration: 52.5 m/s^2 in one step, 1.75 m/s^2 on the ramp
    assert hard_lost[0] == pytest.approx(0.01 * v_max / dt)
    assert hard_lost[0] == pytest.approx(0.525)
    np.testing.assert_allclose(ramp_lost[:30], 0.01 * v_max / 30 / dt, rtol=1e-5)  # float32 actions
    assert np.all(hard_lost[1:] == 0) and np.all(ramp_lost[30:] == 0)
    # the distance lost: what was commanded minus what was driven
    hard_s, hard_cmd = along(hard_poses, hard, env)
    ramp_s, ramp_cmd = along(ramp_poses, ramp, env)
    hard_loss = float((hard_cmd - hard_s).sum())
    ramp_loss = float((ramp_cmd - ramp_s).sum())
    assert hard_loss == pytest.approx(0.525 * v_max * dt, rel=1e-6)  # 3.1 cm
    assert ramp_loss < 0.6 * hard_loss  # 1.6 cm: a linear model roughly halves the loss on a ramp
    assert hard_lost.max() > 25 * ramp_lost.max()


def test_turn_rate_changes_slip_by_their_own_coefficient() -> None:
    env = make({"slip_per_angular_accel_s2": 0.004})
    rc, dt = env.config.robot, env.config.dt_s
    _, lost, _ = drive(env, [(0.0, 0.5), (0.0, 0.5), (0.0, -0.5)])
    alpha = 0.5 * rc.max_turn_rate_rps / dt  # 45 rad/s^2
    np.testing.assert_allclose(lost, [0.004 * alpha, 0.0, 0.004 * 2 * alpha])


def test_slip_in_contact_along_a_wall() -> None:
    """Driving at 30 degrees into the east boundary wall: once the robot touches it, it slides
    along it by 1 - slip_in_contact of what it does without the contact slip."""
    actions = [(0.5, 0.0)] * 60
    start = (5.0, 3.0, math.radians(30))
    free_poses, free_lost, _ = drive(make({}), actions, pose=start)
    env = make({"slip_in_contact": 0.3})
    poses, lost, _ = drive(env, actions, pose=start)
    assert np.all(free_lost == 0.0)
    touching = lost > 0
    first = int(np.argmax(touching))
    assert 5 <= first <= 20 and np.all(touching[first:])  # touches after a few steps, and stays pressed on
    assert np.all(lost[touching] == 0.3)
    np.testing.assert_array_equal(poses[: first + 1], free_poses[: first + 1])  # the same until the contact
    # sliding along the wall (+y), once settled against it
    free_dy = np.diff(free_poses[:, 1])[first + 3 :]
    dy = np.diff(poses[:, 1])[first + 3 :]
    assert dy.sum() / free_dy.sum() == pytest.approx(0.7, abs=0.02)


def test_slip_in_contact_with_a_held_crowd_member() -> None:
    env = make({"slip_in_contact": 0.25}, crowd_size=1)
    env.reset(seed=0, options={"robot_pose": list(CENTRE)})
    env.world.place_crowd_member(0, (3.5, 5.0), hold=True)  # 1 m ahead: the 0.54 m gap closes in 10 steps at 1.75 m/s
    lost, began = [], []
    for t in range(20):
        _, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        lost.append(info["slip_fraction"])
        began += [t for c in info["contacts"] if c.other == "crowd"]
    assert began and 5 <= began[0] <= 12
    first = began[0] + 1  # the first step that starts in contact
    assert lost[1:first] == [0.0] * (first - 1)  # free space at constant speed
    assert lost[first:] == [0.25] * (20 - first) and env.world.robot_touching()


def test_the_same_seed_slips_the_same_way() -> None:
    rng = np.random.default_rng(5)
    actions = [tuple(a) for a in rng.uniform(-1.0, 1.0, size=(60, 2))]
    runs = [drive(make(SLIPPY, crowd_size=4), actions, seed=11) for _ in range(2)]
    for a, b in zip(*runs):
        np.testing.assert_array_equal(a, b)
    other = drive(make(SLIPPY, crowd_size=4), actions, seed=12)
    assert not np.array_equal(runs[0][1], other[1])  # the random slip follows the seed


def test_the_growing_terms_draw_nothing_from_the_world_stream() -> None:
    actions = [(1.0, 1.0), (-1.0, 0.0), (0.3, -1.0)] * 10
    states = []
    for robot in ({}, {"slip_per_accel_s2": 0.01, "slip_per_angular_accel_s2": 0.01, "slip_in_contact": 0.5}):
        env = make(robot)
        drive(env, actions)
        states.append(env._world_rng.bit_generator.state)
    assert states[0] == states[1]


def test_slip_fraction_sums_the_terms_and_caps_them() -> None:
    rc = RobotConfig(start_pose=(0.0, 0.0, 0.0), slip_per_accel_s2=0.01, slip_per_angular_accel_s2=0.02, slip_in_contact=0.2)
    rng = np.random.default_rng(0)
    assert rc.slip_fraction(0.0, 0.0, False, rng) == 0.0
    assert rc.slip_fraction(10.0, 0.0, False, rng) == pytest.approx(0.1)
    assert rc.slip_fraction(10.0, 5.0, True, rng) == pytest.approx(0.4)
    assert rc.slip_fraction(1e3, 0.0, True, rng) == rc.slip_max_total == 0.9


@pytest.mark.parametrize(
    ("overrides", "words"),
    [
        ({"slip_per_accel_s2": -0.01}, ["slip_per_accel_s2", "-0.01"]),
        ({"slip_per_accel_s2": math.nan}, ["slip_per_accel_s2", "nan"]),
        ({"slip_per_accel_s2": 2.0}, ["slip_per_accel_s2", "2.0"]),
        ({"slip_per_angular_accel_s2": math.inf}, ["slip_per_angular_accel_s2", "inf"]),
        ({"slip_in_contact": 1.5}, ["slip_in_contact", "1.5"]),
        ({"slip_in_contact": -0.1}, ["slip_in_contact", "-0.1"]),
        ({"slip_max_total": 1.0}, ["slip_max_total", "1.0"]),
        ({"slip_max_total": math.nan}, ["slip_max_total", "nan"]),
        ({"slip_max_total": 0.3}, ["slip_max_fraction", "0.5", "slip_max_total", "0.3"]),
    ],
)
def test_bad_slip_values_are_refused_naming_the_field(overrides: dict, words: list[str]) -> None:
    with pytest.raises(ConfigError) as raised:
        make(overrides)
    for word in words:
        assert word in str(raised.value)


def test_a_wrong_type_is_refused() -> None:
    with pytest.raises(ConfigError, match="slip_in_contact"):
        make({"slip_in_contact": "a lot"})
