"""belief_greedy (agents/policies/belief_greedy.py): the motion after which the localizer's belief is expected
to narrow most, from the belief alone."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium import spaces

import agents  # noqa: F401
from agents.policies import make_policy
from agents.policies.belief_greedy import (
    BeliefGreedy,
    bearing_predictor,
    expected_entropy,
    range_predictor,
    scene_bearing_predictor,
)
from core.schema import ConfigError
from localizers.far_landmark_pf.scene_map import SceneMap

BOX = spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)


def test_readings_that_tell_hypotheses_apart_leave_no_entropy_and_equal_ones_leave_it_all() -> None:
    same = np.zeros((6, 4))
    assert expected_entropy(same, 0.02, circular=True) == pytest.approx(math.log(6))
    apart = np.arange(6, dtype=float)[:, None] * np.ones((6, 4))
    assert expected_entropy(apart, 0.02, circular=False) == pytest.approx(0.0, abs=1e-9)
    # angles wrap: readings of -pi + 0.001 and pi - 0.001 are 0.002 apart, not 2 pi
    near = np.array([[-math.pi + 0.001], [math.pi - 0.001]])
    assert expected_entropy(near, 0.02, circular=True) == pytest.approx(math.log(2), abs=1e-3)
    # one hypothesis seeing a landmark the other does not is told apart too
    assert expected_entropy(np.array([[0.1], [np.nan]]), 0.02, circular=True) < math.log(2)


def test_it_turns_the_way_that_tells_twins_apart() -> None:
    """Two hypotheses at one place facing 0 and 90 deg; a landmark 2 m below, out of a 90 deg camera's view from
    both. Turning right brings it into view of the first alone; turning left, into neither's."""
    twins = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2]])
    predict = bearing_predictor(np.array([[0.0, -2.0]]), math.pi / 2, 10.0)
    policy = BeliefGreedy(BOX, lambda: (twins, np.array([0.5, 0.5])), predict, 0.02, True, (-5.0, -5.0, 5.0, 5.0),
                          seed=0, hypotheses=16, speeds=(0.0,), turns=(-1.0, 0.0, 1.0))  # fmt: skip
    scores = policy.scores(twins[np.array([0, 1] * 8)], {})
    assert scores[0] < scores[1] == pytest.approx(scores[2])
    action, _ = policy.predict({})
    assert action.tolist() == [0.0, -1.0]


def test_its_action_is_the_beliefs_not_the_truths() -> None:
    """The policy reads the belief, the sonar and the map: the same belief gives the same action wherever the robot
    really is (the env's true pose lives in info only)."""
    env = gym.make("crowdloc/CrowdedRoom-v0", localizer="mcl_lidar", crowd_size=0)
    policy_a = make_policy("belief_greedy", env, seed=1)
    obs_a, _ = env.reset(seed=4, options={"robot_pose": (2.8, 3.5, 0.3)})
    frozen = env.get_wrapper_attr("localizer").overlay()
    belief = (np.asarray(frozen.poses).copy(), np.asarray(frozen.weights).copy())
    policy_a.belief = lambda: belief
    first = policy_a.predict(obs_a)[0].tolist()
    obs_b, _ = env.reset(seed=9, options={"robot_pose": (4.5, 2.6, -1.0)})  # the truth moves; the belief handed in does not
    policy_b = make_policy("belief_greedy", env, seed=1)
    policy_b.belief = lambda: belief
    assert policy_b.predict(obs_b)[0].tolist() == first
    env.close()


@pytest.mark.parametrize(
    ("env_id", "localizer", "kwargs"),
    [
        ("crowdloc/RoboCupCrowded-v0", "candidate_sets", {"camera": {"fov_rad": math.pi / 2}, "prior": "none"}),
        ("crowdloc/RoboCupCrowded-v0", "mcl_bearing", {"prior": "none"}),
        ("crowdloc/CrowdedRoom-v0", "mcl_lidar", {"prior": "none"}),
        ("crowdloc/StereoCampus-v0", "far_landmark_pf", {}),
    ],
)
def test_it_drives_a_world_on_its_localizers_sensor_the_same_for_the_same_seed(env_id: str, localizer: str, kwargs: dict) -> None:
    def run() -> list[list[float]]:
        env = gym.make(env_id, localizer=localizer, crowd_size=4, **kwargs)
        obs, _ = env.reset(seed=2)
        policy = make_policy("belief_greedy", env, seed=2)
        out = []
        for _ in range(150):
            action, _ = policy.predict(obs)
            out.append(action.tolist())
            obs, *_ = env.step(action)
        env.close()
        return out

    first = run()
    assert first == run() and len({tuple(a) for a in first}) > 1  # deterministic, and it does more than one thing


