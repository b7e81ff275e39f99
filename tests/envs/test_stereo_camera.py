"""The stereo camera sensor: its two modes, occlusion by people, its observation and its bad input."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from core.schema import ConfigError
from envs.localization_env import LocalizationEnv
from envs.sensors.stereo_camera import StereoCamera, StereoCameraConfig
from envs.stereo.vision import EdgeList, edge_types_parts
from tests.envs.stereo_scene import FACADE_X_M, ROBOT_POSE, place, scene, scene_env


def camera(env: LocalizationEnv) -> StereoCamera:
    sensor = env.sensors["stereo"]
    assert isinstance(sensor, StereoCamera)
    return sensor


def edges_now(env: LocalizationEnv) -> tuple[EdgeList, ...]:
    """The cameras' edges for the env's current state (observing once more)."""
    cam = camera(env)
    cam.observe(env.state, np.random.default_rng(1))
    return cam.last_edges


def twins(a: EdgeList, b: EdgeList, within_px: float) -> float:
    """Share of the edges of ``a`` with an edge of the same type in ``b`` within ``within_px``."""
    if a.u.size == 0:
        return 1.0
    hit = 0
    for u, t in zip(a.u, a.type):
        same = b.u[b.type == t]
        hit += bool(same.size and np.min(np.abs(same - u)) <= within_px)
    return hit / a.u.size


# ------------------------------------------------------------------ the two modes


def test_image_and_fast_mode_find_the_same_edges_on_a_clean_scene() -> None:
    image, fast = scene_env(mode="image"), scene_env(mode="fast")
    for j, (ei, ef) in enumerate(zip(edges_now(image), edges_now(fast))):
        assert ei.u.size > 100, f"camera {j}: the façade shows {ei.u.size} edges"
        # the same edges within a pixel, both ways (measured 0.97-0.99 and 0.93-0.96; the rest are
        # window edges seen at a grazing angle near the façade's end, where the filter mixes neighbours)
        assert twins(ei, ef, 1.0) >= 0.9, j
        assert twins(ef, ei, 1.0) >= 0.85, j
        assert abs(ei.u.size - ef.u.size) <= 0.15 * ei.u.size


def test_matched_edges_on_the_facade_triangulate_to_its_distance() -> None:
    # the lines model keeps sub-pixel columns; the rows model (the default) puts an edge on whole pixels as the
    # image mode does, where 1 px of the outer pair's ~10 px disparity is about 2 m at 20 m
    env = scene_env(mode="fast", fast_edges="lines")
    obs = env.step(np.zeros(2, dtype=np.float32))[0]
    slots = obs["stereo"].reshape(-1, 4)
    seen = slots[slots[:, 0] > 0.5]
    assert seen.shape[0] > 20
    x, y, theta = env.state.robot_pose
    rng, bearing = 1.0 / seen[:, 2], seen[:, 3]
    ex = x + rng * np.cos(theta + bearing)
    # most detections lie on the façade plane x = 30 (ideal cameras: sub-pixel columns, 0.4 m at 20 m is 2 px of disparity)
    on_facade = np.abs(ex - FACADE_X_M) < 0.6
    assert on_facade.mean() > 0.8
    # and their bearings lie inside the field of view
    assert np.all(np.abs(bearing) < math.radians(31))


@pytest.mark.parametrize("mode", ["image", "fast"])
def test_a_near_person_hides_the_upper_rows_and_a_far_one_does_not(mode: str) -> None:
    env = scene_env(people=1, mode=mode)
    cam = camera(env)
    x0, y0, _ = ROBOT_POSE

    def building_edges_behind(distance: float) -> int:
        place(env, 0, x0 + distance, y0)
        env.step(np.zeros(2, dtype=np.float32))
        found = cam.last_edges[1]  # the middle camera
        _, level, _ = edge_types_parts(found.type)
        # the columns a person's torso covers 2 m ahead, around the image centre
        behind = (level == 0) & (np.abs(found.u - cam.rig_geometry.cx_px) < 20)  # inside the head's silhouette
        return int(behind.sum())

    near, far = building_edges_behind(2.0), building_edges_behind(12.0)
    assert near == 0  # the person covers the top row there
    assert far >= 4  # a person 12 m away reaches the bottom row only: the façade's windows show above


# ------------------------------------------------------------------ observation


def test_observation_holds_slots_and_images_only_when_asked() -> None:
    plain = scene_env(mode="fast")
    obs, _ = plain.reset(seed=0)
    assert set(obs) == {"odometry", "stereo"}
    assert obs["stereo"].shape == (96 * 4,) and obs["stereo"].dtype == np.float32
    assert plain.observation_space["stereo"].contains(obs["stereo"])
    both = scene_env(mode="fast", images=True)
    obs, info = both.reset(seed=0)
    assert set(obs) == {"odometry", "stereo", "stereo_left", "stereo_middle", "stereo_right"}
    for key in ("stereo_left", "stereo_middle", "stereo_right"):
        assert obs[key].shape == (480, 640, 3) and obs[key].dtype == np.uint8
        assert both.observation_space[key].contains(obs[key])
    assert info["stereo_detections"] == int(obs["stereo"].reshape(-1, 4)[:, 0].sum())
    # the images differ: three cameras 19 cm apart
    assert not np.array_equal(obs["stereo_left"], obs["stereo_right"])


def test_slots_keep_the_strongest_detections_from_left_to_right() -> None:
    env = scene_env(mode="fast", slots=8)
    obs, info = env.reset(seed=0)
    slots = obs["stereo"].reshape(-1, 4)
    assert slots[:, 0].sum() == 8 and info["stereo_dropped"] > 0
    assert np.all(np.diff(slots[:, 3]) <= 0)  # bearings fall from left to right
    assert info["stereo_detections"] == 8


@pytest.mark.parametrize("images", [False, True])
def test_env_checkers_with_and_without_images(images: bool) -> None:
    env = LocalizationEnv(scene(mode="fast", images=images))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("error")
        gym_check_env(env, skip_render_check=True)
        sb3_check_env(env, warn=True)
    assert caught == []


def test_same_seed_same_detections() -> None:
    a, b = scene_env(people=1, edge_noise_px=0.5), scene_env(people=1, edge_noise_px=0.5)
    for _ in range(5):
        oa = a.step(np.array([0.5, 0.2], dtype=np.float32))[0]
        ob = b.step(np.array([0.5, 0.2], dtype=np.float32))[0]
        np.testing.assert_array_equal(oa["stereo"], ob["stereo"])


# ------------------------------------------------------------------ rendering


def test_rendered_frame_shows_the_three_images_under_the_top_view() -> None:
    config = dataclasses.replace(scene(mode="fast"), view_m=(40.0, 30.0))
    env = LocalizationEnv(config, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None
    from envs.render import frame_shape

    assert frame.shape == frame_shape(config)
    strip = camera(env).config.panel_height_px(frame.shape[1])
    assert strip > 0 and frame.shape[0] > strip
    views = camera(env).views(env.state)
    assert views.shape == (480, 1920, 3)
    # the strip is the façade's colours, not the top view's
    assert frame[-strip:].std() > 10


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    ("field", "value", "words"),
    [
        ("focal_px", 0.0, "focal_px must be finite and > 0, got 0.0"),
        ("focal_px", -5.0, "focal_px must be finite and > 0, got -5.0"),
        ("baseline_m", 0.0, "baseline_m must be finite and > 0, got 0.0"),
        ("baseline_m", float("nan"), "baseline_m must be finite and > 0, got nan"),
        ("baseline_m", 2.0, "the cameras do not overlap where matching starts: with baseline_m 2.0"),
        ("principal_point_px", (700.0, 240.0), "principal_point_px (700.0, 240.0) must lie inside"),
        ("detection_rows_px", (10, 100, 140, 180, 220), "window of row 10 does not fit an image of 480 rows"),
        ("detection_rows_px", (60, 100, 140), "must be 5 rows"),
        ("mode", "laser", "mode must be 'fast' or 'image', got 'laser'"),
        ("min_range_m", 200.0, "min_range_m 200.0 must be below max_range_m 100.0"),
    ],
)
def test_bad_camera_config_is_refused_naming_the_value(field: str, value: object, words: str) -> None:
    with pytest.raises(ConfigError) as caught:
        StereoCameraConfig(**{field: value})  # type: ignore[arg-type]
    assert words in str(caught.value)


def test_bad_camera_config_from_the_env_keywords_names_it() -> None:
    with pytest.raises(ConfigError) as caught:
        LocalizationEnv(scene(), stereo={"baseline_m": -0.19})
    assert "baseline_m must be finite and > 0, got -0.19" in str(caught.value)
