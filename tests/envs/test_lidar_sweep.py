"""The swept LIDAR (``lidar.sweep_s``): each beam from the robot's pose at its own time.

Analytic: in the bare room (four walls) a robot turning in place at ``w`` sees every beam
turned back by ``w`` times its lag, so the back wall's points from the first beams (taken
``sweep_s * 270/360`` before the end) are rotated by ``w * sweep_s * 0.75`` against those of the
last beams; a robot driving at ``v`` sees each wall point displaced by ``v`` times its lag.
"""

from __future__ import annotations

import dataclasses
import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from core.schema import ConfigError
from envs.config import load_world
from envs.sensors.lidar import beam_lags_s

BARE_ROOM = dataclasses.replace(load_world("crowded_room"), walls=(), furniture=())
NO_SLIP = {"slip_per_accel_s2": 0.0, "slip_per_angular_accel_s2": 0.0, "slip_in_contact": 0.0}
UTM_SWEEP_S = 0.025  # Hokuyo UTM-30LX: 25 ms a turn


def room(sweep_s: float, **kwargs: object) -> gym.Env:
    return gym.make("crowdloc/CrowdedRoom-v0", world=BARE_ROOM, crowd_size=0, robot=NO_SLIP,
                    lidar={"range_std_m": 0.0, "sweep_s": sweep_s}, **kwargs)  # fmt: skip


def box_ranges(x: np.ndarray, y: np.ndarray, angles: np.ndarray, size: tuple[float, float]) -> np.ndarray:
    """Distance from each ``(x, y)`` inside the ``size`` box to its walls along each angle."""
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        tx = np.where(c > 0, (size[0] - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (size[1] - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)


def beam_angles(env: gym.Env) -> np.ndarray:
    return np.asarray(env.unwrapped.sensor_metadata["lidar"]["beam_angles_rad"])


def test_beam_lags_follow_a_counter_clockwise_turn() -> None:
    angles = np.linspace(-0.75 * math.pi, 0.75 * math.pi, 1081)
    lags = beam_lags_s(angles, UTM_SWEEP_S)
    assert lags[-1] == 0.0 and lags[0] == pytest.approx(0.75 * UTM_SWEEP_S)  # 18.75 ms of a 25 ms turn
    assert np.all(np.diff(lags) < 0)  # the first beam first
    full = np.arange(720) * (2 * math.pi / 720)
    assert beam_lags_s(full, 0.1)[0] == pytest.approx(0.1 * 719 / 720)  # a VLP-16's turn


def test_turning_in_place_rotates_the_walls_by_the_turn_during_the_sweep() -> None:
    env = room(UTM_SWEEP_S)
    pose = (1.0, 3.5, 0.0)  # 1 m in front of the back wall (x = 0), which the first and the last 100 beams see
    env.reset(seed=0, options={"robot_pose": list(pose)})
    base = env.unwrapped
    obs, *_ = base.step(np.array([0.0, 1.0], dtype=np.float32))  # full turn rate, from rest
    w = base.max_turn_rate_rps
    state = base.state
    assert state.robot_pose[2] - state.robot_start[2] == pytest.approx(w * base.config.dt_s, abs=1e-12)
    np.testing.assert_allclose(state.robot_pose[:2], pose[:2], atol=1e-12)  # turning in place
    angles = beam_angles(env)
    lags = beam_lags_s(angles, UTM_SWEEP_S)
    ranges = np.asarray(obs["lidar"], dtype=np.float64)
    # every beam along its direction at its time: the heading w * lag before the end
    heading = state.robot_pose[2] - w * lags
    np.testing.assert_allclose(ranges, box_ranges(pose[0], pose[1], heading + angles, BARE_ROOM.size_m), atol=2e-5)
    # the back wall (x = 0, 1 m behind) in the end pose's frame: the first beams see it turned by w * lag against the last
    points = ranges[:, None] * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    back = np.r_[0:40, angles.size - 40 : angles.size]  # -135 .. -125 deg and 125 .. 135 deg

    def world_x(pts: np.ndarray) -> np.ndarray:  # end frame -> world x (0 on the back wall)
        theta = state.robot_pose[2]
        return state.robot_pose[0] + math.cos(theta) * pts[:, 0] - math.sin(theta) * pts[:, 1]

    turn_back = -w * lags[back]
    c, s = np.cos(turn_back), np.sin(turn_back)
    unturned = np.stack([c * points[back, 0] - s * points[back, 1], s * points[back, 0] + c * points[back, 1]], axis=1)
    np.testing.assert_allclose(world_x(unturned), 0.0, atol=2e-5)  # turned back by w * lag: on the wall
    assert w * lags[0] == pytest.approx(w * UTM_SWEEP_S * 0.75)  # first beam vs last: 28 mrad
    off = world_x(points[back])  # as an instantaneous scan would place them: the first beams ~3 cm off the wall
    assert abs(off[0]) > 0.02 and abs(off[-1]) < 2e-5
    env.close()


def test_driving_shifts_each_wall_point_by_the_travel_during_its_lag() -> None:
    env = room(UTM_SWEEP_S)
    pose = (1.0, 3.5, 0.0)  # 1 m in front of the back wall (x = 0), which the first and the last 100 beams see
    env.reset(seed=0, options={"robot_pose": list(pose)})
    base = env.unwrapped
    for _ in range(3):
        obs, *_ = base.step(np.array([1.0, 0.0], dtype=np.float32))  # straight ahead (+x) at full speed
    v = base.max_speed_mps
    state = base.state
    assert state.robot_pose[0] - state.robot_start[0] == pytest.approx(v * base.config.dt_s, abs=1e-9)
    angles = beam_angles(env)
    lags = beam_lags_s(angles, UTM_SWEEP_S)
    ranges = np.asarray(obs["lidar"], dtype=np.float64)
    x_end, y_end = state.robot_pose[:2]
    np.testing.assert_allclose(ranges, box_ranges(x_end - v * lags, y_end, angles, BARE_ROOM.size_m), atol=2e-5)
    # the back wall's points (first and last beams) lie v * lag nearer than the wall does from the end pose
    points_x = ranges * np.cos(angles)
    back = np.r_[0:40, angles.size - 40 : angles.size]
    np.testing.assert_allclose(points_x[back], -(x_end - v * lags[back]), atol=2e-5)
    assert v * lags[0] == pytest.approx(0.5 * 0.01875)  # 9.4 mm at 0.5 m/s
    env.close()


def test_no_sweep_and_a_robot_standing_still_give_todays_scan_bit_for_bit() -> None:
    """``sweep_s: 0`` casts every beam from the end pose; a robot that does not move
    sees the same scan with any sweep, noise and crowd included."""
    still = np.zeros(2, dtype=np.float32)
    scans = {}
    for sweep in (0.0, UTM_SWEEP_S):
        env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=8, lidar={"sweep_s": sweep})
        obs, _ = env.reset(seed=3)
        seen = [obs["lidar"]]
        for _ in range(10):
            obs, *_ = env.step(still)
            seen.append(obs["lidar"])
        scans[sweep] = np.stack(seen)
        env.close()
    assert np.array_equal(scans[0.0], scans[UTM_SWEEP_S])
    # and the sweep does change a moving robot's scan
    moving = {}
    for sweep in (0.0, UTM_SWEEP_S):
        env = room(sweep)
        env.reset(seed=0, options={"robot_pose": [3.5, 3.5, 0.0]})
        moving[sweep], *_ = env.step(np.array([0.5, 1.0], dtype=np.float32))
        env.close()
    assert np.abs(moving[0.0]["lidar"] - moving[UTM_SWEEP_S]["lidar"]).max() > 1e-3


def test_a_swept_scan_is_determined_by_the_seed() -> None:
    def run(seed: int) -> np.ndarray:
        env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=12, lidar={"sweep_s": UTM_SWEEP_S})
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        out = []
        for _ in range(15):
            obs, *_ = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            out.append(obs["lidar"])
        env.close()
        return np.stack(out)

    assert np.array_equal(run(5), run(5))
    assert not np.array_equal(run(5), run(6))