def test_the_range_predictor_reads_the_walls() -> None:
    walls = np.array([[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 4.0], [4.0, 4.0, 0.0, 4.0], [0.0, 4.0, 0.0, 0.0]])
    predict = range_predictor(walls, np.array([0.0, math.pi / 2]), 3.0)
    ranges = predict(np.array([[1.0, 1.0, 0.0], [3.0, 1.0, 0.0]]))
    np.testing.assert_allclose(ranges[0], [np.nan, np.nan])  # 3 m and 3 m: at the maximum, nothing read
    np.testing.assert_allclose(ranges[1], [1.0, np.nan])


def test_the_scene_predictor_reads_the_landmarks_of_the_scenes_nearest_the_hypotheses() -> None:
    """Scene 0 at the origin holds landmarks 10 m east and 10 m north, scene 1 (50 m east, facing
    north) one 5 m ahead of it: a 60 deg camera sees each from the pose facing it, the landmarks no
    pose sees are left out, and hypotheses by scene 1 read scene 1's landmark alone."""
    scenes = SceneMap(poses=np.array([[0.0, 0.0, 0.0], [50.0, 0.0, math.pi / 2]]), first=np.array([0, 2, 3]),
                      types=np.array([0, 1, 0]), relative_xy=np.array([[10.0, 0.0], [0.0, 10.0], [5.0, 0.0]]),
                      world="test", fingerprint="test")  # fmt: skip
    predict = scene_bearing_predictor(scenes, 1, 10.0, math.radians(60.0), 1.0, 100.0)
    facing = predict(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2]]))
    np.testing.assert_allclose(facing, [[0.0, np.nan], [np.nan, 0.0]], atol=1e-12)
    askew = predict(np.array([[0.0, 0.0, 0.2], [0.0, 0.0, 0.2]]))  # only the east one in view, 0.2 rad to the right
    np.testing.assert_allclose(askew, [[-0.2], [-0.2]], atol=1e-12)
    assert predict(np.array([[9.5, 0.0, 0.0]])).shape == (1, 0)  # 0.5 m from the east one: nearer than min_range_m
    by_scene_1 = predict(np.array([[50.0, 1.0, math.pi / 2 + 0.1]]))  # scene 1's landmark at (50, 5), 4 m ahead
    np.testing.assert_allclose(by_scene_1, [[-0.1]], atol=1e-12)
    assert predict(np.array([[25.0, 0.0, 0.0]])).shape == (1, 0)  # no scene within 10 m


def test_without_a_localizer_it_says_what_it_needs() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    with pytest.raises(ConfigError, match="belief_greedy reads the localizer's belief: make the env with a localizer"):
        make_policy("belief_greedy", env)
    env.close()


def test_it_plans_every_replan_steps_and_holds_the_motion_between() -> None:
    calls = []
    twins = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.pi / 2]])

    def belief() -> tuple[np.ndarray, np.ndarray]:
        calls.append(1)
        return twins, np.array([0.5, 0.5])

    predict = bearing_predictor(np.array([[0.0, -2.0]]), math.pi / 2, 10.0)
    policy = BeliefGreedy(BOX, belief, predict, 0.02, True, (-5.0, -5.0, 5.0, 5.0), seed=0, replan_steps=5)
    actions = [policy.predict({})[0].tolist() for _ in range(10)]
    assert len(calls) == 2 and actions[:5] == [actions[0]] * 5
    with pytest.raises(ConfigError, match="replan_steps must be an integer >= 1, got 0"):
        BeliefGreedy(BOX, belief, predict, 0.02, True, (-5.0, -5.0, 5.0, 5.0), replan_steps=0)
