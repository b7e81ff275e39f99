"""Seeded layouts (envs/layouts.py): the soccer field's and the corridor's generators, their bounds, and the keyword."""

from __future__ import annotations

import dataclasses
import math
import os

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401
from core.schema import ConfigError
from envs.config import load_world
from envs.layouts import (
    ALONG_PATH_M,
    BUILDING_HEIGHT_M,
    BUILDING_INSET_M,
    BUILDING_INSET_SHARE,
    CAMPUS_GAP_M,
    CORNER_SHIFT_M,
    DISTRACTOR_ALONG_M,
    DISTRACTOR_OUT_M,
    DISTRACTOR_RADIUS_M,
    FACADE_SCALE,
    GOAL_WIDTH_M,
    LANE_HALF_WIDTH_M,
    POST_FROM_CORNER_M,
    layout_world,
    layout_worlds,
)

SOCCER = load_world("robocup_crowded")
CORNERS = ("L1", "L4", "L5", "L8")
GOALS = (("L2", "L3"), ("L7", "L6"))  # (left post, right post) on y = 0 and on y = 5


def _positions(config: object) -> dict[str, tuple[float, float]]:
    return {lm.name: (lm.x_m, lm.y_m) for lm in config.landmarks}  # type: ignore[attr-defined]


def test_no_layout_is_the_worlds_own() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0")
    assert env.unwrapped.layout is None and env.unwrapped.config == SOCCER
    env.close()


def test_a_layout_is_its_seeds_alone_and_seeds_differ() -> None:
    assert layout_world(SOCCER, 7) == layout_world(load_world("robocup_crowded"), 7)
    drawn = [tuple(sorted(_positions(layout_world(SOCCER, seed)).values())) for seed in range(50)]
    assert len(set(drawn)) == 50
    assert _positions(layout_world(SOCCER, 0)) != _positions(SOCCER)


@pytest.mark.parametrize("seed", range(0, 400, 7))
def test_soccer_layouts_keep_what_the_paper_fixes_and_vary_within_their_bounds(seed: int) -> None:
    world = layout_world(SOCCER, seed)
    x0, y0, x1, y1 = 0.0, 0.0, 5.0, 5.0
    # what stays: the field, the landmarks' names, kinds and radii, the distractors' count, the crowd
    assert world.size_m == SOCCER.size_m and world.robot == SOCCER.robot
    assert [(a.name, a.kind, a.radius_m) for a in world.landmarks] == [(a.name, a.kind, a.radius_m) for a in SOCCER.landmarks]
    assert len(world.sensors["camera"].distractors) == len(SOCCER.sensors["camera"].distractors)
    crowd, paper = world.crowds["soccer"], SOCCER.crowds["soccer"]
    assert (crowd.count, crowd.max_count, crowd.speed_mps) == (paper.count, paper.max_count, paper.speed_mps)
    at = _positions(world)
    widths = []
    for (left, right), line in zip(GOALS, (y0, y1), strict=True):
        (xa, ya), (xb, yb) = at[left], at[right]
        assert ya == yb == line
        widths.append(xb - xa)
        assert xa >= x0 + POST_FROM_CORNER_M - 1e-12 and xb <= x1 - POST_FROM_CORNER_M + 1e-12
    assert math.isclose(widths[0], widths[1]) and GOAL_WIDTH_M[0] <= widths[0] <= GOAL_WIDTH_M[1]
    for name in CORNERS:
        (x, y), (px, py) = at[name], _positions(SOCCER)[name]
        assert x == px and CORNER_SHIFT_M[0] <= abs(y - py) <= CORNER_SHIFT_M[1]
        assert y0 <= y <= y1  # moved along its side line, into the field's length
    for d in world.sensors["camera"].distractors:
        beyond = max(x0 - d.x_m, d.x_m - x1, y0 - d.y_m, d.y_m - y1)
        assert DISTRACTOR_OUT_M[0] - 1e-12 <= beyond <= DISTRACTOR_OUT_M[1] + 1e-12
        assert DISTRACTOR_RADIUS_M[0] <= d.radius_m <= DISTRACTOR_RADIUS_M[1] and d.landmark in at
        # by the landmark it imitates: out from a line that landmark is on, at most DISTRACTOR_ALONG_M along it
        lx, ly = at[d.landmark]
        if y0 <= d.y_m <= y1:  # beyond a side line: the landmark is on it
            assert lx == (x0 if d.x_m < x0 else x1) and abs(d.y_m - ly) <= DISTRACTOR_ALONG_M[1] + 1e-12
        else:  # beyond an end line
            assert ly == (y0 if d.y_m < y0 else y1) and abs(d.x_m - lx) <= DISTRACTOR_ALONG_M[1] + 1e-12
    assert [tuple(p) for p in crowd.keeper_posts] == [at["L7"], at["L6"]]  # the keeper keeps the far goal


