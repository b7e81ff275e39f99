"""The corridor crowd: walkers both ways and groups standing by the walls of the ceiling corridor.

Nothing here depends on which sensors the world has, beyond odometry in the push test.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import envs  # noqa: F401  (registers crowdloc/*)
from core.schema import ConfigError
from envs.crowds import CorridorConfig, CorridorCrowd
from envs.crowds.corridor import group_ring
from envs.localization_env import LocalizationEnv

ENV_ID = "crowdloc/CeilingCorridor-v0"
STILL = np.zeros(2, dtype=np.float32)


def make(count: int, seed: int, **crowd: Any) -> tuple[gym.Env, CorridorCrowd]:
    env = gym.make(ENV_ID, crowd_size=count, crowd={"corridor": crowd} if crowd else None)
    env.reset(seed=seed)
    crowd_obj = env.unwrapped.world.crowds["corridor"]
    assert isinstance(crowd_obj, CorridorCrowd)
    return env, crowd_obj


def roaming_actions(seed: int, steps: int, hold: int = 40) -> np.ndarray:
    """Random actions held for ``hold`` steps each: the robot wanders about and meets people."""
    rng = np.random.default_rng(seed)
    return np.repeat(rng.uniform(-1, 1, size=(steps // hold + 1, 2)), hold, axis=0)[:steps].astype(np.float32)


def in_open_space(env: gym.Env, xy: np.ndarray) -> np.ndarray:
    """``(N,)`` whether each point can be reached straight across from the corridor's centre line
    without crossing a wall: inside the corridor, a door recess or an alcove, never in the
    closed voids behind the walls (every recess and alcove is a rectangle open to the corridor)."""
    config = env.unwrapped.config
    walls = np.asarray(config.walls, dtype=np.float64)
    a, b = walls[:, None, :2], walls[:, None, 2:]
    p = np.stack([np.zeros(len(xy)), xy[:, 1]], axis=1)[None]  # from (0, y) ...
    q = xy[None]  # ... to the point
    (x0, y0, x1, y1) = config.field_m

    def cross(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (w[..., 0] - u[..., 0])

    crosses = (np.sign(cross(a, b, p)) * np.sign(cross(a, b, q)) < 0) & (np.sign(cross(p, q, a)) * np.sign(cross(p, q, b)) < 0)
    inside = (xy[:, 0] > x0) & (xy[:, 0] < x1) & (xy[:, 1] > y0) & (xy[:, 1] < y1)
    return inside & ~crosses.any(axis=0)


def wall_clearance(env: gym.Env, xy: np.ndarray) -> np.ndarray:
    """``(N,)`` distance from each point to the nearest wall or boundary segment."""
    world = env.unwrapped.world
    d = world.seg_b - world.seg_a
    rel = xy[:, None, :] - world.seg_a[None]
    t = np.clip(np.sum(rel * d[None], axis=2) / np.sum(d * d, axis=1), 0.0, 1.0)
    return np.min(np.linalg.norm(rel - t[..., None] * d[None], axis=2), axis=1)


def gaps(xy: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Surface-to-surface gaps of every pair of discs."""
    g = np.linalg.norm(xy[:, None] - xy[None], axis=-1) - (radii[:, None] + radii[None])
    return g[~np.eye(len(radii), dtype=bool)]


def test_the_world_uses_the_corridor_crowd() -> None:
    default = gym.make(ENV_ID)
    default.reset(seed=0)
    assert default.unwrapped.world.member_rows.size == 0  # the paper's empty corridor unless asked
    default.close()
    env, crowd = make(20, seed=0)
    config = env.unwrapped.config.crowds["corridor"]
    assert isinstance(config, CorridorConfig) and list(env.unwrapped.config.crowds) == ["corridor"]
    assert crowd.walkers == 20 and crowd.standing == sum(config.sizes) == 8  # groups of 3, 2, 3
    assert crowd.count == 28 and env.unwrapped.world.member_rows.tolist() == list(range(1, 29))
    assert np.all(env.unwrapped.world.radii_m[1:] == 0.2)
    env.close()


