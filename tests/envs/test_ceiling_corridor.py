"""The ceiling corridor: its ceiling feature, the upward camera and the systematic odometry."""

from __future__ import annotations

import math
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import envs  # noqa: F401  (registers the ids)
from core.schema import ConfigError, from_mapping
from envs.config import load_world
from envs.features.ceiling import LABEL_CEILING, LABEL_HEAD, CeilingConfig, CeilingTarget, colour_label
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import IDEAL, CeilingCamera, undistort

ID = "crowdloc/CeilingCorridor-v0"
CLEAN = IDEAL  # every imperfection of the camera off


def camera(**fields: object) -> CeilingCamera:
    env = LocalizationEnv("ceiling_corridor", camera=fields or None)
    cam = env.sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    return cam


def test_world_frame_and_targets_follow_the_paper() -> None:
    world = load_world("ceiling_corridor")
    ceiling = world.features["ceiling"]
    assert isinstance(ceiling, CeilingConfig)
    assert [t.y_m for t in ceiling.targets] == [0.0, 6.9, 13.9, 20.8]
    assert all(t.x_m == 0.0 for t in ceiling.targets)  # on the centre line
    # the line across the corridor (2 cm x 38 cm), squares of 2 cm at its ends, A at -x
    (ax, ay), (bx, by) = ceiling.end_xy(ceiling.targets[0])
    assert (ax, bx) == pytest.approx((-0.2, 0.2)) and ay == by == 0.0
    assert len(set(ceiling.target_by_code())) == 4  # every target has its own colour code
    assert world.robot.start_pose == pytest.approx((0.0, 0.0, math.pi / 2))
    assert 2 * world.robot.radius_m == pytest.approx(0.55)
    xmin, ymin, xmax, ymax = world.field_m
    assert xmin < -1.0 and xmax > 1.0 and ymax - ymin == pytest.approx(25.0)