def test_a_teleport_is_no_motion_within_the_sweep() -> None:
    """The world records the step's start after a teleport (a kidnap): the scan is not smeared across the jump."""
    env = room(UTM_SWEEP_S)
    env.reset(seed=0, options={"robot_pose": [2.0, 2.0, 0.0]})
    base = env.unwrapped
    base.world.set_robot_pose((5.0, 4.0, 1.0))
    state = base.state
    np.testing.assert_array_equal(state.robot_start, [5.0, 4.0, 1.0])
    obs, *_ = base.step(np.zeros(2, dtype=np.float32))
    angles = beam_angles(env)
    np.testing.assert_allclose(obs["lidar"], box_ranges(5.0, 4.0, 1.0 + angles, BARE_ROOM.size_m), atol=2e-5)
    env.close()


@pytest.mark.parametrize(
    ("sweep", "message"),
    [
        (-0.01, "lidar.sweep_s must be finite and >= 0 s, got -0.01"),
        (math.nan, "lidar.sweep_s must be finite and >= 0 s, got nan"),
        (0.04, "lidar.sweep_s = 0.04 s takes its beams over 0.03 s"),
    ],
)
def test_bad_sweeps_are_named(sweep: float, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace(".", r"\.").replace("(", r"\(")) as caught:
        gym.make("crowdloc/CrowdedRoom-v0", lidar={"sweep_s": sweep})
    if sweep == 0.04:
        assert "dt_s = 0.025 s" in str(caught.value)


def test_the_datasheet_sweeps_fit_their_worlds() -> None:
    """The UTM-30LX's 25 ms in the room (25 ms steps) and the VLP-16's 0.1 s on the campus (0.1 s steps)."""
    for env_id, sweep in (("crowdloc/CrowdedRoom-v0", 0.025), ("crowdloc/StereoCampus-v0", 0.1)):
        env = gym.make(env_id, lidar={"sweep_s": sweep})
        assert env.unwrapped.sensor_metadata["lidar"]["sweep_s"] == sweep
        env.close()
