"""The glare spot on the ceiling's glossy tape: its place by the mirror geometry, its lobe, the sensor's saturation."""

from __future__ import annotations

import math
import re

import cv2
import numpy as np
import pytest

import envs  # noqa: F401  (registers the ids)
from core.schema import ConfigError
from envs.features.ceiling import LABEL_COLOUR
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import IDEAL, CeilingCamera
from envs.sensors.glare import mirror_spot_xy
from tests.envs.ceiling_frames import ceiling_frames

CEILING_M, MOUNT_M = 2.5, 0.75
#: a lamp hung 0.5 m below the ceiling, 0.2 m across the corridor from the second target's centre
LAMP = (0.2, 6.9, 2.0)
UNDER_T1 = np.array([0.0, 6.9, math.pi / 2])


def camera(**fields: object) -> CeilingCamera:
    cam = LocalizationEnv("ceiling_corridor", camera=fields or None).sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    return cam


def world_to_pixel(cam: CeilingCamera, pose: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """The pixel (u, v) where the ceiling point ``xy`` shows from robot pose ``pose``."""
    rel = xy - pose[:2]
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    forward, left = cos * rel[0] + sin * rel[1], -sin * rel[0] + cos * rel[1]
    u, v = cam.model.project(np.array([forward]), np.array([left]), cam.depth, cam.config.offset_m)
    return np.array([u[0], v[0]])


def brightest(lit: tuple[np.ndarray, int, int] | None) -> np.ndarray:
    """The glare's peak pixel (u, v), at its centre (+ 0.5)."""
    assert lit is not None
    glare = lit[0]
    v, u = np.unravel_index(int(np.argmax(glare[..., 0])), glare.shape[:2])
    return np.array([u + 0.5, v + 0.5])


def test_the_spot_is_where_the_ray_to_the_mirrored_lamp_meets_the_ceiling() -> None:
    # the mirror point against the ray's crossing, found independently: the camera joined to the lamp's mirror image
    camera_xyz, lamp = np.array([0.3, 2.0, MOUNT_M]), np.array([-0.4, 3.1, 1.9])
    image = np.array([lamp[0], lamp[1], 2 * CEILING_M - lamp[2]])
    t = (CEILING_M - camera_xyz[2]) / (image[2] - camera_xyz[2])
    np.testing.assert_allclose(mirror_spot_xy(camera_xyz, lamp, CEILING_M), (camera_xyz + t * (image - camera_xyz))[:2])
    assert mirror_spot_xy(camera_xyz, np.array([-0.4, 3.1, CEILING_M]), CEILING_M) == pytest.approx(lamp[:2])  # flush: on itself
    # the lobe peaks there: every pixel made tape, the camera offset and the robot turned
    cam = camera(**{**IDEAL, "offset_m": (0.1, 0.05), "glare": {"lamps_m": [[-0.3, 3.4, 2.1]]}})
    assert cam._glare is not None
    pose = np.array([0.1, 3.0, 2.0])
    glare = cam._glare.image(pose, np.full((cam.config.height_px, cam.config.width_px), LABEL_COLOUR, dtype=np.uint8))
    spot = mirror_spot_xy(np.array([*cam._glare.camera_xy(pose), MOUNT_M]), np.array([-0.3, 3.4, 2.1]), CEILING_M)
    assert np.abs(brightest(glare) - world_to_pixel(cam, pose, spot)).max() <= 1.0


def test_moving_the_camera_moves_the_spot_as_the_mirror_geometry_says() -> None:
    lamp = (0.0, 3.0, 2.0)
    cam = camera(**{**IDEAL, "glare": {"lamps_m": [lamp]}})
    assert cam._glare is not None
    tape = np.full((cam.config.height_px, cam.config.width_px), LABEL_COLOUR, dtype=np.uint8)
    d_c, d_l = CEILING_M - MOUNT_M, CEILING_M - lamp[2]
    pose = np.array([0.0, 3.2, math.pi / 2])
    for dx in (0.08, -0.12):
        moved = pose + [dx, 0.0, 0.0]
        before, after = brightest(cam._glare.image(pose, tape)), brightest(cam._glare.image(moved, tape))
        # on the ceiling the spot moves by dx d_l / (d_c + d_l); the view moves with the camera by dx
        spot = mirror_spot_xy(np.array([dx, 3.2, MOUNT_M]), np.array(lamp), CEILING_M)
        assert spot[0] == pytest.approx(dx * d_l / (d_c + d_l))
        predicted = world_to_pixel(cam, moved, spot) - world_to_pixel(
            cam, pose, mirror_spot_xy(np.array([0, 3.2, MOUNT_M]), np.array(lamp), CEILING_M)
        )
        assert abs(predicted[0]) > 10  # the spot moves through the image (-dx d_c / (d_c + d_l) of ceiling)
        assert np.abs((after - before) - predicted).max() <= 1.0


def test_the_glare_adds_to_the_tape_and_the_sensor_saturation_clips_its_hue() -> None:
    cam = camera(**{**IDEAL, "glare": {"lamps_m": [list(LAMP)]}})
    plain, labels = camera(**IDEAL).render(UNDER_T1, labels=True)
    assert labels is not None and cam._glare is not None
    lit, _ = cam.render(UNDER_T1)
    lit_image = cam._glare.image(UNDER_T1, labels)
    assert lit_image is not None
    glare, first, end = lit_image
    tape = labels >= LABEL_COLOUR
    assert (first, end) == (np.flatnonzero(tape.any(axis=1))[0], np.flatnonzero(tape.any(axis=1))[-1] + 1)
    assert np.array_equal(lit[~tape], plain[~tape])  # only the tape is glossy
    expected = np.clip(np.floor(plain.astype(np.float64) + glare + 0.5), 0, 255)
    assert np.abs(lit.astype(np.float64) - expected).max() <= 1.0
    # the spot's core: every channel clipped to white, the tape's hue gone; far from it the tape keeps its colour
    u, v = world_to_pixel(cam, UNDER_T1, mirror_spot_xy(np.array([0.0, 6.9, MOUNT_M]), np.array(LAMP), CEILING_M)).astype(int)
    assert tape[v, u] and (lit[v, u] == 255).all() and not (plain[v, u] == 255).all()
    hsv = cv2.cvtColor(lit, cv2.COLOR_RGB2HSV)
    assert hsv[v, u, 1] == 0
    faint = tape & (glare[..., 0] < 0.5)
    assert faint.any() and np.array_equal(lit[faint], plain[faint])


def frames(seed: int, steps: int = 5, **fields: object) -> list[np.ndarray]:
    return ceiling_frames(seed, steps, **fields)[0]


def test_glare_off_renders_todays_frames_and_on_is_deterministic() -> None:
    default = frames(seed=3)
    assert all(np.array_equal(a, b) for a, b in zip(default, frames(seed=3, glare={"lamps_m": []})))
    # the drive starts under the first target: a lamp beside it lights the tape, moving frames blurred with it
    on = {"glare": {"lamps_m": [[0.2, 0.3, 2.0]]}}
    lit = frames(seed=3, **on)
    assert not all(np.array_equal(a, b) for a, b in zip(default, lit))
    assert all(np.array_equal(a, b) for a, b in zip(lit, frames(seed=3, **on)))
    # with no tape in view the glare changes nothing
    away = np.array([0.0, 3.5, math.pi / 2])
    assert np.array_equal(camera(**IDEAL).render(away)[0], camera(**{**IDEAL, **on}).render(away)[0])


@pytest.mark.parametrize(
    ("glare", "message"),
    [
        ({"lamps_m": [[0.0, 1.0, 2.5]]}, "glare.lamps_m [0.0, 1.0, 2.5]: a lamp must hang below the ceiling at 2.5 m"),
        ({"lamps_m": [[0.0, 1.0]]}, "glare.lamps_m[0]: expected 3 values, got 2"),
        ({"shininess": 0.0}, "glare.shininess must be in [1, 10000], got 0.0"),
        ({"lamp_intensity_cd": -1.0}, "glare.lamp_intensity_cd must be > 0, got -1.0"),
        ({"ceiling_lux": 0.0}, "glare.ceiling_lux must be > 0, got 0.0"),
        ({"refractive_index": 1.0}, "glare.refractive_index must be in (1, 3], got 1.0"),
    ],
)
def test_bad_glare_names_the_field_and_value(glare: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        camera(glare=glare)