def test_the_env_and_its_localizer_use_the_layout() -> None:
    env = gym.make("crowdloc/RoboCupCrowded-v0", layout=3, localizer="candidate_sets", camera={"noise_std_rad": 0.0})
    base = env.unwrapped
    assert base.layout == 3
    drawn = layout_world(SOCCER, 3)
    want = np.array([[lm.x_m, lm.y_m] for lm in drawn.landmarks])
    assert np.array_equal(base.landmark_map.positions_xy_m, want)
    assert np.array_equal(env.get_wrapper_attr("localizer")._map.positions_xy_m, want)
    assert base.config.sensors["camera"].noise_std_rad == 0.0  # the overrides apply on top
    env.reset(seed=0)
    for _ in range(20):
        env.step(env.action_space.sample())
    env.close()


def test_a_layout_steps_the_same_for_the_same_seeds() -> None:
    def run() -> list[float]:
        env = gym.make("crowdloc/RoboCupCrowded-v0", layout=11, crowd_size=10)
        env.reset(seed=5)
        env.action_space.seed(5)
        out = []
        for _ in range(30):
            obs, *_ = env.step(env.action_space.sample())
            out += obs["landmarks"].tolist()
        env.close()
        return out

    assert run() == run()


@pytest.mark.parametrize("bad", [-1, 1.5, "3", True, [3]])
def test_a_bad_layout_seed_is_refused_naming_it(bad: object) -> None:
    with pytest.raises(ConfigError, match=r"layout must be a layout seed, an integer >= 0, got"):
        gym.make("crowdloc/RoboCupCrowded-v0", layout=bad)


def test_a_world_without_a_generator_says_which_have_one() -> None:
    assert layout_worlds() == ("ceiling_corridor", "crowded_room", "robocup_crowded", "stereo_campus")
    with pytest.raises(
        ConfigError,
        match=r"world 'robocup_static' has no layout generator \(worlds with one: ceiling_corridor, crowded_room, robocup_crowded, stereo_campus\)",
    ):
        gym.make("crowdloc/RoboCupStatic-v0", layout=0)


# ---------------------------------------------------------------------------------------- corridor

CORRIDOR = load_world("ceiling_corridor")


def _wall_runs(config: object, side: float) -> list[tuple[float, float, float]]:
    """``(start, end, depth)`` of each run along the corridor where the first wall on ``side`` is not the
    straight wall, read by casting rays from the centre line every 5 mm (as the corridor crowd reads it)."""
    from core.raycast import cast_rays

    seg_a, seg_b = config.wall_segments()  # type: ignore[attr-defined]
    x0, y0, x1, y1 = config.field_m  # type: ignore[attr-defined]
    ys = np.arange(y0 + 0.0025, y1, 0.005)
    angle = np.array([0.0 if side > 0 else math.pi])
    none = np.zeros((0, 2)), np.zeros(0)
    depth = np.array([cast_rays(np.array([0.0, y]), angle, math.inf, seg_a, seg_b, *none)[0] for y in ys])
    runs, start = [], None
    for i, d in enumerate(depth):
        opening = d > 1.0 + 1e-6
        if opening and start is None:
            start = i
        if start is not None and (not opening or i == len(depth) - 1):
            runs.append((float(ys[start]), float(ys[i - 1]), float(np.median(depth[start:i]))))
            start = None
    return runs