@pytest.mark.parametrize(("count", "seed"), [(20, 0), (20, 1), (40, 2), (40, 3), (5, 4)])
def test_nobody_overlaps_anybody_or_a_wall_at_reset(count: int, seed: int) -> None:
    env, crowd = make(count, seed)
    world = env.unwrapped.world
    np.testing.assert_allclose(world.robot_pose, [0.0, 0.0, math.pi / 2], atol=1e-12)  # the start pose is kept
    assert np.all(gaps(world.positions, world.radii_m) > 0)
    people = world.positions[crowd.member_rows]
    assert in_open_space(env, people).all()
    assert np.all(wall_clearance(env, people) > 0.2)
    walkers = people[: crowd.walkers]
    assert np.all(np.abs(walkers[:, 0]) < 1.0 - 0.2)  # walkers start in the corridor proper ...
    assert np.ptp(walkers[:, 1]) > 0.5 * 25.0 * (1 - 2 / max(count, 2))  # ... spread over its length
    # standing people keep the robot's drive line free and stand by a wall
    standing = people[crowd.walkers :]
    assert np.all(np.abs(standing[:, 0]) - 0.2 >= 0.3 - 1e-9)
    for g in range(len(crowd.sizes)):
        assert wall_clearance(env, standing[crowd.group_of == g]).min() < 0.2 + 0.1
    env.close()


def test_walkers_stay_inside_the_corridor() -> None:
    env, crowd = make(20, seed=5)
    world = env.unwrapped.world
    rows = crowd.member_rows
    for step, action in enumerate(roaming_actions(5, 3000)):
        env.step(action)
        people = world.positions[rows]
        ok = in_open_space(env, people)
        assert ok.all(), (step, np.flatnonzero(~ok), people[~ok])
        # pressed against a wall by the crowd, a disc may dent it by millimetres, never pass it
        assert wall_clearance(env, people).min() > 0.2 - 0.03, step
        assert np.all(np.abs(people[: crowd.walkers, 0]) < 1.6 - 0.2)
    env.close()


def crossings(track: np.ndarray, y: float) -> np.ndarray:
    """``(steps - 1, N)``: +1 where a walker walked across ``y`` toward +y that step, -1 toward
    -y (a re-entry at the other end jumps across it and is not counted)."""
    above = track[:, :, 1] > y
    walked = np.linalg.norm(np.diff(track, axis=0), axis=2) < 1.0
    return (above[1:].astype(int) - above[:-1].astype(int)) * walked


def test_both_directions_flow_steadily() -> None:
    env, crowd = make(20, seed=6)
    config = env.unwrapped.config.crowds["corridor"]
    assert (crowd.direction > 0).sum() == 10 and (crowd.direction < 0).sum() == 10  # plus_y_share 0.5
    direction = crowd.direction.copy()
    steps = 6001  # 300 s: each walker walks the corridor about a dozen times
    track = np.empty((steps, crowd.walkers, 2))
    for i in range(steps):
        env.step(STILL)
        track[i] = env.unwrapped.world.positions[crowd.member_rows][: crowd.walkers]
    np.testing.assert_array_equal(crowd.direction, direction)  # nobody turns round
    crossed = crossings(track, 10.5)
    assert np.all((crossed > 0) <= (direction > 0)) and np.all((crossed < 0) <= (direction < 0))  # each its own way
    windows = 6  # 50 s each: about 20 crossings each way in each
    for way in (1, -1):
        per_window = (crossed == way).reshape(windows, -1, crowd.walkers).sum(axis=(1, 2))
        assert per_window.min() >= 10, (way, per_window)
        assert per_window.max() <= 2.5 * per_window.min(), (way, per_window)
        # the walkers of each way stay spread along the corridor: the middle third holds its share
        mine = track[1:, direction == way, 1]
        middle = ((mine > 6.3) & (mine < 14.7)).mean(axis=1)  # a third of the walkable length
        per_window_share = middle.reshape(windows, -1).mean(axis=1)
        assert np.all(per_window_share > 0.15) and np.all(per_window_share < 0.55), (way, per_window_share)
    # they walk at about their desired speeds (1.0-1.4 m/s) despite the traffic
    step_len = np.linalg.norm(np.diff(track, axis=0), axis=2)
    walking = step_len[step_len < 1.0]  # re-entries are jumps
    lo, hi = config.walk_speed_mps
    assert 0.8 * lo < np.median(walking) / env.unwrapped.config.dt_s < hi
    env.close()


def test_walkers_keep_to_their_right() -> None:
    env, crowd = make(20, seed=7)
    steps = 2000
    xs = np.empty((steps, crowd.walkers))
    for i in range(steps):
        env.step(STILL)
        xs[i] = env.unwrapped.world.positions[crowd.member_rows][: crowd.walkers, 0]
    right = np.sign(xs) == crowd.direction  # toward +y the right is +x
    assert right.mean() > 0.85, right.mean()
    env.close()


