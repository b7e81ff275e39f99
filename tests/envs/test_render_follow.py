"""The top view's follow mode (``view_m``): a fixed frame whose window follows the robot and stays
inside the world, on a 200 m x 120 m test world (tests/data/worlds/follow_view.yaml)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import numpy as np
import pygame
import pytest
from gymnasium.wrappers import RecordVideo, TimeLimit

import envs
from core.schema import ConfigError
from envs.config import LandmarkConfig, WorldConfig
from envs.localization_env import LocalizationEnv
from envs.palette import HIDDEN_LANDMARK, landmark_color
from envs.render import BACKGROUND, CAPTION_PX, ROBOT_FILL, Renderer, frame_shape
from envs.sensors import Lidar
from envs.view import background_size_px, drawn_bounds, fit

WORLD = Path(__file__).resolve().parents[1] / "data" / "worlds" / "follow_view.yaml"
MAGENTA = (255, 0, 255)
STILL = np.zeros(2, dtype=np.float32)
# the 40 m x 30 m window in a frame of 600 px: 14.2 px/m, margins of 16 px, the caption above
SCALE = 568 / 40
LEFT, TOP = 16, CAPTION_PX + 16
HEIGHT, WIDTH = 478, 600


def _env(**kwargs: Any) -> LocalizationEnv:
    return LocalizationEnv(str(WORLD), render_mode="rgb_array", **kwargs)


def _frame_at(env: LocalizationEnv, pose: tuple[float, float, float]) -> np.ndarray:
    env.reset(seed=0, options={"robot_pose": list(pose)})
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    return frame


def _centre_of(frame: np.ndarray, color: tuple[int, int, int]) -> tuple[float, float]:
    """``(column, row)`` of the middle of the bounding box of the pixels of ``color``."""
    rows, cols = np.nonzero(np.all(frame == np.array(color, dtype=np.uint8), axis=-1))
    assert rows.size, f"no pixel of {color}"
    return (0.5 * (cols.min() + cols.max()), 0.5 * (rows.min() + rows.max()))


def test_the_frame_has_a_fixed_shape_from_view_m() -> None:
    config = envs.load_world(WORLD)
    assert config.view_m == (40.0, 30.0)
    assert frame_shape(config) == (HEIGHT, WIDTH, 3)
    layout = fit(40.0, 30.0)
    assert (layout.scale, layout.width, layout.height, layout.left, layout.top) == pytest.approx(
        (SCALE, WIDTH, HEIGHT, LEFT, TOP)
    )
    env = _env()
    shapes = {_frame_at(env, pose).shape for pose in [(100.0, 60.0, 0.0), (1.0, 1.0, 0.0), (199.0, 119.0, 3.0)]}
    for _ in range(5):
        env.step(np.array([1.0, 0.3], dtype=np.float32))
        shapes.add(env.render().shape)
    assert shapes == {(HEIGHT, WIDTH, 3)}
    env.close()


def test_the_robot_is_drawn_at_the_frame_centre_away_from_the_edges() -> None:
    env = _env()
    for x, y in [(100.0, 60.0), (60.0, 40.0), (150.0, 95.0)]:
        frame = _frame_at(env, (x, y, 0.0))
        col, row = _centre_of(frame, ROBOT_FILL)
        assert col == pytest.approx(WIDTH / 2, abs=1.5) and row == pytest.approx(CAPTION_PX + (HEIGHT - CAPTION_PX) / 2, abs=1.5)
        renderer = env._renderer
        assert renderer.window_m == pytest.approx((x - 20.0, y - 15.0, x + 20.0, y + 15.0))
    env.close()


@pytest.mark.parametrize(
    ("pose", "window"),
    [
        ((3.0, 2.0), (0.0, 0.0, 40.0, 30.0)),
        ((199.0, 119.0), (160.0, 90.0, 200.0, 120.0)),
        ((5.0, 110.0), (0.0, 90.0, 40.0, 120.0)),
    ],
)
def test_the_window_stops_at_the_worlds_corners(pose: tuple[float, float], window: tuple[float, ...]) -> None:
    env = _env()
    frame = _frame_at(env, (*pose, 0.0))
    assert env._renderer.window_m == pytest.approx(window)
    x0, _, _, y1 = window
    # the robot is off-centre, where the window puts it
    col, row = _centre_of(frame, ROBOT_FILL)
    want = (LEFT + (pose[0] - x0) * SCALE, TOP + (y1 - pose[1]) * SCALE)
    assert (col, row) == pytest.approx(want, abs=1.5)
    assert math.hypot(col - WIDTH / 2, row - HEIGHT / 2) > 150
    # beyond the world's edge, in the margin, is the background colour
    edge_col = 3 if x0 == 0.0 else WIDTH - 4
    assert tuple(frame[HEIGHT // 2, edge_col]) == BACKGROUND
    env.close()


def test_a_landmark_appears_where_the_window_puts_it() -> None:
    env = _env()
    frame = _frame_at(env, (100.0, 60.0, 0.0))  # window x [80, 120], y [45, 75]
    p1 = env.world.landmark_names.index("P1")  # at (104, 62)
    col, row = math.floor(LEFT + (104.0 - 80.0) * SCALE), math.floor(TOP + (75.0 - 62.0) * SCALE)
    patch = {tuple(int(v) for v in p) for p in frame[row - 1 : row + 2, col - 1 : col + 2].reshape(-1, 3)}
    assert len(patch) == 1 and patch.pop() in (landmark_color(p1), HIDDEN_LANDMARK)
    assert tuple(env._renderer.to_pixel((104.0, 62.0))) == (col, row)
    # the robot 50 m away: P1 out of the window, the frame draws without it
    frame = _frame_at(env, (150.0, 60.0, 0.0))
    assert not np.any(np.all(frame == np.array(landmark_color(p1), dtype=np.uint8), axis=-1))
    env.close()


def test_overlays_and_sensors_draw_in_world_coordinates() -> None:
    env = _env()
    env.add_overlay(lambda canvas: canvas.circle(97.0, 57.0, 0.5, MAGENTA, 0))
    frame = _frame_at(env, (100.0, 60.0, 0.0))
    assert _centre_of(frame, MAGENTA) == pytest.approx((LEFT + 17.0 * SCALE, TOP + 18.0 * SCALE), abs=1.5)
    # the LIDAR's hits on the side of the building north of the robot (y = 70 m, x 90-110 m: 90 beams)
    rows, cols = np.nonzero(np.all(frame == np.array(Lidar.hit_color, dtype=np.uint8), axis=-1))
    on_side = np.abs(rows - (TOP + 5.0 * SCALE)) <= 2
    assert on_side.sum() >= 90
    assert cols[on_side].min() >= LEFT + 10.0 * SCALE - 2 and cols[on_side].max() <= LEFT + 30.0 * SCALE + 2
    env.close()


def test_to_pixel_of_a_fresh_renderer_maps_through_the_window_at_the_worlds_centre() -> None:
    renderer = Renderer(envs.load_world(WORLD), "rgb_array", 20)
    assert renderer.window_m == pytest.approx((80.0, 45.0, 120.0, 75.0))
    assert tuple(renderer.to_pixel((100.0, 60.0))) == (math.floor(LEFT + 20 * SCALE), math.floor(TOP + 15 * SCALE))
    renderer.look_at((1000.0, -1000.0))  # far outside: the window stops at the lower right corner
    assert renderer.window_m == pytest.approx((160.0, 0.0, 200.0, 30.0))


def test_a_world_narrower_than_the_window_is_centred_on_that_axis() -> None:
    # 200 m x 20 m: the window's height (30 m) exceeds the world's, which sits in its middle
    base = envs.load_world(WORLD)
    config = dataclasses.replace(
        base,
        size_m=(200.0, 20.0),
        landmarks=(LandmarkConfig("Q", 150.0, 10.0),),
        walls=(),
        crowds={},
        robot=dataclasses.replace(base.robot, start_pose=(150.0, 2.0, 0.0)),  # inside the narrower world
    )
    renderer = Renderer(config, "rgb_array", 20)
    renderer.look_at((150.0, 2.0))
    assert renderer.window_m == pytest.approx((130.0, -5.0, 170.0, 25.0))
    env = LocalizationEnv(config, render_mode="rgb_array")
    env.reset(seed=0, options={"robot_pose": [150.0, 2.0, 0.0]})
    frame = env.render()
    env.close()
    assert frame.shape == (HEIGHT, WIDTH, 3)
    assert tuple(frame[TOP + 2, WIDTH // 2]) == BACKGROUND  # above the world (y 25 -> 20 m)
    assert tuple(frame[HEIGHT - LEFT - 2, WIDTH // 2]) == BACKGROUND  # below it (y -5 -> 0 m)


def test_record_video_writes_an_mp4_in_follow_mode(tmp_path: Path) -> None:
    folder = tmp_path / "videos"
    env = RecordVideo(TimeLimit(_env(), max_episode_steps=20), video_folder=str(folder), episode_trigger=lambda e: e == 0)
    env.reset(seed=0)
    truncated = terminated = False
    while not (truncated or terminated):
        _, _, terminated, truncated, _ = env.step(np.array([1.0, 0.2], dtype=np.float32))
    env.close()
    video = folder / "rl-video-episode-0.mp4"
    assert video.is_file() and video.stat().st_size > 0


def test_human_mode_runs_headless_in_follow_mode() -> None:
    env = LocalizationEnv(str(WORLD), render_mode="human")
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([1.0, 0.2], dtype=np.float32))
    assert env.render() is None
    assert pygame.display.get_surface().get_size() == (WIDTH, HEIGHT)
    env.close()
    assert not pygame.display.get_init()


@pytest.mark.parametrize(
    "view", [[-40.0, 30.0], [40.0, 0.0], [float("nan"), 30.0], [40.0, float("inf")], [40.0], [40.0, 30.0, 1.0]]
)
def test_a_bad_view_m_is_refused_naming_it(view: list[float], tmp_path: Path) -> None:
    yaml_numbers = {"nan": ".nan", "inf": ".inf"}
    listed = ", ".join(yaml_numbers.get(repr(v), repr(v)) for v in view)
    path = tmp_path / "follow_view_bad.yaml"
    path.write_text(WORLD.read_text().replace("view_m: [40.0, 30.0]", f"view_m: [{listed}]"))
    with pytest.raises(ConfigError, match="view_m") as err:
        envs.load_world(path)
    # the world by its name (the range checks) or its file (a wrong length, the loader's check)
    assert "'follow_view'" in str(err.value) or str(path) in str(err.value)
    config = envs.load_world(WORLD)
    # (a NaN or inf is named by the finite check of every number: view_m[0] must be finite)
    with pytest.raises(ConfigError, match=r"world 'follow_view': view_m(\[\d\])? must be (two )?finite"):
        dataclasses.replace(config, view_m=tuple(view))


def test_a_view_too_small_for_the_world_is_refused_naming_the_size() -> None:
    config = envs.load_world(WORLD)
    # 2 m x 1.5 m of 200 m x 120 m: 284 px/m, a background of 56,880 px
    with pytest.raises(ConfigError, match=r"view_m = \[2.0, 1.5\] m is too small .* 56880 x 34160 px") as err:
        dataclasses.replace(config, view_m=(2.0, 1.5))
    assert "follow_view" in str(err.value) and "8000" in str(err.value)
    # the smallest view the message offers fits
    least = [float(v) for v in str(err.value).rsplit("[", 1)[1].split("]")[0].split(",")]
    assert dataclasses.replace(config, view_m=(least[0], least[1])).view_m == pytest.approx(least)
    # a campus of 150 m x 100 m at about 15 px/m: a background of about 2250 x 1500 px, fine
    pole = (LandmarkConfig("Q", 50.0, 50.0),)
    campus = dataclasses.replace(config, size_m=(150.0, 100.0), landmarks=pole, walls=(), crowds={}, view_m=(37.8, 36.0))
    scale = fit(*campus.view_m).scale
    assert scale == pytest.approx(15.0, rel=0.01)
    assert background_size_px(drawn_bounds(campus), scale) == (2254 + 80, 1503 + 80)  # the pad: 40 px a side


def test_without_view_m_the_whole_world_is_drawn_as_before() -> None:
    config: WorldConfig = dataclasses.replace(envs.load_world(WORLD), view_m=None)
    renderer = Renderer(config, "rgb_array", 20)
    assert renderer.window_m == (0.0, 0.0, 200.0, 120.0)
    assert max(frame_shape(config)[:2]) <= 600