@pytest.mark.parametrize("seed", range(12))
def test_corridor_layouts_keep_the_drive_and_vary_the_walls_targets_and_ceiling(seed: int) -> None:
    from envs.layouts import (
        ALCOVE_LENGTH_M,
        ALCOVES_PER_SIDE,
        LIGHT_PITCH_M,
        OPENING_GAP_M,
        RECESS_DEPTH_M,
        RECESS_WIDTH_M,
        RECESSES_PER_SIDE,
        SIGN_FROM_TARGET_M,
        SPRINKLER_PITCH_M,
        TARGET_SHIFT_M,
    )

    config = layout_world(CORRIDOR, seed)
    assert (config.size_m, config.origin_m, config.robot, config.goal, config.sensors, config.crowds) == (
        CORRIDOR.size_m, CORRIDOR.origin_m, CORRIDOR.robot, CORRIDOR.goal, CORRIDOR.sensors, CORRIDOR.crowds,
    )  # fmt: skip
    x0, y0, x1, y1 = config.field_m
    for side in (-1.0, 1.0):
        runs = _wall_runs(config, side)
        recesses = [r for r in runs if abs(r[2] - (1.0 + RECESS_DEPTH_M)) < 1e-6]
        alcoves = [r for r in runs if abs(r[2] - 1.6) < 1e-6]
        assert len(recesses) + len(alcoves) == len(runs)
        assert RECESSES_PER_SIDE[0] <= len(recesses) <= RECESSES_PER_SIDE[1]
        assert ALCOVES_PER_SIDE[0] <= len(alcoves) <= ALCOVES_PER_SIDE[1]
        assert all(abs(b - a - RECESS_WIDTH_M) < 0.01 for a, b, _ in recesses)
        assert all(ALCOVE_LENGTH_M[0] - 0.01 <= b - a <= ALCOVE_LENGTH_M[1] + 0.01 for a, b, _ in alcoves)
        starts = [a for a, _, _ in runs] + [y1 + OPENING_GAP_M]
        ends = [y0 - OPENING_GAP_M] + [b for _, b, _ in runs]
        assert all(s - e >= OPENING_GAP_M - 0.01 for s, e in zip(starts, ends))
    ceiling, paper = config.features["ceiling"], CORRIDOR.features["ceiling"]
    ys, paper_ys = [t.y_m for t in ceiling.targets], [t.y_m for t in paper.targets]
    assert ys[0] == paper_ys[0] and ys[-1] == paper_ys[-1] == config.goal.y_m
    assert all(abs(y - p) <= TARGET_SHIFT_M for y, p in zip(ys, paper_ys)) and ys != paper_ys
    assert [(t.name, t.a, t.b, t.c) for t in ceiling.targets] == [(t.name, t.a, t.b, t.c) for t in paper.targets]
    assert len(ceiling.signs) == len(paper.signs)
    for sign in ceiling.signs:
        assert abs(sign.x_m) == 0.5
        assert min(abs(sign.y_m - y) for y in ys[1:-1]) <= SIGN_FROM_TARGET_M[1] + 1e-9
        assert any(SIGN_FROM_TARGET_M[0] - 1e-9 <= abs(sign.y_m - y) <= SIGN_FROM_TARGET_M[1] + 1e-9 for y in ys[1:-1])
    assert LIGHT_PITCH_M[0] <= ceiling.light_pitch_m <= LIGHT_PITCH_M[1]
    assert SPRINKLER_PITCH_M[0] <= ceiling.sprinkler_pitch_m <= SPRINKLER_PITCH_M[1]
    assert 0 <= ceiling.light_first_y_m < ceiling.light_pitch_m and 0 <= ceiling.sprinkler_first_y_m < ceiling.sprinkler_pitch_m


