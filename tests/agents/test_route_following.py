"""``route_follower``: pure pursuit along the campus route from the localizer's estimate, stopping
for what its LIDAR (or sonar) sees ahead, standing still without an estimate and at the end.

The drives run the whole 99 m route (about 1,100 steps at 1 m/s and dt 0.1 s), a second or two each.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import agents.policies.route_following as route_following
import envs  # noqa: F401  (registers crowdloc/*)
from agents.policies import FIXED_POLICIES, make_policy
from agents.policies.route_following import RouteFollower
from envs.config import load_world
from envs.wrappers import LocalizationObservation, encode_estimate
from localizers.base import PoseEstimate
from localizers.dead_reckoning import DeadReckoningLocalizer, DeadReckoningParams

CAMPUS = "crowdloc/StereoCampus-v0"
GOAL = np.array([50.0, 71.0])
EXACT_ODOMETRY = {
    "alpha1": 0.0, "alpha2": 0.0, "alpha3": 0.0, "alpha4": 0.0,
    "wheel_diameter_ratio": 1.0, "wheelbase_ratio": 1.0, "distance_scale": 1.0,
}  # fmt: skip
NO_SLIP = {"slip_per_accel_s2": 0.0, "slip_per_angular_accel_s2": 0.0, "slip_in_contact": 0.0}
ROBOT_R, PERSON_R = 0.3, 0.25


class OdometryOnly(DeadReckoningLocalizer):
    """``dead_reckoning`` for a world without a bearing camera: the registry binds the named
    localizer to bearing measurements, so the wrapper refuses it here; this one takes the
    LIDAR's scans and ignores them (the estimate is the odometry's, as dead reckoning's)."""

    measurement = "scan"

    def update(self, measurement: Any) -> None:
        self._require_reset()


def campus(**kwargs: Any) -> gym.Env[Any, Any]:
    """The campus with exact odometry, no slip and dead reckoning from the true start pose."""
    base = gym.make(CAMPUS, odometry=EXACT_ODOMETRY, robot=NO_SLIP, **kwargs)
    params = DeadReckoningParams(max_spread_m=math.inf)  # its drift model would stop claiming a pose after ~15 m
    localizer = OdometryOnly(base.unwrapped.landmark_map, params, dt_s=base.unwrapped.config.dt_s)  # type: ignore[attr-defined]
    return LocalizationObservation(base, localizer, None, "start")


@dataclasses.dataclass
class Drive:
    policy: RouteFollower
    actions: np.ndarray
    true_poses: np.ndarray
    observations: list[dict[str, np.ndarray]]
    contacts: list[Any]
    terminated: bool
    truncated: bool


def drive(env: gym.Env[Any, Any], seed: int = 0, during: Callable[[gym.Env[Any, Any], int], None] | None = None) -> Drive:
    policy = make_policy("route_follower", env)
    assert isinstance(policy, RouteFollower)
    obs, info = env.reset(seed=seed)
    actions, poses, observations, contacts = [], [info["true_pose"].copy()], [obs], []
    terminated = truncated = False
    while not (terminated or truncated):
        if during is not None:
            during(env, len(actions))
        action, state = policy.predict(obs, None, np.array([not actions]), deterministic=True)
        assert state is None and env.action_space.contains(action)
        obs, _, terminated, truncated, info = env.step(action)
        actions.append(action)
        poses.append(info["true_pose"].copy())
        observations.append(obs)
        contacts += info["contacts"]
    return Drive(policy, np.array(actions), np.array(poses), observations, contacts, terminated, truncated)


def route_distance(policy: RouteFollower, xy: np.ndarray) -> np.ndarray:
    """``(N,)`` each point's distance from the route's polyline."""
    a, b = policy.route[:-1], policy.route[1:]
    d = b - a
    t = np.clip(np.einsum("nkj,kj->nk", xy[:, None] - a[None], d) / np.einsum("kj,kj->k", d, d), 0.0, 1.0)
    return np.min(np.hypot(*(a[None] + t[..., None] * d[None] - xy[:, None]).transpose(2, 0, 1)), axis=1)


