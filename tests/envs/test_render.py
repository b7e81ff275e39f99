"""Rendering: frame shape, landmark visibility colours, overlays, human mode, video recording, and the
shipped worlds' frames as recorded before the follow mode (tests/envs/test_render_follow.py)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pygame
import pytest
from gymnasium.wrappers import RecordVideo

import envs
from envs.palette import HIDDEN_LANDMARK, landmark_color
from envs.render import Canvas, Renderer, frame_shape
from localizers.base import Overlay

ENV_IDS = list(envs.ENV_WORLDS)
FRAMES = Path(__file__).resolve().parents[1] / "data" / "pinned" / "render_frames.json"
MAGENTA = (255, 0, 255)
CYAN = (0, 255, 255)
STILL = np.zeros(2, dtype=np.float32)
# spots on the empty robocup_static field (no crowd, robot starts at (2.5, 8.0))
SPOT_A = (1.0, 2.0)
SPOT_B = (4.0, 2.0)


def _static_env(**kwargs: Any) -> gym.Env[Any, Any]:
    return gym.make("crowdloc/RoboCupStatic-v0", render_mode="rgb_array", **kwargs)


def _pixel(env: gym.Env[Any, Any], frame: np.ndarray, xy: tuple[float, float]) -> tuple[int, ...]:
    """Colour of ``frame`` at world point ``xy`` (the layout depends on the world config only)."""
    col, row = Renderer(env.unwrapped.config, "rgb_array", 30).to_pixel(xy)
    return tuple(int(v) for v in frame[row, col])


def _render_with(draw: Any, **kwargs: Any) -> tuple[gym.Env[Any, Any], np.ndarray]:
    env = _static_env(**kwargs)
    env.reset(seed=0)
    env.unwrapped.add_overlay(draw)
    frame = env.render()
    assert isinstance(frame, np.ndarray)
    return env, frame


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_rgb_array_frames_have_the_declared_shape(env_id: str) -> None:
    env = gym.make(env_id, render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    kept = first.copy()
    env.step(np.array([1.0, 0.5], dtype=np.float32))
    second = env.render()
    env.close()

    shape = frame_shape(env.unwrapped.config)
    assert first.shape == second.shape == shape
    assert first.dtype == np.uint8
    # the top view is about 600 px on its long side; sensors' panels (the campus's camera strip) come under it
    panels = sum(sensor.panel_height_px(shape[1]) for sensor in env.unwrapped.config.sensors.values())
    assert 560 <= max(shape[0] - panels, shape[1]) <= 600
    assert shape[0] % 2 == 0 and shape[1] % 2 == 0  # H.264 needs even sizes
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 5
    assert not np.array_equal(first, second)  # the robot moved and the clock advanced
    assert np.array_equal(first, kept)  # a returned frame is not overwritten by the next one
    first[0, 0] = 0  # and it is the caller's to annotate


def test_world_y_axis_points_up_on_screen() -> None:
    renderer = Renderer(envs.load_world("robocup_static"), "rgb_array", 30)
    origin, up, right = renderer.to_pixel([[0.0, 0.0], [0.0, 1.0], [1.0, 0.0]])
    assert up[1] < origin[1] and up[0] == origin[0]
    assert right[0] > origin[0] and right[1] == origin[1]
    assert right[0] - origin[0] == pytest.approx(renderer.scale, abs=1)


def test_occluded_landmark_is_grey_and_visible_landmarks_are_coloured() -> None:
    env = _static_env(crowd_size=1)
    env.reset(seed=0, options={"robot_pose": [2.5, 8.0, 0.0]})
    world = env.unwrapped.world
    l7 = world.landmark_names.index("L7")
    l6 = world.landmark_names.index("L6")

    # the only crowd member stands halfway between the robot and L7
    world.place_crowd_member(0, (2.0, 9.0))
    _, _, _, _, info = env.step(STILL)
    assert not info["visible_landmarks"][l7] and info["visible_landmarks"][l6]
    frame = env.render()
    assert _pixel(env, frame, tuple(world.landmark_xy[l7])) == HIDDEN_LANDMARK
    assert _pixel(env, frame, tuple(world.landmark_xy[l6])) == landmark_color(l6)

    # moved out of the way, L7 is seen and drawn in its colour
    world.place_crowd_member(0, (4.0, 1.0))
    _, _, _, _, info = env.step(STILL)
    assert info["visible_landmarks"][l7]
    frame = env.render()
    assert _pixel(env, frame, tuple(world.landmark_xy[l7])) == landmark_color(l7)
    assert landmark_color(l7) != HIDDEN_LANDMARK
    env.close()


def test_a_narrow_camera_draws_the_edges_of_its_view() -> None:
    from envs.sensors.bearing_camera import SIGHT_LINE

    frames = {}
    for fov in (2 * np.pi, np.pi / 2):
        env = _static_env(crowd_size=0, camera={"fov_rad": fov})
        env.reset(seed=0, options={"robot_pose": [2.5, 5.0, 0.0]})
        frames[fov] = env.render()
        # around a point on the left edge of a 90 deg view facing +x, 2.8 m out (a 1-pixel line)
        col, row = Renderer(env.unwrapped.config, "rgb_array", 30).to_pixel((4.5, 7.0))
        patch = frames[fov][row - 1 : row + 2, col - 1 : col + 2].reshape(-1, 3)
        assert any(tuple(p) == SIGHT_LINE for p in patch) == (fov < 2 * np.pi)
        env.close()


def test_overlay_is_called_with_a_canvas_and_drawn() -> None:
    calls: list[Any] = []

    def draw(canvas: Canvas) -> None:
        calls.append(canvas)
        canvas.circle(*SPOT_A, 0.2, MAGENTA, width_px=0)
        canvas.points(np.array([SPOT_B]), CYAN, size_px=3)

    env, frame = _render_with(draw)
    assert len(calls) == 1 and isinstance(calls[0], Canvas)
    assert _pixel(env, frame, SPOT_A) == MAGENTA
    assert _pixel(env, frame, SPOT_B) == CYAN
    env.render()
    assert len(calls) == 2  # every frame
    env.unwrapped.remove_overlay(draw)
    frame = env.render()
    assert len(calls) == 2 and _pixel(env, frame, SPOT_A) != MAGENTA
    env.close()


@pytest.mark.parametrize("count", [5, 3600])  # pygame.draw path and numpy path
def test_canvas_poses_are_shaded_by_weight(count: int) -> None:
    heavy = np.tile([*SPOT_A, 0.3], (count, 1))
    light = np.tile([*SPOT_B, 0.3], (count, 1))
    weights = np.r_[np.ones(count), np.zeros(count)]

    env, frame = _render_with(lambda c: c.poses(np.vstack([heavy, light]), weights, MAGENTA))
    env_plain, plain = _render_with(lambda c: None)
    assert _pixel(env, frame, SPOT_A) == MAGENTA
    faint = _pixel(env, frame, SPOT_B)
    floor = _pixel(env_plain, plain, SPOT_B)
    assert faint not in (MAGENTA, floor)
    # a low weight stays closer to the floor than to the full colour
    assert np.abs(np.subtract(faint, floor)).sum() < np.abs(np.subtract(faint, MAGENTA)).sum()
    env.close()
    env_plain.close()


def test_canvas_overlay_draws_an_overlay_dataclass_and_its_label() -> None:
    rng = np.random.default_rng(0)
    poses = np.column_stack([rng.uniform(0.5, 4.5, 1000), rng.uniform(0.5, 6.0, 1000), rng.uniform(-3, 3, 1000)])
    ov = Overlay(poses=poses, weights=rng.random(1000), points_xy=np.array([SPOT_B]), label="mcl")

    env, frame = _render_with(lambda c: c.overlay(ov, CYAN))
    env_plain, plain = _render_with(lambda c: None)
    assert _pixel(env, frame, SPOT_B) == CYAN
    field = (slice(40, -40), slice(40, -40))
    assert (np.abs(frame[field].astype(int) - plain[field]).sum(axis=2) > 0).sum() > 1000  # the particles
    caption = slice(0, 20)
    assert not np.array_equal(frame[caption], plain[caption])  # the label
    env.close()
    env_plain.close()


def test_canvas_text_and_pose_draw_on_the_frame() -> None:
    def draw(canvas: Canvas) -> None:
        canvas.pose(*SPOT_A, 0.0, MAGENTA, radius_m=0.3)
        canvas.line(SPOT_B, (SPOT_B[0], SPOT_B[1] + 1.0), CYAN, width_px=3)
        canvas.text("estimate", CYAN)

    env, frame = _render_with(draw)
    env_plain, plain = _render_with(lambda c: None)
    # the heading line runs from the centre along +x
    assert _pixel(env, frame, (SPOT_A[0] + 0.2, SPOT_A[1])) == MAGENTA
    assert _pixel(env, frame, (SPOT_B[0], SPOT_B[1] + 0.5)) == CYAN
    assert not np.array_equal(frame[:20], plain[:20])
    env.close()
    env_plain.close()


def test_canvas_skips_non_finite_poses() -> None:
    def draw(canvas: Canvas) -> None:
        canvas.pose(np.nan, np.nan, np.nan, MAGENTA)
        canvas.poses(np.array([[np.nan, 1.0, 0.0], [*SPOT_A, 0.0]]), None, MAGENTA)
        canvas.points(np.array([[np.inf, 0.0]]), MAGENTA)

    env, frame = _render_with(draw)
    assert _pixel(env, frame, SPOT_A) == MAGENTA
    env.close()


def test_canvas_poses_reject_mismatched_weights() -> None:
    canvas = Renderer(envs.load_world("robocup_static"), "rgb_array", 30).canvas()
    with pytest.raises(ValueError, match="3 poses but 2 weights"):
        canvas.poses(np.zeros((3, 3)), np.ones(2), MAGENTA)


@pytest.mark.parametrize(("mode", "fps", "message"), [("ansi", 30, "render_mode must be"), ("human", 0, "fps must be > 0")])
def test_renderer_rejects_bad_arguments(mode: str, fps: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Renderer(envs.load_world("robocup_static"), mode, fps)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_human_mode_runs_headless_and_closes(env_id: str) -> None:
    env = gym.make(env_id, render_mode="human")
    env.reset(seed=0)
    for _ in range(3):
        env.step(np.array([0.5, 0.2], dtype=np.float32))  # steps draw the window themselves
    assert env.render() is None
    assert pygame.display.get_init() and pygame.display.get_surface() is not None
    env.close()
    assert not pygame.display.get_init()


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_record_video_writes_an_mp4(env_id: str, tmp_path: Path) -> None:
    folder = tmp_path / "videos"  # a fresh folder: RecordVideo warns when it overwrites one
    env = RecordVideo(
        gym.make(env_id, render_mode="rgb_array", max_episode_steps=20),
        video_folder=str(folder),
        episode_trigger=lambda episode: episode == 0,
    )
    env.reset(seed=0)
    truncated = terminated = False
    while not (truncated or terminated):
        _, _, terminated, truncated, _ = env.step(np.array([0.5, 0.2], dtype=np.float32))
    env.close()
    video = folder / "rl-video-episode-0.mp4"
    assert video.is_file() and video.stat().st_size > 0


def test_sonar_readings_are_drawn_where_they_hit() -> None:
    from envs.sensors import Sonar

    SONAR_HIT = Sonar.hit_color

    frames = []
    for sonar in ({"range_std_m": 0.0}, None):
        env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=1, sonar=sonar, render_mode="rgb_array")
        env.reset(seed=0, options={"robot_pose": [2.5, 2.5, 0.0]})
        env.unwrapped.world.place_crowd_member(0, (3.5, 2.5))  # 1 m ahead: sensor 0 reads 1 m - radius
        env.step(np.zeros(2, dtype=np.float32))
        frames.append(env.render())
        r = env.unwrapped.config.crowd.radius_m
        col, row = Renderer(env.unwrapped.config, "rgb_array", 30).to_pixel((3.5 - r, 2.5))
        env.close()
    patch = frames[0][row - 2 : row + 3, col - 2 : col + 3].reshape(-1, 3)
    assert any(tuple(p) == SONAR_HIT for p in patch)
    assert not np.any(np.all(frames[1] == np.array(SONAR_HIT, dtype=np.uint8), axis=-1))  # no sonar, no sonar dots


def test_whole_world_frames_are_the_ones_recorded_before_the_follow_mode() -> None:
    # view_m (the follow mode) left every shipped world's top view as it was, bit for bit
    pinned = json.loads(FRAMES.read_text())
    versions = (pygame.version.ver, ".".join(map(str, pygame.get_sdl_version())))
    if versions != (pinned["pygame"], pinned["sdl"]):
        pytest.skip(f"frames recorded with pygame {pinned['pygame']}, SDL {pinned['sdl']} (fonts differ); here {versions}")
    ids = {world: env_id for env_id, world in envs.ENV_WORLDS.items()}
    for world in pinned["worlds"]:  # the worlds that existed then (later ones have no earlier frames)
        env = gym.make(ids[world], render_mode="rgb_array")
        assert env.unwrapped.config.view_m is None
        env.reset(seed=0)
        frames = [env.render()]
        for _ in range(5):
            env.step(np.array([0.8, 0.3], dtype=np.float32))
            frames.append(env.render())
        env.close()
        assert list(frame_shape(env.unwrapped.config)) == pinned["worlds"][world]["shape"]
        assert [hashlib.sha256(f.tobytes()).hexdigest() for f in frames] == pinned["worlds"][world]["sha256"], world


def test_a_narrow_world_gets_a_frame_wide_enough_for_its_caption() -> None:
    from envs.view import MIN_FRAME_WIDTH_PX, fit

    layout = fit(3.2, 25.0)  # the corridor as one whole-world frame: was 104 px wide
    assert layout.width == MIN_FRAME_WIDTH_PX and layout.height == 600
    assert layout.left == pytest.approx((layout.width - 3.2 * layout.scale) / 2)  # the corridor in the middle
    assert fit(6.0, 11.0).width == 332  # robocup_static's frame, wider than the minimum


def test_the_corridor_frame_is_legible_and_shows_its_whole_caption(monkeypatch: pytest.MonkeyPatch) -> None:
    """The eval GIF of CeilingCorridor-v0 (ceiling_target): a follow window of 46 px/m, and every
    part of the caption (world, time, crowd, the localizer's two texts) drawn whole, on two lines."""
    env = gym.make("crowdloc/CeilingCorridor-v0", render_mode="rgb_array", localizer="ceiling_target", crowd_size=20)
    renderer_cls = Renderer
    laid_out: list[tuple[list[tuple[str, Any]], list[list[tuple[int, str, Any]]], int]] = []
    original = renderer_cls.caption_lines

    def spy(self: Renderer, parts: Any) -> list[list[tuple[int, str, Any]]]:
        lines = original(self, parts)
        laid_out.append((list(parts), lines, self.width))
        return lines

    monkeypatch.setattr(renderer_cls, "caption_lines", spy)
    env.reset(seed=1)
    for _ in range(60):
        env.step(np.array([0.5, 0.0], dtype=np.float32))
    frame = env.render()
    renderer = env.unwrapped._renderer
    scale, font = renderer.scale, renderer._font
    assert isinstance(frame, np.ndarray) and frame.shape == (600, 398, 3)
    assert scale == pytest.approx(548 / 12)  # 12 m of corridor in view
    parts, lines, width = laid_out[-1]
    assert len(parts) == 3 and parts[0][0].startswith("ceiling_corridor  t=3.00 s  crowd=20")
    assert [text.strip() for line in lines for _, text, _ in line] == [text for text, _ in parts]  # every part, whole
    assert all(x + font.size(text)[0] <= width for line in lines for x, text, _ in line)  # none runs off the frame
    assert len(lines) == 2
    env.close()
