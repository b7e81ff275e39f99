"""Daylight that changes over the day, and the camera's auto white balance (grey world)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import envs  # noqa: F401  (registers the ids)
from core.schema import ConfigError, replace_checked
from envs.config import load_world
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import IDEAL, CeilingCamera
from envs.sensors.light_colour import grey_world_gains
from tests.envs.ceiling_frames import ceiling_frames

#: midway between two light panels, away from the sprinklers, signs and targets: tiles and joints only
PLAIN = np.array([0.0, 2.4, math.pi / 2])


def camera(grey: bool = False, **fields: object) -> CeilingCamera:
    world = load_world("ceiling_corridor")
    if grey:  # a grey ceiling: tiles and joints without a colour of their own
        world = replace_checked(world, {"features": {"ceiling": {"rgb": [200, 200, 200], "joint_rgb": [140, 140, 140]}}}, "test")
    cam = LocalizationEnv(world, camera=fields or None).sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    return cam


@pytest.mark.parametrize("cct_k", [2800.0, 4230.0, 6500.0, 12000.0])
def test_grey_world_on_a_grey_ceiling_gives_neutral_gains_under_any_light(cct_k: float) -> None:
    cam = camera(grey=True, **{**IDEAL, "auto_white_balance": True, "cct_k": (cct_k, cct_k)})
    raw = cam.channel_gains(PLAIN, 0.0)
    assert cct_k == 6500.0 or abs(raw[0] - raw[2]) > 0.1  # the light alone would tint the frame
    image, _ = cam.render(PLAIN, gain=raw)
    np.testing.assert_allclose(grey_world_gains(raw, [200.0, 200.0, 200.0]), np.full(3, raw[1]), rtol=1e-12)
    assert np.abs(image.astype(int) - image[..., 1:2]).max() <= 1  # every pixel grey
    plain, _ = camera(grey=True, **IDEAL).render(PLAIN, gain=raw[1])
    assert np.abs(image.astype(int) - plain).max() <= 1  # as a colourless light of the same brightness


def test_grey_world_makes_the_frames_mean_grey_and_cancels_the_lights_colour() -> None:
    images = []
    for cct_k in (3000.0, 9000.0):
        cam = camera(**{**IDEAL, "auto_white_balance": True, "cct_k": (cct_k, cct_k)})
        image, _ = cam.render(PLAIN, gain=cam.channel_gains(PLAIN, 0.0))
        means = image.reshape(-1, 3).mean(axis=0)
        assert np.abs(means - means[1]).max() < 0.5
        images.append(image.astype(int))
    assert np.abs(images[0] - images[1]).max() <= 1
    fixed = camera(**{**IDEAL, "white_balance_k": 6500.0, "cct_k": (3000.0, 3000.0)})
    tinted, _ = fixed.render(PLAIN, gain=fixed.channel_gains(PLAIN, 0.0))
    assert tinted[..., 0].mean() - tinted[..., 2].mean() > 50  # a fixed balance keeps the warm light's cast


def frames(seed: int, steps: int = 4, **fields: object) -> tuple[list[np.ndarray], float]:
    out, camera = ceiling_frames(seed, steps, **fields)
    daylight = camera.daylight_k
    return out, daylight


def test_the_daylight_is_drawn_per_episode_from_its_range_alone() -> None:
    light = {"white_balance_k": 6500.0, "cct_k": (4230.0, 5500.0)}
    drawn = {seed: frames(seed, **light, daylight_cct_k=(5000.0, 7500.0))[1] for seed in (0, 1, 2)}
    assert all(5000.0 <= k <= 7500.0 for k in drawn.values()) and len(set(drawn.values())) == 3
    assert frames(1, **light, daylight_cct_k=(5000.0, 7500.0))[1] == drawn[1]  # the same seed, the same daylight
    # a range of one value gives the fixed cct_k's frames: the draw takes nothing from the other draws
    fixed, none = frames(2, white_balance_k=6500.0, cct_k=(4230.0, 6000.0))
    assert none == 0.0
    one, _ = frames(2, **light, daylight_cct_k=(6000.0, 6000.0))
    assert all(np.array_equal(a, b) for a, b in zip(fixed, one))
    assert not np.array_equal(frames(2, **light)[0][0], one[0])  # the drive starts midway between two panels


def test_the_options_off_render_todays_frames_and_on_is_deterministic() -> None:
    default, _ = frames(5)
    off, _ = frames(5, auto_white_balance=False, daylight_cct_k=(0.0, 0.0))
    assert all(np.array_equal(a, b) for a, b in zip(default, off))
    on = {"auto_white_balance": True, "cct_k": (4230.0, 5500.0), "daylight_cct_k": (5000.0, 7500.0)}
    a, b = frames(5, **on)[0], frames(5, **on)[0]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not any(np.array_equal(x, y) for x, y in zip(default, a))


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"auto_white_balance": True, "white_balance_k": 6500.0}, "white_balance_k 6500 and auto_white_balance: give one"),
        ({"cct_k": (4000.0, 5500.0)}, "cct_k [4000.0, 5500.0] needs white_balance_k"),
        ({"auto_white_balance": True, "cct_k": (1000.0, 5500.0)}, "cct_k must lie in 2000..15000 K, got [1000.0, 5500.0]"),
        (
            {"white_balance_k": 6500.0, "cct_k": (4230.0, 5500.0), "daylight_cct_k": (7500.0, 5000.0)},
            "daylight_cct_k must be [lowest, highest] within 2000..15000 K, got [7500.0, 5000.0]",
        ),
        ({"auto_white_balance": True, "daylight_cct_k": (5000.0, 7500.0)}, "daylight_cct_k [5000.0, 7500.0] needs cct_k"),
    ],
)
def test_bad_light_fields_name_the_field_and_value(fields: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=r"ceiling_camera\." + re.escape(message)):
        camera(**fields)