def test_the_paper_corridor_reads_as_its_yaml_says() -> None:
    """The wall reader of the test above, on the paper's corridor: 3 recesses and 1 alcove on the left,
    2 and 2 on the right (one alcove at the field's start)."""
    left, right = _wall_runs(CORRIDOR, -1.0), _wall_runs(CORRIDOR, 1.0)
    assert [round(d, 2) for *_, d in left] == [1.25, 1.25, 1.6, 1.25]
    assert [round(d, 2) for *_, d in right] == [1.6, 1.25, 1.6, 1.25]


def test_the_corridor_env_and_its_localizer_use_the_layout() -> None:
    env = gym.make("crowdloc/CeilingCorridor-v0", layout=4, localizer="ceiling_target", crowd_size=10)
    env.reset(seed=2)
    ceiling = env.unwrapped.config.features["ceiling"]
    assert ceiling == layout_world(CORRIDOR, 4).features["ceiling"]
    (targets,) = env.get_wrapper_attr("localizer")._targets.values()
    np.testing.assert_allclose(targets.a_xy[:, 1], [t.y_m for t in ceiling.targets])
    for _ in range(20):
        env.step(env.action_space.sample())
    env.close()


@pytest.mark.parametrize(("layout", "seed"), [(5, 4), (53, 2)])
def test_a_corridor_whose_small_group_takes_the_only_fitting_alcove_places_the_large_ones_first(layout: int, seed: int) -> None:
    """On these layouts the listed order leaves a group of three no alcove (a pair took it): the groups are placed
    again, the largest first, and every one stands by a wall off the robot's lane."""
    env = gym.make("crowdloc/CeilingCorridor-v0", layout=layout, crowd_size=40)
    env.reset(seed=seed)
    crowds = env.unwrapped.world.crowds
    crowd = crowds["corridor"] if isinstance(crowds, dict) else next(c for c in crowds if c.name == "corridor")
    env.close()
    corridor = CORRIDOR.crowds["corridor"]
    assert crowd.spot.shape[0] == sum(crowd.sizes) >= 8
    assert np.all(np.abs(crowd.spot[:, 0] - corridor.centre_x_m) - corridor.radius_m >= corridor.clear_half_width_m)


# -------------------------------------------------------------------------------------------- room

ROOM = load_world("crowded_room")


def _segment_point_distance(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> float:
    t = np.clip(np.dot(p - a, b - a) / max(np.dot(b - a, b - a), 1e-12), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * (b - a))))


def _rect_distance(corners: np.ndarray, p: np.ndarray) -> float:
    """Distance from ``p`` to a convex quadrilateral (0 inside)."""
    edges = list(zip(corners, np.roll(corners, -1, axis=0)))
    cross = [(b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0]) for a, b in edges]
    if all(c >= 0 for c in cross) or all(c <= 0 for c in cross):
        return 0.0
    return min(_segment_point_distance(a, b, p) for a, b in edges)