def test_the_follower_drives_the_whole_route_and_the_episode_ends_at_the_goal() -> None:
    env = campus(crowd_size=0)
    run = drive(env)
    p = run.policy
    assert run.terminated and not run.truncated
    assert p.phase == "done" and p.progress_m == pytest.approx(p.length_m, abs=0.06)
    assert p.length_m == pytest.approx(98.70, abs=0.01)  # 57 m, a 6-chord quarter circle of radius 3 m, 37 m
    # about the route's length at 1 m/s, with the acceleration, the turn and the slowing at the end
    assert 99 / 0.1 < len(run.actions) < 1.2 * 99 / 0.1
    assert np.linalg.norm(run.true_poses[-1, :2] - GOAL) < 0.1
    assert abs(run.true_poses[-1, 2] - math.pi / 2) < 0.02  # facing the library
    # the estimate is exact here, so the true path is the follower's: on the route throughout
    off = route_distance(p, run.true_poses[:, :2])
    assert off.max() < 0.15, off.max()
    # it cruised at 1 m/s, never faster, and stood still at the end (the goal's hold time)
    assert np.all(run.actions[:, 0] >= 0.0) and run.actions[:, 0].max() == pytest.approx(1.0)
    assert np.all(run.actions[-10:] == 0.0)
    assert not run.contacts and p.blocked_steps == 0


def test_a_person_standing_on_the_route_is_waited_for_then_passed_by_once_it_goes() -> None:
    # one person (no cars, no groups), held standing on the route's first leg 30 m ahead; once the
    # robot has stood still for 3 s, the person steps 6 m off the route
    env = campus(crowd_size=1, crowd={"campus": {"car_share": 0.0, "group_share": 0.0}})
    policy = make_policy("route_follower", env)
    assert isinstance(policy, RouteFollower)
    obs, info = env.reset(seed=0)
    world = env.unwrapped.world  # type: ignore[attr-defined]
    person = np.array([80.0, 31.0])
    world.place_crowd_member(0, tuple(person), hold=True)
    actions: list[np.ndarray] = []
    poses = [info["true_pose"].copy()]
    contacts: list[Any] = []
    moved_at = None
    terminated = truncated = False
    while not (terminated or truncated):
        if moved_at is None and len(actions) >= 30 and not np.any(actions[-30:]):
            world.place_crowd_member(0, (80.0, 37.0), hold=True)
            moved_at = len(actions)
        action, _ = policy.predict(obs, None, np.array([not actions]))
        obs, _, terminated, truncated, info = env.step(action)
        actions.append(action)
        poses.append(info["true_pose"].copy())
        contacts += info["contacts"]
    true = np.array(poses)
    assert moved_at is not None, "the robot never stopped for the person"
    # it stopped before the person, the gap about stop_m (its LIDAR at 0.8 m sees legs or torso
    # inside the footprint disc), touching nothing, and waited there
    gap = np.hypot(*(true[: moved_at + 1, :2] - person).T) - ROBOT_R - PERSON_R
    assert gap.min() > 0.4 and gap[-1] < policy.params.stop_m + 0.35, (gap.min(), gap[-1])
    assert true[moved_at, 0] > person[0]  # still on its side of the person
    assert not contacts
    assert policy.blocked_steps >= 30
    # and once the person has gone it drove on to the goal
    assert terminated and policy.phase == "done"
    assert np.linalg.norm(true[-1, :2] - GOAL) < 0.1


def test_a_world_without_a_route_is_refused() -> None:
    room = gym.make("crowdloc/CrowdedRoom-v0", localizer="mcl_lidar")
    with pytest.raises(ValueError, match="world 'crowded_room' has no route feature"):
        make_policy("route_follower", room)
    assert FIXED_POLICIES["route_follower"].unmet_need(load_world("crowded_room")) == (
        "a route feature",
        "its features: none",
    )
    assert FIXED_POLICIES["route_follower"].unmet_need(load_world("stereo_campus")) is None
    # the env without a localizer has no estimate to drive from: it says so
    plain = gym.make(CAMPUS)
    policy = make_policy("route_follower", plain)
    obs, _ = plain.reset(seed=0)
    with pytest.raises(KeyError, match="make the env with localizer"):
        policy.predict(obs)


