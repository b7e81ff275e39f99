"""Fixed policies: every one runs on every bearing env, stays in the action space, sees no truth."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from agents.policies import FIXED_POLICIES, GreedyInformationGain, PatrolPath, make_policy
from localizers.base import LandmarkMap

BEARING_IDS = ["crowdloc/RoboCupStatic-v0", "crowdloc/RoboCupCrowded-v0"]
#: every fixed policy but the corridor follower (it needs a sonar and a ceiling's targets: tests/agents/test_navigation.py)
#: and the route followers (they need a route: tests/agents/test_route_following.py)
BEARING_POLICIES = sorted(set(FIXED_POLICIES) - {"corridor_follower", "route_follower", "look_then_route"})


def test_the_policies_say_which_worlds_they_run_in() -> None:
    from agents.evaluate.spec import runnable_policies
    from envs import load_world

    for world in ("robocup_static", "robocup_crowded"):
        assert sorted(runnable_policies(load_world(world))) == BEARING_POLICIES
    corridor = load_world("ceiling_corridor")  # no bearing camera; a sonar and a ceiling
    assert runnable_policies(corridor) == ["random_walk", "spin", "stop_and_go", "patrol", "corridor_follower"]
    campus = load_world("stereo_campus")  # no bearing camera; a route
    assert runnable_policies(campus) == [
        "random_walk", "spin", "stop_and_go", "patrol", "route_follower", "look_then_route", "belief_greedy"
    ]  # fmt: skip
    assert FIXED_POLICIES["belief_greedy"].unmet_need(corridor) == (
        "a bearing_camera, lidar or stereo_camera sensor",
        "its sensors: odometry, sonar, camera",
    )
    assert FIXED_POLICIES["corridor_follower"].unmet_need(load_world("crowded_room")) == (
        "a sonar sensor",
        "its sensors: odometry, lidar",
    )


@pytest.mark.parametrize("name", BEARING_POLICIES)
@pytest.mark.parametrize("env_id", BEARING_IDS)
def test_every_fixed_policy_runs_on_every_bearing_env(env_id: str, name: str) -> None:
    env = gym.make(env_id, localizer="mcl_bearing")
    policy = make_policy(name, env, seed=0)
    obs, _ = env.reset(seed=0)
    episode_start = np.array([True])
    for _ in range(200):
        action, state = policy.predict(obs, None, episode_start, deterministic=True)
        episode_start = np.array([False])
        assert state is None
        assert env.action_space.contains(action), action
        obs, _, terminated, truncated, _ = env.step(action)
        assert not terminated
    env.close()


@pytest.mark.parametrize("name", ["landmark_seeking", "greedy_info_gain"])
def test_map_policies_run_with_a_sonar_ring_and_a_narrow_camera(name: str) -> None:
    env = gym.make(
        "crowdloc/RoboCupCrowded-v0", localizer="candidate_sets", crowd_size=10, sonar={}, camera={"fov_rad": math.pi / 2}
    )
    policy = make_policy(name, env, seed=0)
    obs, _ = env.reset(seed=0)
    for _ in range(150):
        action, _ = policy.predict(obs, deterministic=True)
        assert env.action_space.contains(action), action
        obs, *_ = env.step(action)
    env.close()


def test_a_planning_policy_without_a_localizer_says_what_is_missing() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    policy = make_policy("greedy_info_gain", env)
    obs, _ = env.reset(seed=0)
    with pytest.raises(KeyError, match="localizer"):
        policy.predict(obs)


def test_unknown_policy_and_bad_settings_name_the_value() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    with pytest.raises(ValueError, match="wander"):
        make_policy("wander", env)
    with pytest.raises(ValueError, match="1.5"):
        make_policy("random_walk", env, speed=1.5)
    with pytest.raises(ValueError, match="SpinInPlace turn must be a number in .* got True"):
        make_policy("spin", env, turn=True)  # a bool is no command, though True == 1
    with pytest.raises(ValueError, match="segment 1"):
        PatrolPath.from_segments(env.action_space, [(0.5, 0.0, 10), (0.0, 0.2, 0)])
    with pytest.raises(ValueError, match="action 1"):
        PatrolPath(env.action_space, [[0.5, 0.0], [1.5, 0.0]])


def test_patrol_drives_the_exp1_path_through_every_vertex_and_closes_it() -> None:
    from agents.policies.paths import EXP1_VERTICES

    env = gym.make("crowdloc/RoboCupStatic-v0", odometry={"alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0})
    policy = make_policy("patrol", env)
    obs, info = env.reset(seed=0)
    visited = []
    for _ in range(len(policy.actions)):
        obs, _, _, _, info = env.step(policy.predict(obs)[0])
        visited.append(info["true_pose"].copy())
    visited = np.array(visited)
    for name, vertex in EXP1_VERTICES.items():
        assert np.min(np.linalg.norm(visited[:, :2] - vertex, axis=1)) < 1e-6, name
    np.testing.assert_allclose(info["true_pose"], [2.5, 8.0, 0.0], atol=1e-6)  # back at a, facing +x


def test_greedy_information_gain_prefers_the_motion_that_uncovers_landmarks() -> None:
    # four landmarks in a square; only two are seen now, from the middle of the left edge.
    landmarks = LandmarkMap(np.array([[0.0, 0.0], [0.0, 4.0], [4.0, 0.0], [4.0, 4.0]]), ("a", "b", "c", "d"), (0, 0, 4, 4))
    from gymnasium import spaces

    policy = GreedyInformationGain(spaces.Box(-1, 1, (2,), np.float32), landmarks, max_speed_mps=1.0, max_turn_rate_rps=1.0)
    pose = np.array([1.0, 2.0, 0.0])
    seen = np.array([True, True, False, False])
    ends = policy.end_poses(pose)
    visible = policy.expected_visible(pose, ends[:, :2], seen)
    standing = int(np.flatnonzero((policy.candidates[:, 0] == 0) & (policy.candidates[:, 1] == 0))[0])
    # standing still cannot uncover the hidden pair; driving a metre toward them turns their lines of sight
    assert visible[standing].tolist() == [True, True, False, False]
    forward = int(np.flatnonzero((policy.candidates[:, 0] == 1) & (policy.candidates[:, 1] == 0))[0])
    assert visible[forward].all()
    obs = {
        "landmarks": np.array([1, math.cos(-2.0), math.sin(-2.0), 1, math.cos(2.0), math.sin(2.0), 0, 0, 0, 0, 0, 0], np.float32),
        "estimate": np.array([-0.5, 0.0, 1.0, 0.0], np.float32),
        "estimate_valid": np.ones(1, np.float32),
        "estimate_spread": np.array([0.05, 0.05], np.float32),
    }
    action, _ = policy.predict(obs)
    assert action[0] > 0  # it moves rather than standing still


def test_greedy_information_gain_turns_a_narrow_camera_toward_the_landmarks() -> None:
    # landmarks only on the left (x = 0); the robot in the middle faces +x with a 90 deg camera
    landmarks = LandmarkMap(np.array([[0.0, 1.0], [0.0, 2.0], [0.0, 3.0]]), ("a", "b", "c"), (0, 0, 4, 4))
    from gymnasium import spaces

    space = spaces.Box(-1, 1, (2,), np.float32)
    policy = GreedyInformationGain(space, landmarks, max_speed_mps=1.0, max_turn_rate_rps=3.0, fov_rad=math.pi / 2)
    pose = np.array([2.0, 2.0, 0.0])
    seen = np.zeros(3, dtype=bool)  # nothing in view: none of them is known to be hidden
    ends = policy.end_poses(pose)
    visible = policy.expected_visible(pose, ends[:, :2], seen, ends[:, 2])
    standing = int(np.flatnonzero((policy.candidates[:, 0] == 0) & (policy.candidates[:, 1] == 0))[0])
    assert not visible[standing].any()  # still facing away
    full_turn = int(np.flatnonzero((policy.candidates[:, 0] == 0) & (policy.candidates[:, 1] == 1))[0])
    assert visible[full_turn].all()  # 3 rad of turn brings all three into the 90 deg view
    obs = {
        "landmarks": np.zeros(9, np.float32),
        "estimate": np.array([0.0, 0.0, 1.0, 0.0], np.float32),  # (2, 2) facing +x
        "estimate_valid": np.ones(1, np.float32),
        "estimate_spread": np.array([0.05, 0.05], np.float32),
    }
    action, _ = policy.predict(obs)
    assert abs(action[1]) == 1.0  # a full-rate turn
    with pytest.raises(ValueError, match="headings"):
        policy.expected_visible(pose, ends[:, :2], seen)
    with pytest.raises(ValueError, match="fov_rad"):
        GreedyInformationGain(space, landmarks, fov_rad=0.0)


def test_map_policies_do_not_drive_into_what_the_sonar_reads() -> None:
    # the first greedy test's situation (it drives forward to uncover the hidden pair), now
    # with a robot 0.3 m straight ahead on sonar sensor 0 of 12
    landmarks = LandmarkMap(np.array([[0.0, 0.0], [0.0, 4.0], [4.0, 0.0], [4.0, 4.0]]), ("a", "b", "c", "d"), (0, 0, 4, 4))
    from gymnasium import spaces

    from agents.policies import LandmarkSeeking

    space = spaces.Box(-1, 1, (2,), np.float32)
    greedy = GreedyInformationGain(space, landmarks, max_speed_mps=1.0, max_turn_rate_rps=1.0)
    obs = {
        "landmarks": np.array([1, math.cos(-2.0), math.sin(-2.0), 1, math.cos(2.0), math.sin(2.0), 0, 0, 0, 0, 0, 0], np.float32),
        "estimate": np.array([-0.5, 0.0, 1.0, 0.0], np.float32),
        "estimate_valid": np.ones(1, np.float32),
        "estimate_spread": np.array([0.05, 0.05], np.float32),
    }
    assert greedy.predict(obs)[0].tolist() == [1.0, 0.0]  # straight ahead, without a sonar
    sonar = np.full(12, 2.0, np.float32)
    sonar[0] = 0.3
    ahead = {**obs, "sonar": sonar}
    # within 45 deg of sensor 0 (at 0 deg) is obstructed, beyond it is not
    assert greedy.blocked(ahead, [0.0, 0.7, -0.7, 0.9, math.pi / 2, math.pi]).tolist() == [True, True, True, False, False, False]
    assert not greedy.blocked(obs, [0.0]).any()
    v, w = greedy.predict(ahead)[0]
    mid_arc = 0.5 * w * greedy.max_turn_rate_rps * greedy.horizon_s
    assert v == 0 or not greedy.blocked(ahead, mid_arc)
    assert [v, w] != [1.0, 0.0]
    seeking = LandmarkSeeking(space, landmarks)
    assert seeking.predict(obs)[0][0] > 0
    walled_in = {**obs, "sonar": np.full(12, 0.3, np.float32)}
    assert seeking.predict(walled_in)[0][0] == 0  # turns in place at most
    with pytest.raises(ValueError, match="clearance_m must be >= 0, got -1"):
        LandmarkSeeking(space, landmarks, clearance_m=-1)


def test_make_policy_reads_the_camera_field_of_view() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", localizer="candidate_sets", camera={"fov_rad": 1.5})
    assert make_policy("greedy_info_gain", env).fov_rad == 1.5
    assert make_policy("landmark_seeking", env).fov_rad == 1.5
    env.close()


def test_policies_are_seeded() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", localizer="mcl_bearing")
    obs, _ = env.reset(seed=0)
    a = [make_policy("random_walk", env, seed=3).predict(obs)[0] for _ in range(1)]
    b = [make_policy("random_walk", env, seed=3).predict(obs)[0] for _ in range(1)]
    np.testing.assert_array_equal(a, b)