@pytest.mark.parametrize("seed", range(0, 300, 11))
def test_room_layouts_keep_the_room_and_clear_the_robot_and_the_queues(seed: int) -> None:
    from envs.layouts import BEVEL_M, QUEUE_FROM_WALL_M, QUEUE_HEAD_FROM_WALL_M, QUEUE_SPACING_M, ROOM_CLEAR_M

    world = layout_world(ROOM, seed)
    # what stays: the room, the robot, the sensors, the pieces' kinds, sizes and heights, the crowd's numbers
    assert world.size_m == ROOM.size_m and world.robot == ROOM.robot and world.sensors == ROOM.sensors
    assert [(f.name, f.kind, f.size_m, f.height_m) for f in world.furniture] == [
        (f.name, f.kind, f.size_m, f.height_m) for f in ROOM.furniture
    ]
    for piece, paper in zip(world.furniture, ROOM.furniture, strict=True):
        assert math.isclose(math.hypot(*piece.map_offset_m), math.hypot(*paper.map_offset_m), abs_tol=1e-12)
    q, paper_q = world.crowds["queues"], ROOM.crowds["queues"]
    assert (q.count, q.max_count, q.radius_m, q.step_period_s) == (
        paper_q.count,
        paper_q.max_count,
        paper_q.radius_m,
        paper_q.step_period_s,
    )
    assert QUEUE_FROM_WALL_M[0] <= q.left_x_m <= QUEUE_FROM_WALL_M[1]
    assert QUEUE_FROM_WALL_M[0] <= 7.0 - q.right_x_m <= QUEUE_FROM_WALL_M[1]
    assert QUEUE_HEAD_FROM_WALL_M[0] <= 7.0 - q.head_y_m <= QUEUE_HEAD_FROM_WALL_M[1]
    assert QUEUE_SPACING_M[0] <= q.spacing_m <= QUEUE_SPACING_M[1]
    slots = np.arange(math.ceil(q.max_count / 2))
    places = [np.array([x, q.head_y_m - k * q.spacing_m]) for x in (q.left_x_m, q.right_x_m) for k in slots]
    assert min(p[1] for p in places) >= q.radius_m  # the longest queue ends inside the room
    clear = np.array(ROOM.robot.start_region_m) + np.array([-1, -1, 1, 1]) * ROOM_CLEAR_M
    for piece in world.furniture:
        corners = piece.footprint()
        assert np.all(corners >= -1e-9) and np.all(corners <= 7.0 + 1e-9)  # inside the room
        # out of the robot's middle (the task's square) and off every queue place at the largest crowd
        assert np.all(corners[:, 0] <= clear[0] + 0.03) or np.all(corners[:, 0] >= clear[2] - 0.03) or np.all(
            corners[:, 1] <= clear[1] + 0.03) or np.all(corners[:, 1] >= clear[3] - 0.03)  # fmt: skip
        assert min(_rect_distance(corners, p) for p in places) >= q.radius_m + 0.1
        if piece.kind == "box":  # its back against a wall
            assert min(corners[:, 0].min(), corners[:, 1].min(), 7.0 - corners[:, 0].max(), 7.0 - corners[:, 1].max()) < 1e-9
    for a, b in [(a, b) for i, a in enumerate(world.furniture) for b in world.furniture[i + 1 :]]:
        assert min(_rect_distance(a.footprint(), p) for p in b.footprint()) > 0.1  # apart
    bevel, door = (np.asarray(w) for w in world.walls)
    for leg in (abs(bevel[0] - bevel[2]), abs(bevel[1] - bevel[3])):  # a corner cut: one end on each of its walls
        assert BEVEL_M[0] <= leg <= BEVEL_M[1]
    for end in (bevel[:2], bevel[2:]):  # both ends on the room's walls
        assert min(end[0], end[1], 7.0 - end[0], 7.0 - end[1]) < 1e-9
    hinge, tip = door[:2], door[2:]
    assert min(hinge[0], hinge[1], 7.0 - hinge[0], 7.0 - hinge[1]) < 1e-9 and 0.7 <= np.linalg.norm(tip - hinge) <= 0.9
    assert min(_segment_point_distance(hinge, tip, p) for p in places) >= q.radius_m + 0.1


def test_room_layouts_differ_and_the_room_env_runs_on_one() -> None:
    drawn = {tuple((f.x_m, f.y_m) for f in layout_world(ROOM, seed).furniture) for seed in range(40)}
    assert len(drawn) == 40
    env = gym.make("crowdloc/CrowdedRoom-v0", layout=5, localizer="mcl_lidar", crowd_size=30)
    env.reset(seed=1)
    walls = env.get_wrapper_attr("localizer")._map.walls_m
    assert any(np.allclose(w, layout_world(ROOM, 5).walls[1]) for w in walls)  # the localizer's map has the layout's door
    for _ in range(40):
        env.step(env.action_space.sample())
    env.close()