def test_the_policy_reads_the_observation_only() -> None:
    # no reference to the env, its world or its info: make_policy hands it plain values
    env = campus(crowd_size=20)
    run = drive(env, seed=3)
    assert not any(isinstance(v, (gym.Env, gym.Wrapper)) for v in vars(run.policy).values())
    source = inspect.getsource(route_following)
    for word in ("info[", "true_pose", ".world", ".unwrapped", ".state"):
        assert word not in source, word
    # the same observations give the same actions from a fresh policy
    replay = make_policy("route_follower", env)
    actions = [replay.predict(obs, None, np.array([i == 0]))[0] for i, obs in enumerate(run.observations[:-1])]
    np.testing.assert_array_equal(np.array(actions), run.actions)


def observation(
    xy: tuple[float, float], heading: float, lidar: np.ndarray | None = None, valid: bool = True
) -> dict[str, np.ndarray]:
    """An observation with the estimate at ``xy``, ``heading`` on the campus and optionally a LIDAR scan."""
    bounds = (0.0, 0.0, 150.0, 100.0)
    obs = {
        "estimate": encode_estimate(PoseEstimate(xy[0], xy[1], heading, np.eye(3) * 1e-4, True), bounds),
        "estimate_valid": np.array([1.0 if valid else 0.0], np.float32),
        "estimate_spread": np.array([0.01, 0.01], np.float32),
    }
    if lidar is not None:
        obs["lidar"] = lidar.astype(np.float32)
    return obs


BEAMS = np.linspace(-math.pi, math.pi, 720, endpoint=False)
ROUTE = [(0.0, 50.0), (100.0, 50.0)]


def follower(**params: Any) -> RouteFollower:
    space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    return RouteFollower(space, ROUTE, (0.0, 0.0, 150.0, 100.0), beam_angles_rad=BEAMS, max_range_m=100.0, **params)


def scan_with(point: tuple[float, float] | None) -> np.ndarray:
    """A 360 deg scan (robot frame) seeing nothing but a 0.2 m disc at ``point``."""
    ranges = np.full(BEAMS.size, 100.0)
    if point is not None:
        x, y = point
        d, a = math.hypot(x, y), math.atan2(y, x)
        near = np.abs((BEAMS - a + math.pi) % (2 * math.pi) - math.pi) < math.asin(0.2 / d)
        ranges[near] = d - 0.2
    return ranges


@pytest.mark.parametrize(
    ("point", "expected"),
    [
        (None, "cruise"),
        ((8.0, 0.0), "cruise"),  # beyond slow_m
        ((2.5, 0.3), "slow"),  # in the corridor, 2.0 m from the robot's surface
        ((1.2, -0.2), "stop"),  # 0.7 m: inside stop_m
        ((1.2, 1.5), "cruise"),  # beside the corridor
        ((-1.0, 0.0), "cruise"),  # behind
    ],
)
def test_obstacles_in_the_corridor_ahead_slow_or_stop_the_robot(point: tuple[float, float] | None, expected: str) -> None:
    policy = follower()
    policy._speed_mps = 1.0  # already cruising
    action = policy._act(observation((10.0, 50.0), 0.0, scan_with(point)))
    if expected == "cruise":
        assert action[0] == pytest.approx(1.0)
    elif expected == "slow":
        assert 0.0 < action[0] < 0.9
    else:
        assert action.tolist() == [0.0, 0.0] and policy.blocked_steps == 1


