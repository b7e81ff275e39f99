"""Persistent false detections: a distractor of a landmark's colour beyond the field is
reported in that landmark's slot, at its own bearing, whenever it is in view and the
landmark is not (the bearing camera's ``distractors``)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from core.geometry import wrap_angle
from core.schema import ConfigError
from envs.config import load_world, world_path
from envs.palette import landmark_color
from envs.render import Renderer
from envs.sensors.bearing_camera import BearingCameraConfig, DistractorConfig

STILL = np.zeros(2, dtype=np.float32)
# robocup_static: field x in [0, 5], y in [0, 10], walls 0.5 m beyond it; L5 (5, 10) seen within
# 4.6 m only, L6 (3.5, 10), L7 (1.5, 10); the robot starts at (2.5, 8.0)
L5_XY = np.array([5.0, 10.0])
L5_RANGE_M = 4.6
FAKE_L5 = {"landmark": "L5", "x_m": 5.3, "y_m": 10.3}  # in the corner beyond the field, behind L5
NEAR = (2.5, 8.0, 0.0)  # L5 in view (3.2 m)
FAR = (2.5, 2.0, 0.0)  # L5 out of its range (8.5 m); FAKE_L5 8.8 m away


def slots(obs: dict[str, Any]) -> np.ndarray:
    return np.asarray(obs["landmarks"]).reshape(-1, 3)


def static_env(distractors: list[dict[str, Any]], **camera: Any) -> gym.Env[Any, Any]:
    return gym.make(
        "crowdloc/RoboCupStatic-v0", crowd_size=1, camera={"noise_std_rad": 0.0, "distractors": distractors, **camera}
    )


def place(env: gym.Env[Any, Any], pose: tuple[float, float, float], blocker: tuple[float, float] = (0.5, 1.0)) -> tuple:
    """Observe from ``pose`` with the one crowd member held at ``blocker`` (by default far from every sight line)."""
    env.reset(seed=0, options={"robot_pose": list(pose)})
    env.unwrapped.world.place_crowd_member(0, blocker)
    env.unwrapped.world.set_robot_pose(pose)
    obs, _, _, _, info = env.step(STILL)
    np.testing.assert_allclose(info["true_pose"][:2], pose[:2], atol=1e-9)
    return obs, info


def bearing(pose: tuple[float, float, float], xy: Any) -> float:
    return float(wrap_angle(math.atan2(xy[1] - pose[1], xy[0] - pose[0]) - pose[2]))


def reported(obs: dict[str, Any], j: int) -> float:
    return math.atan2(float(slots(obs)[j, 2]), float(slots(obs)[j, 1]))


def test_a_distractor_appears_at_its_place_whenever_it_is_in_view_and_the_landmark_is_not() -> None:
    """Poses over the field and headings all round, with a 90 deg camera: the L5 slot holds L5
    when it is in view, else the distractor when that is in view, else nothing (geometry here,
    independent of the camera's code; no crowd member near the sight lines)."""
    fov = math.pi / 2
    env = static_env([FAKE_L5], fov_rad=fov)
    rng = np.random.default_rng(3)
    seen = {"landmark": 0, "distractor": 0, "none": 0}
    for _ in range(40):
        pose = (float(rng.uniform(1.0, 4.5)), float(rng.uniform(2.0, 9.5)), float(rng.uniform(-math.pi, math.pi)))
        obs, info = place(env, pose)
        landmark_in_view = np.hypot(*(L5_XY - pose[:2])) <= L5_RANGE_M and abs(bearing(pose, L5_XY)) <= fov / 2
        fake_in_view = abs(bearing(pose, (FAKE_L5["x_m"], FAKE_L5["y_m"]))) <= fov / 2
        assert bool(info["visible_landmarks"][0]) == landmark_in_view, pose
        if landmark_in_view:
            seen["landmark"] += 1
            assert slots(obs)[0, 0] == 1.0 and not info["distractor_detections"][0]
            assert reported(obs, 0) == pytest.approx(bearing(pose, L5_XY), abs=1e-6)
        elif fake_in_view:
            seen["distractor"] += 1
            assert slots(obs)[0, 0] == 1.0 and info["distractor_detections"][0], pose
            assert reported(obs, 0) == pytest.approx(bearing(pose, (5.3, 10.3)), abs=1e-6)
        else:
            seen["none"] += 1
            assert slots(obs)[0].tolist() == [0.0, 0.0, 0.0] and not info["distractor_detections"][0]
        assert not info["distractor_detections"][1:].any()  # only L5 has a distractor
        assert not info["false_detections"].any()
    env.close()
    assert min(seen.values()) >= 3, seen  # every case came up


def test_never_while_the_landmark_is_in_view() -> None:
    env = static_env([FAKE_L5])
    obs, info = place(env, NEAR)
    assert info["visible_landmarks"][0] and not info["distractor_detections"].any()
    assert reported(obs, 0) == pytest.approx(bearing(NEAR, L5_XY), abs=1e-6)
    obs, info = place(env, FAR)
    assert not info["visible_landmarks"][0] and info["distractor_detections"].tolist() == [True, False, False]
    assert reported(obs, 0) == pytest.approx(bearing(FAR, (5.3, 10.3)), abs=1e-6)
    assert reported(obs, 0) != pytest.approx(bearing(FAR, L5_XY), abs=1e-3)  # a wrong bearing, not the landmark's
    env.close()


def test_a_crowd_member_on_the_sight_line_hides_it() -> None:
    env = static_env([FAKE_L5])
    midpoint = tuple(0.5 * (np.array(FAR[:2]) + np.array([5.3, 10.3])))
    obs, info = place(env, FAR, blocker=midpoint)
    assert slots(obs)[0].tolist() == [0.0, 0.0, 0.0] and not info["distractor_detections"].any()
    world = env.unwrapped.world
    for _ in range(3):  # held there: it stays hidden
        obs, _, _, _, info = env.step(STILL)
        assert slots(obs)[0, 0] == 0.0 and not info["distractor_detections"][0]
    world.place_crowd_member(0, (0.5, 1.0))
    obs, _, _, _, info = env.step(STILL)
    assert slots(obs)[0, 0] == 1.0 and info["distractor_detections"][0]
    env.close()


def test_outside_the_field_of_view_or_its_range_it_is_not_seen() -> None:
    env = static_env([FAKE_L5], fov_rad=math.pi / 2)
    towards = bearing((FAR[0], FAR[1], 0.0), (5.3, 10.3))
    obs, info = place(env, (FAR[0], FAR[1], towards))
    assert info["distractor_detections"][0] and reported(obs, 0) == pytest.approx(0.0, abs=1e-6)
    obs, info = place(env, (FAR[0], FAR[1], towards + math.pi))  # facing away
    assert slots(obs)[0, 0] == 0.0 and not info["distractor_detections"][0]
    env.close()

    # its own range, and the camera's; the landmark's own 4.6 m does not apply
    for camera_range, own_range, seen in ((math.inf, math.inf, True), (math.inf, 8.0, False), (8.0, math.inf, False)):
        env = static_env([{**FAKE_L5, "max_range_m": own_range}], max_range_m=camera_range)
        _, info = place(env, FAR)
        assert bool(info["distractor_detections"][0]) == seen, (camera_range, own_range)
        env.close()


def test_the_nearest_of_several_is_reported() -> None:
    near, far = {"landmark": "L6", "x_m": 3.0, "y_m": -0.3}, {"landmark": "L6", "x_m": 1.0, "y_m": 10.4}
    pose = (2.5, 1.0, 0.0)  # 1.4 m from `near`, 9.4 m from `far`; L6 hidden by a robot on its sight line
    to_l6 = np.array([3.5, 10.0]) - np.array(pose[:2])
    blocker = tuple(np.array(pose[:2]) + 3.0 * to_l6 / np.linalg.norm(to_l6))  # 3 m out: it hides +-4.4 deg only
    for order in ([near, far], [far, near]):
        env = static_env(order)
        obs, info = place(env, pose, blocker=blocker)
        assert not info["visible_landmarks"][1]
        assert info["distractor_detections"].tolist() == [False, True, False]
        assert reported(obs, 1) == pytest.approx(bearing(pose, (3.0, -0.3)), abs=1e-6)
        env.close()


def test_a_dropped_slot_stays_empty_and_a_random_false_detection_comes_first() -> None:
    # dropout drops the slot (a missed detection, or Exp 2's random landmark subset): the
    # landmark is not replaced by its distractor, in view or not
    for pose in (NEAR, FAR):
        env = static_env([FAKE_L5], dropout_probability=1.0)
        obs, info = place(env, pose)
        assert not info["distractor_detections"].any()
        assert slots(obs)[:, 0].tolist() == [0.0, 0.0, 0.0]
        env.close()

    env = static_env([FAKE_L5], false_detection_probability=1.0)
    _, info = place(env, FAR)
    assert info["false_detections"].all() and not info["distractor_detections"].any()
    env.close()


def test_the_bearing_carries_the_camera_noise() -> None:
    env = static_env([FAKE_L5], noise_std_rad=0.02)
    env.reset(seed=5, options={"robot_pose": list(FAR)})
    env.unwrapped.world.place_crowd_member(0, (0.5, 1.0))
    errors = []
    for _ in range(200):
        obs, _, _, _, info = env.step(STILL)
        assert info["distractor_detections"][0]
        pose = tuple(info["true_pose"])
        errors.append(wrap_angle(reported(obs, 0) - bearing(pose, (5.3, 10.3))))
    env.close()
    errors = np.asarray(errors)
    assert 0.015 < errors.std() < 0.025 and abs(errors.mean()) < 0.005


def rollout(distractors: list[dict[str, Any]], seed: int = 4, steps: int = 120) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    env = gym.make("crowdloc/RoboCupCrowded-v0", crowd_size=6, camera={"distractors": distractors})
    actions = np.random.default_rng(seed).uniform(-1, 1, size=(steps, 2)).astype(np.float32)
    obs, info = env.reset(seed=seed)
    out = [(obs, info)]
    for a in actions:
        obs, _, _, _, info = env.step(a)
        out.append((obs, info))
    env.close()
    return out


CROWDED_FAKES = [
    {"landmark": "L2", "x_m": 1.3, "y_m": -0.35},
    {"landmark": "L6", "x_m": 3.8, "y_m": 5.35},
    {"landmark": "L8", "x_m": -0.3, "y_m": 5.3, "radius_m": 0.1},
]


def test_determinism_and_no_extra_random_numbers() -> None:
    a, b = rollout(CROWDED_FAKES), rollout(CROWDED_FAKES)
    plain = rollout([])
    reports = 0
    for t, ((obs_a, info_a), (obs_b, info_b), (obs_p, info_p)) in enumerate(zip(a, b, plain)):
        for key in obs_a:
            np.testing.assert_array_equal(obs_a[key], obs_b[key], err_msg=f"step {t}: {key}")
        np.testing.assert_array_equal(info_a["distractor_detections"], info_b["distractor_detections"])
        # the distractors change only the slots they fill: the same noise, the same crowd, the same path
        np.testing.assert_array_equal(info_a["true_pose"], info_p["true_pose"], err_msg=f"step {t}")
        np.testing.assert_array_equal(obs_a["odometry"], obs_p["odometry"], err_msg=f"step {t}")
        keep = ~info_a["distractor_detections"]
        np.testing.assert_array_equal(slots(obs_a)[keep], slots(obs_p)[keep], err_msg=f"step {t}")
        assert not slots(obs_p)[~keep, 0].any()  # filled slots were empty without distractors
        assert not info_p["distractor_detections"].any()
        reports += int(info_a["distractor_detections"].sum())
    assert reports > 0  # the rollout did meet them


def test_the_soccer_worlds_ship_distractors_beyond_their_fields_and_the_default_has_none() -> None:
    for name in ("robocup_static", "robocup_crowded"):
        world = load_world(name)
        camera = world.sensors["camera"]
        assert isinstance(camera, BearingCameraConfig) and len(camera.distractors) >= 2
        xmin, ymin, xmax, ymax = world.field_m
        for d in camera.distractors:
            assert not (xmin <= d.x_m <= xmax and ymin <= d.y_m <= ymax)  # beyond the field
    assert BearingCameraConfig().distractors == ()
    # the crowded field's keeper hides its goal posts: their distractors get reported
    flags = np.array([info["distractor_detections"] for _, info in rollout(list(_shipped("robocup_crowded")))])
    assert flags.any()


def _shipped(name: str) -> list[dict[str, Any]]:
    camera = load_world(name).sensors["camera"]
    assert isinstance(camera, BearingCameraConfig)
    return [dataclasses.asdict(d) for d in camera.distractors]


@pytest.mark.parametrize(
    ("distractor", "message"),
    [
        ({"landmark": "L9", "x_m": 5.3, "y_m": 10.3}, r"unknown landmark 'L9' \(the world's landmarks: L5, L6, L7\)"),
        ({"landmark": "l5", "x_m": 5.3, "y_m": 10.3}, r"unknown landmark 'l5'"),
        ({"landmark": "L5", "x_m": math.nan, "y_m": 10.3}, r"x_m and y_m must be finite, got \(nan, 10.3\)"),
        ({"landmark": "L5", "x_m": 5.3, "y_m": math.inf}, r"x_m and y_m must be finite, got \(5.3, inf\)"),
        ({"landmark": "L5", "x_m": 4.0, "y_m": 9.0}, r"\(4, 9\) m is inside the field x in \[0, 5\], y in \[0, 10\]"),
        ({"landmark": "L5", "x_m": 5.0, "y_m": 10.0}, r"inside the field"),  # on its corner
        ({"landmark": "L5", "x_m": 6.0, "y_m": 10.3}, r"\(6, 10.3\) m is not inside the boundary walls x in \(-0.5, 5.5\)"),
        ({"landmark": "L5", "x_m": 5.5, "y_m": 10.3}, r"not inside the boundary walls"),  # on the wall
        ({"landmark": "L5", "x_m": 5.3, "y_m": 10.3, "radius_m": 0.0}, r"radius_m must be > 0 and finite, got 0.0"),
        ({"landmark": "L5", "x_m": 5.3, "y_m": 10.3, "radius_m": math.inf}, r"radius_m must be > 0 and finite"),
        ({"landmark": "L5", "x_m": 5.3, "y_m": 10.3, "max_range_m": -1}, r"max_range_m must be > 0, got -1"),
        ({"landmark": "L5", "x_m": 5.3, "y_m": 10.3, "colour": "blue"}, r"unknown key 'colour' for DistractorConfig"),
        ({"landmark": "L5", "x_m": 5.3}, r"missing required key 'y_m' for DistractorConfig"),
        ({"landmark": "L5", "x_m": "5.3", "y_m": 10.3}, r"distractors\[0\]\.x_m: expected a number, got str '5.3'"),
        ({"landmark": 5, "x_m": 5.3, "y_m": 10.3}, r"distractors\[0\]\.landmark: expected a string, got int 5"),
    ],
)
def test_bad_distractors_are_refused(distractor: dict[str, Any], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        gym.make("crowdloc/RoboCupStatic-v0", camera={"distractors": [distractor]})


def test_bad_distractors_in_a_world_file_name_the_file_and_the_entry(tmp_path: Path) -> None:
    text = world_path("robocup_static").read_text()
    shipped = text.index("    distractors:")
    text = text[:shipped] + text[text.index("crowds:") :]  # the file without its own distractors
    assert "noise_std_rad: 0.0174532925199433   # 1 deg\n" in text
    good = text.replace(
        "    noise_std_rad: 0.0174532925199433   # 1 deg\n",
        "    noise_std_rad: 0.0174532925199433   # 1 deg\n    distractors:\n      - {landmark: L6, x_m: 3.2, y_m: 10.3}\n",
    )
    path = tmp_path / "fooled.yaml"
    path.write_text(good)
    assert load_world(path).sensors["camera"].distractors == (DistractorConfig("L6", 3.2, 10.3),)  # type: ignore[attr-defined]
    path.write_text(good.replace("landmark: L6", "landmark: L8"))
    with pytest.raises(ConfigError, match=r"fooled.yaml.*camera 'camera': distractors\[0\]: unknown landmark 'L8'"):
        load_world(path)
    path.write_text(good.replace("distractors:\n", "distractors:\n      - {landmark: L6, x_m: 3.2}\n"))
    with pytest.raises(ConfigError, match=r"fooled.yaml.sensors.camera.distractors\[0\]: missing required key 'y_m'"):
        load_world(path)
    with pytest.raises(ConfigError, match="expected DistractorConfig entries, got dict"):
        BearingCameraConfig(distractors=({"landmark": "L6", "x_m": 3.2, "y_m": 10.3},))  # type: ignore[arg-type]


def test_the_renderer_draws_distractors_as_rings_in_their_landmark_colour() -> None:
    def frame(distractors: list[dict[str, Any]]) -> tuple[gym.Env[Any, Any], np.ndarray]:
        env = gym.make("crowdloc/RoboCupStatic-v0", render_mode="rgb_array", camera={"distractors": distractors})
        env.reset(seed=0, options={"robot_pose": list(NEAR)})
        return env, env.render()

    def window(env: gym.Env[Any, Any], image: np.ndarray, xy: tuple[float, float], half: int) -> np.ndarray:
        col, row = Renderer(env.unwrapped.config, "rgb_array", 30).to_pixel(xy)
        return image[row - half : row + half + 1, col - half : col + half + 1]

    colour = np.array(landmark_color(1))  # L6's
    spot = (3.2, 10.3)
    env, with_ring = frame([{"landmark": "L6", "x_m": spot[0], "y_m": spot[1]}])
    ring = window(env, with_ring, spot, 7)
    assert (ring == colour).all(axis=-1).sum() >= 20  # the ring
    ring_band = window(env, with_ring, spot, 3)
    assert (ring_band == colour).all(axis=-1).sum() < (ring_band.shape[0] * ring_band.shape[1]) // 2  # hollow
    env.close()
    env, without = frame([])
    assert not (window(env, without, spot, 7) == colour).all(axis=-1).any()
    assert with_ring.shape == without.shape
    env.close()


def test_a_recording_keeps_the_distractor_flags() -> None:
    from agents.experiments.replay import record
    from agents.experiments.scenarios import exp1_driver

    kwargs = {"camera": {"distractors": [FAKE_L5]}}
    rec = record("crowdloc/RoboCupStatic-v0", exp1_driver, seed=4, max_steps=300, env_kwargs=kwargs)
    assert rec.distractor_detections.shape == rec.false_detections.shape == (rec.steps, 3)
    flags = rec.distractor_detections[:, 0]
    assert flags.any() and not rec.distractor_detections[:, 1:].any()
    assert not (flags & rec.visible[:, 0]).any()  # never while L5 itself is in view
    plain = record("crowdloc/RoboCupStatic-v0", exp1_driver, seed=4, max_steps=300, env_kwargs={"camera": {"distractors": []}})
    assert not plain.distractor_detections.any()