def test_a_layouts_range_table_is_built_in_memory_and_the_worlds_own_is_cached(tmp_path, monkeypatch) -> None:
    from localizers.range_table import CACHE_ENV, build_range_table

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    own = gym.make("crowdloc/CrowdedRoom-v0").unwrapped.landmark_map
    drawn = gym.make("crowdloc/CrowdedRoom-v0", layout=2).unwrapped.landmark_map
    assert own.disk_cache and not drawn.disk_cache
    kwargs = {"resolution_m": 0.25, "directions": 16, "max_range_m": 30.0}
    table = build_range_table(drawn, **kwargs)
    assert list(tmp_path.iterdir()) == [] and not table.loaded
    assert not build_range_table(drawn, **kwargs).loaded  # built again: nothing kept on disk
    build_range_table(own, **kwargs)
    assert len(list(tmp_path.iterdir())) == 1 and build_range_table(own, **kwargs).loaded


# ------------------------------------------------------------------------------------------ campus

CAMPUS = load_world("stereo_campus")


def _dense(points: object, step: float = 0.02) -> np.ndarray:
    """A polyline sampled every ``step`` metres (the check below measures against these samples)."""
    pts = np.asarray(points, dtype=np.float64)
    out = [np.linspace(a, b, max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)) for a, b in zip(pts[:-1], pts[1:])]
    return np.concatenate(out)


def _inside_convex(corners: np.ndarray, p: np.ndarray, grow: float) -> bool:
    """Whether ``p`` is within ``grow`` of a convex polygon, by its edge half-planes moved out by ``grow``
    (a rounded corner counts as in: the check is the stricter for it)."""
    edges = np.roll(corners, -1, axis=0) - corners
    normals = np.stack([edges[:, 1], -edges[:, 0]], axis=1) / np.linalg.norm(edges, axis=1)[:, None]  # outward (ccw)
    return bool(np.all(np.einsum("ij,ij->i", p - corners, normals) <= grow))


@pytest.mark.parametrize("seed", range(0, 120, 10))
def test_campus_layouts_keep_the_route_and_the_crowd_and_vary_the_buildings_and_poles(seed: int) -> None:
    world = layout_world(CAMPUS, seed)
    # what stays: the field, the robot, the goal, the route, the crowd (walkways, lanes, parked cars)
    assert (world.size_m, world.robot, world.goal, world.crowds) == (CAMPUS.size_m, CAMPUS.robot, CAMPUS.goal, CAMPUS.crowds)
    assert world.features["route"] == CAMPUS.features["route"] and world.sensors == CAMPUS.sensors
    paper, drawn = CAMPUS.features["buildings"].items, world.features["buildings"].items
    assert [(b.name, b.doors) for b in drawn] == [(b.name, b.doors) for b in paper]
    facades = []
    for a, b in zip(paper, drawn, strict=True):
        lo, hi = a.corners.min(axis=0), a.corners.max(axis=0)
        cap = np.minimum(BUILDING_INSET_M, BUILDING_INSET_SHARE * (hi - lo)) + 1e-9
        moved_in = np.concatenate([b.corners.min(axis=0) - lo, hi - b.corners.max(axis=0)])
        assert np.all(moved_in >= -1e-9) and np.all(moved_in <= np.tile(cap, 2)), (a.name, moved_in)
        assert len(b.corners) == len(a.corners) and BUILDING_HEIGHT_M[0] <= b.height_m <= BUILDING_HEIGHT_M[1]
        # the same shape on its new box: each corner at the same share of the box
        share_a = (a.corners - lo) / (hi - lo)
        share_b = (b.corners - b.corners.min(axis=0)) / (b.corners.max(axis=0) - b.corners.min(axis=0))
        np.testing.assert_allclose(share_a, share_b, atol=1e-9)
        facades.append(b.facade)
    # the façades: the paper's, shuffled among the buildings, each one's horizontal sizes scaled alike
    used = set()
    for f in facades:
        twins = [k for k, g in enumerate(paper) if g.facade.wall_rgb == f.wall_rgb and k not in used]
        assert twins, f.wall_rgb
        used.add(twins[0])
        g = paper[twins[0]].facade
        widths = [(g.column_pitch_m, f.column_pitch_m), (g.window_pitch_m, f.window_pitch_m), (g.panel_m, f.panel_m),
                  (g.column_width_m, f.column_width_m), (g.window_size_m[0], f.window_size_m[0])]  # fmt: skip
        scales = {round(new / old, 9) for old, new in widths if old > 0}
        assert len(scales) == 1 and FACADE_SCALE[0] <= scales.pop() <= FACADE_SCALE[1]
        assert (f.floor_m, f.window_size_m[1], f.sill_m) == (g.floor_m, g.window_size_m[1], g.sill_m)
    # poles and trees: the paper's, each at most ALONG_PATH_M from its place and clear of paths, buildings, cars
    campus = CAMPUS.crowds["campus"]
    paths = [(_dense(w.points_m), w.width_m / 2) for w in campus.walkways]
    paths += [(_dense(lane.points_m), LANE_HALF_WIDTH_M) for lane in campus.lanes]
    for feature, radius in (("poles", "radius_m"), ("trees", "trunk_radius_m")):
        for a, b in zip(CAMPUS.features[feature].items, world.features[feature].items, strict=True):
            assert dataclasses.replace(b, x_m=a.x_m, y_m=a.y_m) == a
            p, r = np.array([b.x_m, b.y_m]), getattr(b, radius)
            if np.hypot(b.x_m - a.x_m, b.y_m - a.y_m) == 0:
                continue  # no free place found along its path: where the paper has it
            assert np.hypot(b.x_m - a.x_m, b.y_m - a.y_m) <= ALONG_PATH_M + 1e-9
            for samples, half in paths:
                assert np.min(np.linalg.norm(samples - p, axis=1)) >= half + r + CAMPUS_GAP_M - 0.02
            assert not any(_inside_convex(g.corners, p, r + CAMPUS_GAP_M - 1e-6) for g in drawn)
            assert all(np.hypot(x - b.x_m, y - b.y_m) > 2.3 + r for x, y, _ in campus.parked)