def test_a_stopped_robot_waits_until_the_way_is_clear_by_the_resume_margin() -> None:
    policy = follower()
    policy._speed_mps = 1.0
    assert policy._act(observation((10.0, 50.0), 0.0, scan_with((1.2, 0.0))))[0] == 0.0  # 0.7 m: stop
    assert policy._act(observation((10.0, 50.0), 0.0, scan_with((1.38, 0.0))))[0] == 0.0  # 0.88 m: not yet clear
    moving = policy._act(observation((10.0, 50.0), 0.0, scan_with((1.6, 0.0))))  # 1.1 m: drives on, gently
    assert 0.0 < moving[0] <= policy.params.max_accel_mps2 * policy.params.dt_s + 1e-9


def test_the_corridor_follows_the_turn_it_drives() -> None:
    policy = follower()
    ahead = np.array([[3.0, 0.0]])
    # turning left on a 2 m radius: a point 3 m straight ahead is off the arc (1.6 m), one on the arc is in the way
    r = 2.0
    assert policy.gap_ahead(ahead, 1 / r) == math.inf
    on_arc = np.array([[r * math.sin(0.9), r - r * math.cos(0.9)]])
    assert policy.gap_ahead(on_arc, 1 / r) == pytest.approx(r * 0.9 - 0.3)
    assert policy.gap_ahead(on_arc * [1.0, -1.0], -1 / r) == pytest.approx(r * 0.9 - 0.3)  # turning right
    assert policy.gap_ahead(on_arc * [1.0, -1.0], 1 / r) == math.inf
    assert policy.gap_ahead(ahead, 0.0) == pytest.approx(2.7)  # driving straight


def test_with_max_turn_it_turns_no_faster_and_slows_in_the_bend_instead() -> None:
    """``max_turn`` (a scene map's drive on free-running webcams): the whole campus route with no command
    turning faster than the cap; the corner takes longer at a lower speed, and the route is still driven to its end."""
    fast = drive(campus(crowd_size=0))
    env = campus(crowd_size=0)
    policy = make_policy("route_follower", env, max_turn=0.1)
    obs, _ = env.reset(seed=0)
    actions, terminated, truncated = [], False, False
    while not (terminated or truncated):
        action, _ = policy.predict(obs, deterministic=True)
        obs, _, terminated, truncated, _ = env.step(action)
        actions.append(action)
    turns = np.abs(np.array(actions)[:, 1])
    assert terminated and turns.max() <= 0.1 + 1e-6
    assert np.abs(fast.actions[:, 1]).max() > 0.3  # uncapped, the corner is taken at three times that
    assert len(actions) > len(fast.actions) + 50  # the slow corner costs more than 5 s


def test_without_an_estimate_it_stands_still_or_coasts_for_coast_s() -> None:
    policy = follower()
    assert policy._act(observation((10.0, 50.0), 0.0, valid=False)).tolist() == [0.0, 0.0]
    assert policy.phase == "wait"
    coasting = follower(coast_s=0.25)
    for _ in range(5):
        going = coasting._act(observation((10.0, 50.0), 0.0))
    assert going[0] > 0
    kept = [coasting._act(observation((10.0, 50.0), 0.0, valid=False)) for _ in range(4)]
    np.testing.assert_array_equal(kept[0], going)
    np.testing.assert_array_equal(kept[1], going)
    assert kept[3].tolist() == [0.0, 0.0]  # after 0.25 s


def test_it_turns_in_place_toward_a_route_behind_it_and_ends_standing_at_the_last_point() -> None:
    policy = follower()
    action = policy._act(observation((10.0, 50.0), math.pi))  # facing away from the route's direction
    assert action[0] == 0.0 and abs(action[1]) == pytest.approx(1.0)
    done = follower()
    assert done._act(observation((99.97, 50.0), 0.0)).tolist() == [0.0, 0.0]
    assert done.phase == "done"
    assert done._act(observation((50.0, 50.0), 0.0)).tolist() == [0.0, 0.0]  # done stays done


