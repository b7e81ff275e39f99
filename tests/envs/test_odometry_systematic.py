"""Systematic odometry errors (Borenstein & Feng 1996, the UMBmark model): unequal wheel
diameters E_d, a wrong wheelbase E_b and a scale error k, on top of the alpha noise.

The body moves as commanded; the reading is what the encoders and the nominal kinematics
make of it. Expected values come from the model's closed forms, written out here:

    straight drive of S:  reads k S (E_d + 1)^2 / (4 E_d) long, turned by k S (1 - E_d^2) / (2 b E_d)
    turn in place of a:   reads k E_b (E_d + 1)^2 / (4 E_d) a
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import gymnasium as gym
import numpy as np
import pytest

from core.geometry import compose, wrap_angle
from core.motion import odometry_noise_std, sample_odometry
from core.schema import ConfigError
from envs import LocalizationEnv
from envs.config import load_world
from envs.sensors.odometry import Odometry, OdometryConfig
from tests.envs.exact import EXACT

#: noise-free and without the world's systematic errors (the soccer worlds ship some)
NO_NOISE = {"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0, **EXACT}
STATIC = "crowdloc/RoboCupStatic-v0"  # 5 m x 10 m, 1.75 m/s, 3 rad/s, dt 1/30 s
SIDE_M = 4.0
LEG_STEPS, TURN_STEPS = 80, 20


def long_field() -> LocalizationEnv:
    """The static soccer field stretched to 25 m along x, for a 20.8 m straight drive."""
    world = load_world("robocup_static")
    camera = dataclasses.replace(world.sensors["camera"], distractors=())  # they would stand inside the longer field
    config = dataclasses.replace(world, size_m=(25.0, 10.0), sensors={**world.sensors, "camera": camera})
    return LocalizationEnv(config, crowd_size=0, odometry=NO_NOISE)


def with_odometry(env: LocalizationEnv, **fields: float) -> LocalizationEnv:
    return LocalizationEnv(env.config, crowd_size=0, odometry=fields)


def step_length(env: gym.Env, a_v: np.float32) -> float:
    """The signed length of one step of forward action ``a_v``, as the env commands it."""
    config = env.unwrapped.config  # type: ignore[attr-defined]
    return float(a_v) * config.robot.max_speed_mps * config.dt_s


def step_turn(env: gym.Env, a_w: np.float32) -> float:
    config = env.unwrapped.config  # type: ignore[attr-defined]
    return float(a_w) * config.robot.max_turn_rate_rps * config.dt_s


def drive(env: gym.Env, start: np.ndarray, actions: list[np.ndarray], seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Drive ``actions`` from ``start``; the dead-reckoned and the true final pose (no contact allowed)."""
    env.reset(seed=seed, options={"robot_pose": start})
    reckoned = start.astype(np.float64)
    info: dict = {}
    for action in actions:
        obs, _, _, _, info = env.step(action)
        assert info["contacts"] == [], "the drive must have room"
        reckoned = compose(reckoned, obs["odometry"].astype(np.float64))
    return reckoned, info["true_pose"]