def test_standing_groups_stay_near_their_spots() -> None:
    env, crowd = make(20, seed=8)
    config = env.unwrapped.config.crowds["corridor"]
    world = env.unwrapped.world
    spots = crowd.spot.copy()
    w = crowd.walkers
    steps = 3000
    off = np.empty((steps, crowd.standing))
    speed = np.empty((steps, crowd.standing))
    for i in range(steps):
        env.step(STILL)
        off[i] = np.linalg.norm(world.positions[crowd.member_rows][w:] - spots, axis=1)
        speed[i] = np.linalg.norm(world.velocities[crowd.member_rows][w:], axis=1)
    np.testing.assert_array_equal(crowd.spot, spots)  # the spots stay where they were
    assert np.median(off) < config.fidget_m + 0.02
    assert np.quantile(off, 0.99) < 0.3 and off.max() < 0.8  # walkers brush past, never take them away
    assert np.median(speed) < 0.1  # mostly still ...
    assert np.all(np.ptp(off, axis=0) > 0.005)  # ... fidgeting
    # turned toward each other: each faces its group's centre
    facing = crowd.facing_rad(env.unwrapped.state)[w:]
    to_centre = crowd.group_centre[crowd.group_of] - world.positions[crowd.member_rows][w:]
    np.testing.assert_allclose(facing, np.arctan2(to_centre[:, 1], to_centre[:, 0]))
    env.close()


def test_group_rings() -> None:
    np.testing.assert_allclose(group_ring(1, 0.55, 0.0), [[0.0, 0.0]])
    two = group_ring(2, 0.55, 0.0)  # side by side along the wall, facing each other
    np.testing.assert_allclose(two, [[0.0, 0.275], [0.0, -0.275]], atol=1e-12)
    three = group_ring(3, 0.55, 0.3)
    d = np.linalg.norm(three[:, None] - three[None], axis=-1)
    np.testing.assert_allclose(d[~np.eye(3, dtype=bool)], 0.55)


def test_same_seed_same_crowd() -> None:
    def run(seed: int) -> np.ndarray:
        env, crowd = make(20, seed)
        for action in roaming_actions(seed, 500):
            env.step(action)
        out = env.unwrapped.world.positions.copy()
        env.close()
        return out

    first = run(11)
    np.testing.assert_array_equal(first, run(11))
    assert not np.allclose(first, run(12))


def test_the_same_env_replays_a_seed() -> None:
    env, crowd = make(20, seed=3)
    for _ in range(300):
        env.step(STILL)
    after = env.unwrapped.world.positions.copy()
    env.reset(seed=3)
    for _ in range(300):
        env.step(STILL)
    np.testing.assert_array_equal(after, env.unwrapped.world.positions)
    env.close()


@pytest.mark.parametrize(
    ("behind_m", "crowd"),
    [
        (0.6, {"sees_robot": 0.0}),  # an inattentive walker too close to stop or step aside
        (2.0, {"detour_ahead_m": 0.0, "robot_repulsion_gain": 0.0, "sees_robot": 0.0}),  # one that does not avoid the robot
    ],
)
def test_a_walker_pushes_a_stopped_robot(behind_m: float, crowd: dict) -> None:
    env, people = make(1, seed=0, groups=0, plus_y_share=1.0, **crowd)
    world = env.unwrapped.world
    lane = float(people.lane_x_m[0])
    start = np.array([lane, 10.0, math.pi / 2])
    world.set_robot_pose(start)
    world.place_body(int(people.rows[0]), (lane, 10.0 - behind_m), velocity=(0.0, float(people.walk_speed_mps[0])))
    odometry = env.unwrapped.sensor_of_type("odometry")
    assert odometry is not None
    read = 0.0
    touched = False
    for _ in range(100):
        obs, _, _, _, info = env.step(STILL)
        read = max(read, float(np.abs(obs[odometry.key]).max()))
        touched |= any(c.other == "crowd" for c in info["contacts"])
    moved = world.robot_pose - start
    assert touched
    assert moved[1] > 0.02, moved  # shoved along the walker's way ...
    assert read < 1e-9  # ... which odometry never sees
    assert world.positions[people.rows[0], 1] > 10.5  # and the walker went on past
    env.close()


def test_gymnasium_check_env_with_a_crowd() -> None:
    env = gym.make(ENV_ID, crowd_size=20)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("error")
        gym_check_env(env.unwrapped, skip_render_check=True)
    assert caught == []
    env.close()


def test_count_zero_is_an_empty_corridor() -> None:
    env, crowd = make(0, seed=0)
    assert crowd.count == 0 and env.unwrapped.world.member_rows.size == 0
    for action in roaming_actions(0, 200):
        obs, _, _, _, info = env.step(action)
        assert env.observation_space.contains(obs)
        assert not [c for c in info["contacts"] if c.other == "crowd"]
    env.close()