def test_campus_layouts_differ() -> None:
    drawn = {tuple(b.height_m for b in layout_world(CAMPUS, seed).features["buildings"].items) for seed in range(20)}
    assert len(drawn) == 20
    moved = [np.hypot(a.x_m - b.x_m, a.y_m - b.y_m) for a, b in
             zip(CAMPUS.features["poles"].items, layout_world(CAMPUS, 3).features["poles"].items)]  # fmt: skip
    assert sum(m > 0 for m in moved) > len(moved) // 2


def test_a_campus_layout_gets_its_own_scene_map_in_a_bounded_cache(tmp_path, monkeypatch) -> None:
    """The localizer's map of a layout is a drive on that layout, cached among the layouts' maps, of which the
    last used LAYOUT_MAPS_KEPT stay; the world's own map is not one of them."""
    import agents  # noqa: F401  (far_landmark_pf's default map)
    from agents.experiments import scene_maps
    from localizers.far_landmark_pf.scene_map import SceneMap
    from localizers.range_table import CACHE_ENV

    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    folder = tmp_path / "scene_maps" / "layouts"
    folder.mkdir(parents=True)
    own = tmp_path / "scene_maps" / "stereo_campus-own.npz"
    own.write_bytes(b"the world's own")
    for k in range(3):  # older layout maps
        (folder / f"stereo_campus-old{k}.npz").write_bytes(b"old")
        os.utime(folder / f"stereo_campus-old{k}.npz", (1000.0 + k, 1000.0 + k))
    monkeypatch.setattr(scene_maps, "LAYOUT_MAPS_KEPT", 2)
    env = gym.make("crowdloc/StereoCampus-v0", layout=4, localizer="far_landmark_pf")
    path = scene_maps.default_map_path(env.unwrapped)
    assert path.parent == folder and path.is_file()
    assert sorted(p.name for p in folder.iterdir()) == sorted([path.name, "stereo_campus-old2.npz"])  # the newest old one
    assert own.read_bytes() == b"the world's own"
    scenes = SceneMap.load(path)
    assert scenes.fingerprint == scene_maps.world_fingerprint(env.unwrapped)
    assert scenes.fingerprint != scene_maps.world_fingerprint(gym.make("crowdloc/StereoCampus-v0").unwrapped)
    env.reset(seed=0)
    for _ in range(20):
        env.step(np.zeros(2))
    env.close()