def in_frame(pose: np.ndarray, point: np.ndarray) -> np.ndarray:
    """``point`` (x, y) in the frame of ``pose``."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    d = point[:2] - pose[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


# ---------------------------------------------------------------- no systematic error


def old_bound(config: OdometryConfig, env: LocalizationEnv) -> np.ndarray:
    """The observation bound as it was before the systematic errors."""
    trans = env.config.robot.max_speed_mps * env.config.dt_s
    rot = env.config.robot.max_turn_rate_rps * env.config.dt_s
    std = odometry_noise_std([trans * math.cos(rot / 2), trans * math.sin(rot / 2), rot], config.alphas)
    return np.array([trans + 8 * std[1] + 1e-3, trans + 8 * std[1] + 1e-3, rot + 16 * std[0] + 1e-3], dtype=np.float32)


@pytest.mark.parametrize("wheelbase_m", [0.4, 0.7])
def test_the_defaults_read_exactly_as_before(wheelbase_m: float) -> None:
    env = LocalizationEnv("robocup_static", crowd_size=0)
    base = env.config.sensors["odometry"]
    assert isinstance(base, OdometryConfig)
    # a config without the fields (their defaults) and one naming them error-free
    plain = OdometryConfig(alpha1=base.alpha1, alpha2=base.alpha2, alpha3=base.alpha3, alpha4=base.alpha4)
    named = dataclasses.replace(plain, wheelbase_m=wheelbase_m, wheel_diameter_ratio=1.0, wheelbase_ratio=1.0, distance_scale=1.0)
    assert not plain.systematic and not named.systematic
    state = env.world.snapshot()
    sensors = [Odometry("odometry", c, env.config, state) for c in (plain, named)]
    for sensor in sensors:
        np.testing.assert_array_equal(sensor.bound, old_bound(plain, env))
    deltas = np.random.default_rng(3).uniform(-0.06, 0.06, size=(200, 3))
    rngs = [np.random.default_rng(11) for _ in range(3)]
    for delta in deltas:
        before = np.clip(sample_odometry(rngs[0], delta, plain.alphas).astype(np.float32), -sensors[0].bound, sensors[0].bound)
        for sensor, rng in zip(sensors, rngs[1:]):
            sensor.command(delta, rng)
            np.testing.assert_array_equal(sensor.observe(state, rng)[0], before)


def test_an_env_with_error_free_fields_named_rolls_out_identically() -> None:
    # the error-free fields take the exact code path: the wheelbase then makes no difference
    error_free = {"wheelbase_m": 0.55, **EXACT}
    envs = [gym.make(STATIC, crowd_size=3, odometry=EXACT), gym.make(STATIC, crowd_size=3, odometry=error_free)]
    actions = np.random.default_rng(5).uniform(-1, 1, size=(60, 2)).astype(np.float32)
    first = [env.reset(seed=9)[0] for env in envs]
    np.testing.assert_array_equal(first[0]["odometry"], first[1]["odometry"])
    for action in actions:
        a, b = (env.step(action)[0] for env in envs)
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])


# ---------------------------------------------------------------- one step, per wheel


def wheel_reading(s: float, dth: float, b: float, e_d: float, e_b: float, k: float) -> np.ndarray:
    """One step as the encoders see it: nominal diameter 1, actual mean diameter 1 / k."""
    d_mean = 1.0 / k
    d_right, d_left = 2 * e_d / (e_d + 1) * d_mean, 2 / (e_d + 1) * d_mean
    rolled_right, rolled_left = s + dth * e_b * b / 2, s - dth * e_b * b / 2
    # encoder turns times the nominal circumference
    read_right = rolled_right / (math.pi * d_right) * math.pi
    read_left = rolled_left / (math.pi * d_left) * math.pi
    s_read, dth_read = (read_right + read_left) / 2, (read_right - read_left) / b
    return np.array([s_read * math.cos(dth_read / 2), s_read * math.sin(dth_read / 2), dth_read])


@pytest.mark.parametrize("action", [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0), (0.7, -0.4), (-0.5, 0.9)])
@pytest.mark.parametrize(("e_d", "e_b", "k"), [(1.0, 1.0, 1.0221), (1.0, 1.1, 1.0), (1.004, 1.0, 1.0), (0.99, 0.95, 0.98)])
def test_one_step_reads_what_the_wheel_encoders_give(action: tuple[float, float], e_d: float, e_b: float, k: float) -> None:
    fields = {"wheelbase_m": 0.45, "wheel_diameter_ratio": e_d, "wheelbase_ratio": e_b, "distance_scale": k}
    env = LocalizationEnv("robocup_static", crowd_size=0, odometry={**NO_NOISE, **fields})
    env.reset(seed=0, options={"robot_pose": np.array([2.5, 5.0, 0.4])})
    a = np.array(action, dtype=np.float32)
    obs, _, _, _, info = env.step(a)
    expected = wheel_reading(step_length(env, a[0]), step_turn(env, a[1]), 0.45, e_d, e_b, k)
    np.testing.assert_allclose(obs["odometry"], expected, rtol=1e-6, atol=1e-9)
    # backward motion reads backward: the scale error lengthens it, it does not flip it
    assert np.sign(obs["odometry"][0]) == np.sign(action[0]) or action[0] == 0.0


# ---------------------------------------------------------------- straight 20.8 m


@pytest.mark.parametrize("k", [1.0221, 0.97, 1.1])
def test_a_straight_drive_reads_long_by_the_distance_scale(k: float) -> None:
    env = with_odometry(long_field(), **{**NO_NOISE, "distance_scale": k})
    steps = 360
    a_v = np.float32(20.8 / (steps * env.config.robot.max_speed_mps * env.config.dt_s))
    start = np.array([1.0, 2.0, 0.0])
    reckoned, truth = drive(env, start, [np.array([a_v, 0.0], dtype=np.float32)] * steps)
    travelled = steps * step_length(env, a_v)
    assert travelled == pytest.approx(20.8, abs=1e-5)
    np.testing.assert_allclose(truth, [start[0] + travelled, start[1], 0.0], atol=1e-9)
    along, across = in_frame(truth, reckoned)
    assert along == pytest.approx((k - 1) * travelled, abs=2e-5)
    assert abs(across) < 1e-6
    assert abs(wrap_angle(reckoned[2] - truth[2])) < 1e-6


@pytest.mark.parametrize(("e_d", "b"), [(1.002, 0.4), (0.995, 0.4), (1.002, 0.55)])
@pytest.mark.parametrize("k", [1.0, 1.0221])
def test_unequal_wheels_bend_a_straight_drive(e_d: float, b: float, k: float) -> None:
    env = with_odometry(long_field(), **{**NO_NOISE, "wheelbase_m": b, "wheel_diameter_ratio": e_d, "distance_scale": k})
    steps = 360
    a_v = np.float32(20.8 / (steps * env.config.robot.max_speed_mps * env.config.dt_s))
    start = np.array([1.0, 2.0, 0.0])
    reckoned, truth = drive(env, start, [np.array([a_v, 0.0], dtype=np.float32)] * steps)
    s = step_length(env, a_v)
    # per step: a chord of s_read turned by phi; the chords lie on a circle of radius R
    s_read = k * s * (e_d + 1) ** 2 / (4 * e_d)
    phi = k * s * (1 - e_d**2) / (2 * b * e_d)
    heading = steps * phi
    radius = s_read / (2 * math.sin(phi / 2))
    # the right wheel the larger (E_d > 1): it counts too few turns, and the robot believes it turned right
    assert np.sign(heading) == -np.sign(e_d - 1)
    assert heading == pytest.approx(k * 20.8 * (1 - e_d**2) / (2 * b * e_d), rel=1e-5)
    assert wrap_angle(reckoned[2] - truth[2]) == pytest.approx(heading, abs=1e-6)
    np.testing.assert_allclose(
        reckoned[:2] - start[:2], [radius * math.sin(heading), radius * (1 - math.cos(heading))], rtol=0, atol=2e-5
    )


# ---------------------------------------------------------------- UMBmark squares


def square(env: gym.Env, turn_sign: float) -> tuple[list[np.ndarray], float, float]:
    """Four 4 m legs, each followed by a 90 deg turn in place; the actions, a leg's length and one turn."""
    config = env.unwrapped.config  # type: ignore[attr-defined]
    a_v = np.float32(SIDE_M / (LEG_STEPS * config.robot.max_speed_mps * config.dt_s))
    a_w = np.float32(turn_sign * (math.pi / 2) / (TURN_STEPS * config.robot.max_turn_rate_rps * config.dt_s))
    leg = [np.array([a_v, 0.0], dtype=np.float32)] * LEG_STEPS + [np.array([0.0, a_w], dtype=np.float32)] * TURN_STEPS
    return leg * 4, LEG_STEPS * step_length(env, a_v), TURN_STEPS * step_turn(env, a_w)