def test_groups_zero_leaves_the_walkers() -> None:
    env = LocalizationEnv("ceiling_corridor", crowd_size=3, crowd={"corridor": {"groups": 0}})
    env.reset(seed=1)
    crowd = env.world.crowds["corridor"]
    assert crowd.count == crowd.walkers == 3 and crowd.standing == 0
    for _ in range(100):
        env.step(STILL)
    assert in_open_space(env, env.world.positions[crowd.member_rows]).all()
    env.close()


def test_a_single_walker_each_way_share() -> None:
    # plus_y_share 0 and 1 send everyone one way; the share holds to a walker
    for share, way in ((0.0, -1.0), (1.0, 1.0)):
        env, crowd = make(7, seed=2, plus_y_share=share)
        assert np.all(crowd.direction == way)
        env.close()
    env, crowd = make(7, seed=2, plus_y_share=0.3)
    assert (crowd.direction > 0).sum() in (2, 3)
    env.close()


def test_the_renderer_draws_the_crowd() -> None:
    env = gym.make(ENV_ID, crowd_size=10, render_mode="rgb_array")
    env.reset(seed=0)
    env.step(STILL)
    frame = env.render()
    assert frame is not None and frame.ndim == 3
    standing = np.array(CorridorCrowd.standing_fill, dtype=np.uint8)
    walking = np.array(CorridorCrowd.fill, dtype=np.uint8)
    assert np.all(frame == standing, axis=-1).any() and np.all(frame == walking, axis=-1).any()
    env.close()


@pytest.mark.parametrize(
    ("overrides", "fragments"),
    [
        ({"walk_speed_mps": [1.4, 1.0]}, ["walk_speed_mps", "(1.4, 1.0)"]),
        ({"walk_speed_mps": [0.0, 1.0]}, ["walk_speed_mps", "(0.0, 1.0)"]),
        ({"plus_y_share": 1.5}, ["plus_y_share", "1.5"]),
        ({"lane_offset_m": [0.5, 0.9]}, ["lane_offset_m", "(0.5, 0.9)", "0.8"]),
        ({"lane_offset_m": [-0.1, 0.5]}, ["lane_offset_m", "(-0.1, 0.5)"]),
        ({"half_width_m": 0.1}, ["half_width_m", "0.1"]),
        ({"groups": -1}, ["groups", "-1"]),
        ({"group_sizes": []}, ["group_sizes", "()"]),
        ({"group_sizes": [2, 0]}, ["group_sizes", "(2, 0)"]),
        ({"group_spacing_m": 0.3}, ["group_spacing_m", "0.3"]),
        ({"clear_half_width_m": 1.0}, ["clear_half_width_m", "1.0"]),
        ({"fidget_period_s": [0.0, 2.0]}, ["fidget_period_s", "(0.0, 2.0)"]),
        ({"fidget_m": -0.1}, ["fidget_m", "-0.1"]),
        ({"relaxation_s": 0.0}, ["relaxation_s", "0.0"]),
        ({"lookahead_m": -1.0}, ["lookahead_m", "-1.0"]),
        ({"robot_repulsion_gain": -2.0}, ["robot_repulsion_gain", "-2.0"]),
        ({"detour_ahead_m": -1.0}, ["detour_ahead_m", "-1.0"]),
        ({"count": 41}, ["count", "41", "[0, 40]"]),
        ({"mass_kg": 0.0}, ["mass_kg", "0.0"]),
        ({"plus_y_share": "half"}, ["plus_y_share", "'half'"]),
        ({"desired_speed_mps": 1.2}, ["desired_speed_mps", "walk_speed_mps"]),  # the walkers' field, not ours
        ({"half_width_m": 2.0}, ["half_width_m", "field", "-1.6"]),  # wider than the world's field
        ({"end_margin_m": 13.0}, ["end_margin_m", "13.0"]),
    ],
)
def test_bad_config_values_are_refused_by_name(overrides: dict, fragments: list[str]) -> None:
    with pytest.raises(ConfigError) as exc:
        LocalizationEnv("ceiling_corridor", crowd={"corridor": overrides})
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_too_many_groups_say_what_to_change() -> None:
    env = LocalizationEnv("ceiling_corridor", crowd_size=1, crowd={"corridor": {"groups": 12, "group_sizes": [3]}})
    with pytest.raises(RuntimeError, match=r"no room by the walls for standing group \d+ \(3 people\).*groups, group_sizes"):
        env.reset(seed=0)
