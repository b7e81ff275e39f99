"""Queue heads give way to the robot (envs.crowds.steering.give_way): a head walking across the
room to the other queue curves around a robot standing in its path instead of shoving it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from envs.crowds.steering import give_way


def head_meets_robot(seed: int, give: bool) -> tuple[float, float, int]:
    """(closest centre distance, largest robot displacement, contacts) over 15 s with the robot
    standing at the world's mass on the line the left queue's head walks along. The queue does not
    see the robot otherwise (``sees_robot: 0``): only ``give`` decides whether the head avoids it."""
    env = gym.make("crowdloc/CrowdedRoom-v0", crowd_size=2, crowd={"queues": {"give_way": give, "sees_robot": 0.0}})
    env.reset(seed=seed, options={"robot_pose": [3.5, 6.4, 0.0]})
    world = env.unwrapped.world
    start = world.robot_pose[:2].copy()
    closest, moved, contacts = np.inf, 0.0, 0
    for _ in range(600):
        _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
        contacts += len(info["contacts"])
        closest = min(closest, float(np.hypot(*(world.positions[world.member_rows] - world.positions[0]).T).min()))
        moved = max(moved, float(np.hypot(*(world.robot_pose[:2] - start))))
    env.close()
    return closest, moved, contacts


@pytest.mark.parametrize("seed", [0, 2])
def test_a_queue_head_passes_around_the_robot(seed: int) -> None:
    closest, moved, contacts = head_meets_robot(seed, give=True)
    assert moved < 0.03  # the 30 kg robot is not shoved
    assert contacts == 0
    assert closest > 0.18 + 0.25 + 0.2  # it kept most of the 0.3 m margin
    assert closest < 2.0  # and it did pass close by (the set-up puts the robot on its way)


def test_without_giving_way_the_head_shoves_the_robot() -> None:
    _, moved, contacts = head_meets_robot(0, give=False)
    assert moved > 0.1 and contacts > 0


def test_give_way_turns_only_members_on_a_collision_course() -> None:
    pos = np.array([[0.0, 0.0], [0.0, 3.0]])
    want = np.array([[1.0, 0.0], [1.0, 0.0]])  # both walk +x; the robot stands at (2, 0)
    out = give_way(pos, want, np.full(2, 0.2), np.ones(2, dtype=np.bool_), np.array([2.0, 0.0]), np.zeros(2), 0.25, 0.3, 3.0)
    np.testing.assert_array_equal(out[1], want[1])  # 3 m to the side: unchanged
    assert np.hypot(*out[0]) == pytest.approx(1.0)  # same speed, turned
    # its new line passes the robot at the clearance 0.2 + 0.25 + 0.3
    d = out[0] / np.hypot(*out[0])
    p = np.array([2.0, 0.0])
    assert abs(p[0] * d[1] - p[1] * d[0]) == pytest.approx(0.75)
    inactive = give_way(pos, want, np.full(2, 0.2), np.zeros(2, dtype=np.bool_), p, np.zeros(2), 0.25, 0.3, 3.0)
    np.testing.assert_array_equal(inactive, want)


def test_bad_give_way_values_are_refused() -> None:
    from core.schema import ConfigError

    with pytest.raises(ConfigError, match="queues.give_way_margin_m must be finite and >= 0, got -1"):
        gym.make("crowdloc/CrowdedRoom-v0", crowd={"queues": {"give_way_margin_m": -1.0}})
    with pytest.raises(ConfigError, match="queues.give_way_horizon_s must be finite and > 0, got 0"):
        gym.make("crowdloc/CrowdedRoom-v0", crowd={"queues": {"give_way_horizon_s": 0.0}})