def umbmark(e_d: float, e_b: float, k: float = 1.0, b: float = 0.4) -> dict[str, tuple[np.ndarray, np.ndarray, float, float]]:
    """Drive the cw and the ccw square in the static field: per direction the dead-reckoned and
    true final poses, a leg's length and a signed turn."""
    fields = {**NO_NOISE, "wheelbase_m": b, "wheel_diameter_ratio": e_d, "wheelbase_ratio": e_b, "distance_scale": k}
    env = gym.make(STATIC, crowd_size=0, odometry=fields)
    # both squares inside x in [0.5, 4.5], y in [2, 6], clear of the walls and the goal posts
    starts = {"ccw": (np.array([0.5, 2.0, 0.0]), 1.0), "cw": (np.array([0.5, 6.0, 0.0]), -1.0)}
    out = {}
    for name, (start, sign) in starts.items():
        actions, leg, turn = square(env, sign)
        reckoned, truth = drive(env, start, actions)
        np.testing.assert_allclose(truth, start, atol=1e-5)  # the body drove a closed square
        out[name] = (reckoned, truth, leg, turn)
    return out


def heading_error(e_d: float, e_b: float, k: float, b: float, leg: float, turn: float) -> float:
    """Closed form: four straight legs bend by the wheel ratio, four turns read scaled."""
    per_leg = k * leg * (1 - e_d**2) / (2 * b * e_d)
    turn_gain = k * e_b * (e_d + 1) ** 2 / (4 * e_d)
    return 4 * per_leg + 4 * (turn_gain - 1) * turn


@pytest.mark.parametrize(("e_d", "e_b", "k"), [(1.0, 1.02, 1.0), (1.0, 0.97, 1.0), (1.002, 1.0, 1.0), (1.002, 0.99, 1.0221)])
def test_umbmark_heading_errors_follow_the_closed_form(e_d: float, e_b: float, k: float) -> None:
    for reckoned, truth, leg, turn in umbmark(e_d, e_b, k).values():
        expected = heading_error(e_d, e_b, k, 0.4, leg, turn)
        assert wrap_angle(reckoned[2] - truth[2]) == pytest.approx(expected, abs=1e-6)