def test_look_around_turns_first_then_drives_and_look_then_route_turns_twice() -> None:
    policy = follower(look_around_turns=0.5, dt_s=0.1, max_turn_rate_rps=1.0)  # pi rad at 1 rad/s: 32 steps of 0.1 s
    assert policy.phase == "look"
    turning = [policy._act(observation((10.0, 50.0), 0.0, valid=k % 2 == 0)) for k in range(32)]  # estimate or none
    assert all(a.tolist() == [0.0, 1.0] for a in turning)
    assert policy.phase == "wait" and policy.progress_m is None
    assert policy._act(observation((10.0, 50.0), 0.0))[0] > 0.0 and policy.phase == "drive"
    policy.reset()
    assert policy.phase == "look"  # again each episode
    assert follower().phase == "wait"  # route_follower does not look around
    room = gym.make("crowdloc/CrowdedRoom-v0", localizer="mcl_lidar")
    square = np.array([[2.25, 2.25], [4.75, 2.25], [4.75, 4.75]])
    made = make_policy("look_then_route", room, route=square)
    assert isinstance(made, route_following.LookThenRoute) and made.params.look_around_turns == 2.0
    assert made._look_steps == math.ceil(2 * 2 * math.pi / (1.5 * 0.025))  # the room turns at 1.5 rad/s, 40 Hz
    room.close()


def test_a_sonar_ring_is_read_when_there_is_no_lidar() -> None:
    space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    policy = RouteFollower(space, ROUTE, (0.0, 0.0, 150.0, 100.0), max_range_m=6.5)
    policy._speed_mps = 1.0
    sonar = np.full(16, 6.5, np.float32)
    obs = {**observation((10.0, 50.0), 0.0), "sonar": sonar}
    assert policy._act(obs)[0] == pytest.approx(1.0)
    sonar[0] = 0.9  # straight ahead, 0.6 m from the robot's surface
    assert policy._act(obs).tolist() == [0.0, 0.0]


@pytest.mark.parametrize(
    ("params", "words"),
    [
        ({"cruise": 1.5}, ["cruise", "1.5"]),
        ({"lookahead_m": 0.0}, ["lookahead_m", "0.0"]),
        ({"stop_m": 3.0}, ["stop_m (3.0) below slow_m (3.0)"]),
        ({"coast_s": -1.0}, ["coast_s", "-1.0"]),
        ({"look_around_turns": math.nan}, ["look_around_turns", "nan"]),
        ({"lookahed_m": 1.0}, ["'lookahed_m'"]),
        ({"creep": 0.8, "cruise": 0.5}, ["creep (0.8) at most cruise (0.5)"]),
        ({"max_turn": 0.0}, ["max_turn", "0.0"]),
        ({"max_turn": 1.5}, ["max_turn", "1.5"]),
        ({"sonar_rays": True}, ["sonar_rays", "True"]),
        ({"sonar_rays": 2.0}, ["sonar_rays", "2.0"]),
    ],
)
def test_bad_settings_are_refused_naming_them(params: dict[str, Any], words: list[str]) -> None:
    with pytest.raises(ValueError) as error:
        follower(**params)
    for word in words:
        assert word in str(error.value), (word, str(error.value))
    with pytest.raises(ValueError, match="at least two finite points"):
        RouteFollower(gym.spaces.Box(-1.0, 1.0, (2,), np.float32), [(0.0, 0.0)], (0.0, 0.0, 1.0, 1.0))


def test_a_numpy_integer_is_a_whole_number_of_sonar_rays() -> None:
    assert follower(sonar_rays=np.int64(3)).params.sonar_rays == 3


def test_a_route_following_policy_is_given_the_task_s_route_and_the_others_nothing() -> None:
    from agents.policies import task_route_kwargs

    points = ((2.25, 2.25), (4.75, 2.25))
    for name in ("route_follower", "look_then_route"):
        kwargs = task_route_kwargs(name, points)
        assert set(kwargs) == {"route"} and kwargs["route"].dtype == np.float64
        np.testing.assert_array_equal(kwargs["route"], points)
        assert task_route_kwargs(name, ()) == {}  # no points: the map's route
    assert task_route_kwargs("spin", points) == {} and task_route_kwargs("corridor_follower", points) == {}