@pytest.mark.parametrize(
    ("targets", "message"),
    [
        ((CeilingTarget("T0", 5.0), CeilingTarget("T1", 1.0)), "sorted by y_m"),
        ((CeilingTarget("T0", 1.0), CeilingTarget("T1", 1.01)), "overlap"),
        ((CeilingTarget("T0", 1.0), CeilingTarget("T0", 3.0)), "names repeat"),
    ],
)
def test_bad_target_lists_are_refused(targets: tuple[CeilingTarget, ...], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        CeilingConfig(targets=targets)


def test_unknown_colour_names_the_value() -> None:
    with pytest.raises(ConfigError, match="unknown colour 'purple' for a"):
        CeilingTarget("T0", 0.0, a="purple")
    with pytest.raises(ConfigError, match="world.yaml.*unknown colour 'teal' for c"):
        from_mapping(CeilingTarget, {"name": "T9", "y_m": 1.0, "c": "teal"}, "world.yaml")


def test_camera_needs_a_ceiling() -> None:
    with pytest.raises(ConfigError, match="not a ceiling"):
        LocalizationEnv("crowded_room", ceiling_camera={})


def test_check_env_passes_with_the_image_in_the_observation() -> None:
    env = gym.make(ID)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    sb3_check_env(LocalizationEnv("ceiling_corridor"), warn=True)
    obs, _ = env.reset(seed=0)
    image = obs["ceiling_image"]
    assert image.dtype == np.uint8 and image.shape == (240, 320, 3)
    assert env.observation_space["ceiling_image"].contains(image)


def test_the_image_is_the_mirrored_ceiling_and_ends_where_the_paper_says() -> None:
    cam = camera(**CLEAN)
    # at (0, 0) facing +y, end A (green, at -x: the robot's left) shows on the image's right
    _, labels = cam.render(np.array([[0.0, 0.0, math.pi / 2]]), labels=True)
    assert labels is not None
    green = np.argwhere(labels == colour_label("green"))
    red = np.argwhere(labels == colour_label("red"))
    assert green[:, 1].mean() > 160 > red[:, 1].mean()
    # a point 0.2 m ahead of the robot appears above the image centre, at f * 0.2 / d rows
    ahead = cam.render(np.array([[0.0, -0.2, math.pi / 2]]), labels=True)[1]
    assert ahead is not None
    rows = np.argwhere(ahead == colour_label("yellow"))[:, 0]
    expected = 120 - cam.model.fy * 0.2 / cam.depth
    assert rows.mean() == pytest.approx(expected, abs=0.5)


def test_the_footprint_is_the_papers() -> None:
    cam = camera()
    width = 2 * cam.depth * math.tan(cam.config.hfov_rad / 2)
    height = width * 240 / 320
    assert width == pytest.approx(1.10, abs=0.005) and height == pytest.approx(0.84, abs=0.02)


def test_undistort_inverts_the_lens_model() -> None:
    rng = np.random.default_rng(0)
    xu, yu = rng.uniform(-0.4, 0.4, 100), rng.uniform(-0.3, 0.3, 100)
    k1 = -0.1
    scale = 1 + k1 * (xu**2 + yu**2)
    x, y = undistort(xu * scale, yu * scale, k1)
    assert np.allclose(x, xu, atol=1e-12) and np.allclose(y, yu, atol=1e-12)


def test_motion_blur_grows_with_speed_and_a_stopped_robot_is_sharp() -> None:
    def sharpness(speed: float) -> float:
        # every run ends at the same pose, 10 cm short of the first target, after 10 steps
        env = LocalizationEnv("ceiling_corridor", camera={"noise_std": 0.0})
        travel = 10 * env.config.dt_s * speed * env.config.robot.max_speed_mps
        env.reset(seed=0, options={"robot_pose": [0.0, -0.1 - travel, math.pi / 2]})
        for _ in range(10):
            obs, *_ = env.step(np.array([speed, 0.0], dtype=np.float32))
        assert env.world.robot_pose[1] == pytest.approx(-0.1, abs=1e-6)
        grey = obs["ceiling_image"].astype(np.float64).mean(axis=2)
        return float(np.sum(np.diff(grey, axis=0) ** 2))  # edge energy along the motion: blur spreads it

    still, slow, fast = sharpness(0.0), sharpness(0.5), sharpness(1.0)
    assert still > slow > fast


def test_turning_blurs_the_image_edges_more_than_the_rotation_centre() -> None:
    # the exposure spans the whole step: a turn of dtheta smears a pixel r px from the image
    # centre (the camera is on the rotation axis) over about r * dtheta px
    cam = camera(**dict(CLEAN, exposure_s=0.05))
    pose = np.array([0.0, 0.0, math.pi / 2 + 0.3])  # the target's line across the image centre, tile joints at the sides

    def energy(image: np.ndarray, window: tuple[slice, slice]) -> float:
        grey = image.astype(np.float64).mean(axis=2)[window]
        return float(np.sum(np.diff(grey, axis=0) ** 2) + np.sum(np.diff(grey, axis=1) ** 2))

    centre, sides = (slice(100, 140), slice(130, 190)), (slice(0, 240), np.r_[0:50, 270:320])
    sharp, _ = cam.render(pose)
    assert energy(sharp, centre) > 0 and energy(sharp, sides) > 0
    still, _ = cam.render(pose, previous=pose)
    assert np.array_equal(still, sharp)  # a stopped robot's image is sharp
    kept = {}
    for turn in (0.02, 0.04):
        blurred, _ = cam.render(pose, previous=pose - np.array([0.0, 0.0, turn]))
        kept[turn] = (energy(blurred, centre) / energy(sharp, centre), energy(blurred, sides) / energy(sharp, sides))
        assert kept[turn][1] < 0.5 * kept[turn][0]  # the sides lose far more of their edges
    assert kept[0.04][0] < kept[0.02][0] and kept[0.04][1] < kept[0.02][1]  # a faster turn blurs more
    # the blur is the turn's: the same turn without exposure time is sharp
    assert np.array_equal(camera(**CLEAN).render(pose, previous=pose - np.array([0.0, 0.0, 0.04]))[0], sharp)


def test_a_head_near_the_robot_hides_the_ceiling_at_the_edge() -> None:
    cam = camera(**CLEAN)
    pose = np.array([[0.0, 3.0, math.pi / 2]])
    _, alone = cam.render(pose, labels=True)
    # a person touching the robot (footprints 0.275 + 0.2 m apart) ahead on its left, toward the
    # image's top right corner: forward 0.224 m and left 0.299 m at head height
    corner = math.atan2(0.55 * 0.95 / 1.75, 0.42 * 0.95 / 1.75)  # from the heading toward the left
    touching = pose[0, :2] + 0.476 * np.array([-math.sin(corner), math.cos(corner)])
    _, crowded = cam.render(pose, touching[None, :], labels=True)
    assert alone is not None and crowded is not None
    assert not (alone == LABEL_HEAD).any()
    hidden = np.argwhere(crowded == LABEL_HEAD)
    assert 0 < hidden.shape[0] < 0.1 * crowded.size
    # in the image's top right corner: ahead (up) and on the robot's left (mirrored: image right)
    assert hidden[:, 0].max() < 60 and hidden[:, 1].min() > 240
    _, far = cam.render(pose, np.array([[-0.9, 3.0]]), labels=True)
    assert far is not None and not (far == LABEL_HEAD).any()


def test_rendering_is_deterministic_and_the_period_repeats_frames() -> None:
    def run(period: int) -> list[np.ndarray]:
        env = gym.make(ID, camera={"period_steps": period})
        obs, _ = env.reset(seed=3)
        frames = [obs["ceiling_image"]]
        for _ in range(4):
            obs, *_ = env.step(np.array([0.6, 0.1], dtype=np.float32))
            frames.append(obs["ceiling_image"])
        return frames

    a, b = run(1), run(1)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(a[0], a[1])
    held = run(2)
    assert np.array_equal(held[0], held[1]) and not np.array_equal(held[1], held[2])


def test_no_ground_truth_in_the_observation() -> None:
    env = gym.make(ID, localizer="ceiling_target")
    obs, info = env.reset(seed=0)
    truth = np.asarray(info["true_pose"])
    for key, value in obs.items():
        if key == "ceiling_image":
            continue  # rendered from the true pose, as a real camera's frames are
        flat = np.asarray(value, dtype=np.float64).ravel()
        assert not np.any(np.isclose(flat[:, None], truth[None, :2], atol=1e-9) & (np.abs(truth[None, :2]) > 1e-6)), key


def test_dead_reckoning_with_the_systematic_odometry_ends_about_45_cm_long() -> None:
    # straight along the corridor centre at full speed, no crowd: odometry reads 2.2 % long
    env = LocalizationEnv("ceiling_corridor")
    env.reset(seed=0)
    pose = np.array([0.0, 0.0, math.pi / 2])
    odometry = env.config.sensors["odometry"]
    while True:
        obs, _, _, _, info = env.step(np.array([1.0, 0.0], dtype=np.float32))
        dx, dy, dth = obs["odometry"].astype(np.float64)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        pose = pose + [c * dx - s * dy, s * dx + c * dy, dth]
        if pose[1] >= 20.8:
            break
    true_y = float(info["true_pose"][1])
    expected = 20.8 * (1 - 1 / odometry.distance_scale)  # type: ignore[attr-defined]
    assert 20.8 - true_y == pytest.approx(expected, abs=0.05)
    assert 0.40 < 20.8 - true_y < 0.50


def test_labels_cover_the_image() -> None:
    cam = camera(**CLEAN)
    _, labels = cam.render(np.array([[0.0, 10.0, 1.0]]), labels=True)
    assert labels is not None and labels.shape == (240, 320)
    assert (labels == LABEL_CEILING).mean() > 0.5