def test_a_wrong_wheelbase_gives_mirror_symmetric_umbmark_errors() -> None:
    e_b = 1.02
    runs = umbmark(1.0, e_b)
    errors = {}
    for name, (reckoned, truth, leg, turn) in runs.items():
        # straight legs of the true length, turns of E_b times the true one
        psi = e_b * turn
        corners = sum(np.array([math.cos(i * psi), math.sin(i * psi)]) for i in range(4))
        np.testing.assert_allclose(reckoned[:2] - truth[:2], leg * corners, atol=2e-5)
        errors[name] = (reckoned[:2] - truth[:2], wrap_angle(reckoned[2] - truth[2]))
    (ccw_xy, ccw_th), (cw_xy, cw_th) = errors["ccw"], errors["cw"]
    # opposite headings: 4 turns of (E_b - 1) 90 deg each, one way round and the other
    assert ccw_th == pytest.approx(2 * math.pi * (e_b - 1), abs=1e-5)
    assert cw_th == pytest.approx(-ccw_th, abs=1e-6)
    # the return positions are mirror images across the first leg
    np.testing.assert_allclose(cw_xy, [ccw_xy[0], -ccw_xy[1]], atol=2e-5)
    assert np.linalg.norm(ccw_xy) > 0.1  # a real error, not rounding


def test_unequal_wheels_give_umbmark_heading_errors_of_one_sign() -> None:
    e_d = 1.002
    runs = umbmark(e_d, 1.0)
    headings = {name: wrap_angle(r[2] - t[2]) for name, (r, t, _, _) in runs.items()}
    # both the same way: every leg bends right when the right wheel is the larger
    per_leg = SIDE_M * (1 - e_d**2) / (2 * 0.4 * e_d)
    for heading in headings.values():
        assert heading == pytest.approx(4 * per_leg, rel=1e-3)
        assert heading < -0.07
    # what differs between them is of second order in E_d - 1
    assert abs(headings["cw"] - headings["ccw"]) < 1e-4


# ---------------------------------------------------------------- bad values, bounds, metadata

BAD = [
    *[("wheelbase_m", v) for v in (0.0, -0.4, math.nan, math.inf, 0.01, 6.0)],
    *[
        (f, v)
        for f in ("wheel_diameter_ratio", "wheelbase_ratio", "distance_scale")
        for v in (0.0, -1.0, math.nan, math.inf, 0.5, 2.0)
    ],
]


@pytest.mark.parametrize(("field", "value"), BAD)
def test_bad_systematic_values_are_config_errors_naming_the_field(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=f"odometry.{field}"):
        OdometryConfig(**{field: value})


def test_a_bad_override_names_the_field() -> None:
    with pytest.raises(ConfigError, match="odometry.wheel_diameter_ratio"):
        gym.make(STATIC, odometry={"wheel_diameter_ratio": 0.0})


@pytest.mark.parametrize(("e_d", "e_b", "k", "b"), list(itertools.product((0.8, 1.25), (0.8, 1.25), (0.8, 1.25), (0.05, 5.0))))
def test_the_readings_stay_inside_the_space_at_the_extremes(e_d: float, e_b: float, k: float, b: float) -> None:
    fields = {"wheelbase_m": b, "wheel_diameter_ratio": e_d, "wheelbase_ratio": e_b, "distance_scale": k}
    corners = [np.array(c, dtype=np.float32) for c in itertools.product((-1.0, 0.0, 1.0), repeat=2)]
    randoms = list(np.random.default_rng(2).uniform(-1, 1, size=(20, 2)).astype(np.float32))
    for alphas in (NO_NOISE, {}):
        env = LocalizationEnv("robocup_static", crowd_size=0, odometry={**alphas, **fields})
        space = env.observation_space["odometry"]
        sensor = env.sensors["odometry"]
        assert isinstance(sensor, Odometry)
        env.reset(seed=4)
        for action in corners + randoms:
            obs = env.step(action)[0]["odometry"]
            assert space.contains(obs), (obs, space)
            if alphas is NO_NOISE:  # noise-free: the clip never bit, the reading is the model's
                command = np.array([step_length(env, action[0]), 0.0, step_turn(env, action[1])])
                command[:2] = command[0] * np.array([math.cos(command[2] / 2), math.sin(command[2] / 2)])
                np.testing.assert_allclose(obs, sensor.measured(command), rtol=1e-6, atol=1e-9)


def test_the_metadata_keeps_the_bias_from_the_localizers() -> None:
    env = gym.make(STATIC, odometry={"wheel_diameter_ratio": 1.01, "wheelbase_ratio": 0.98, "distance_scale": 1.0221})
    meta = env.unwrapped.sensor_metadata["odometry"]  # type: ignore[attr-defined]
    assert set(meta) == {"type", "key", "alphas"}
    assert meta["alphas"] == env.unwrapped.config.sensors["odometry"].alphas  # type: ignore[attr-defined]
