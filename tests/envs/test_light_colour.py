"""The ceiling camera's light colour: the light's colour temperature against a fixed white balance."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

import envs  # noqa: F401  (registers the ids)
from core.schema import ConfigError
from envs.features.ceiling import LABEL_CEILING
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import IDEAL, CeilingCamera
from envs.sensors.light_colour import XYZ_TO_SRGB, cct_white_rgb
from tests.envs.ceiling_frames import ceiling_frames

ID = "crowdloc/CeilingCorridor-v0"
#: cool-white fluorescent light seen by a camera balanced for daylight
WARM = {"white_balance_k": 6500.0, "cct_k": (4000.0, 4000.0)}
#: points of the Planckian locus in CIE 1931 (x, y), as tabulated (Wyszecki and Stiles, Color Science, 2nd ed., table 1(3.11))
LOCUS_XY = {4000.0: (0.3805, 0.3768), 6500.0: (0.3135, 0.3237)}


def camera(**fields: object) -> CeilingCamera:
    cam = LocalizationEnv("ceiling_corridor", camera=fields or None).sensors["camera"]
    assert isinstance(cam, CeilingCamera)
    return cam


def tabulated_white(cct_k: float) -> np.ndarray:
    """Linear sRGB (green 1) of the tabulated locus point: the oracle for Krystek's fit."""
    x, y = LOCUS_XY[cct_k]
    rgb = XYZ_TO_SRGB @ np.array([x / y, 1.0, (1 - x - y) / y])
    return rgb / rgb[1]


def frames(seed: int, steps: int = 6, **fields: object) -> list[np.ndarray]:
    return ceiling_frames(seed, steps, **fields)[0]


@pytest.mark.parametrize("cct_k", [4000.0, 6500.0])
def test_krystek_fit_meets_the_tabulated_planckian_locus(cct_k: float) -> None:
    np.testing.assert_allclose(cct_white_rgb(cct_k), tabulated_white(cct_k), rtol=0.01)


@pytest.mark.parametrize("cct_k", [2800.0, 4230.0, 6500.0])
def test_light_at_the_white_balance_is_neutral(cct_k: float) -> None:
    cam = camera(**{**IDEAL, "white_balance_k": cct_k, "cct_k": (cct_k, cct_k)})
    pose = np.array([0.0, 3.0, math.pi / 2])
    gains = cam.channel_gains(pose, 1.0)
    assert gains[0] == gains[1] == gains[2] == cam.gain(pose, 1.0)
    plain, _ = camera(**IDEAL).render(pose, gain=0.8)
    balanced, _ = cam.render(pose, gain=cam.channel_gains(pose, 0.0) * 0.8)
    assert np.array_equal(plain, balanced)


def test_a_light_warmer_than_the_white_balance_raises_red_over_blue_by_the_locus_factor() -> None:
    expected = (tabulated_white(4000.0) / tabulated_white(6500.0))[[0, 2]]
    expected_rb = expected[0] / expected[1]  # about 2.6
    cam = camera(**{**IDEAL, **WARM})
    pose = np.array([0.0, 3.0, math.pi / 2])
    gains = cam.channel_gains(pose, 0.0)
    assert gains[1] == cam.gain(pose, 0.0)  # green keeps the brightness gain
    assert gains[0] / gains[2] == pytest.approx(expected_rb, rel=0.01)
    # on the grey ceiling's pixels (dark enough that no channel saturates) each channel scales by its gain
    plain, labels = cam.render(pose, gain=0.5, labels=True)
    tinted, _ = cam.render(pose, gain=0.5 * gains / gains[1])
    ceiling = labels == LABEL_CEILING
    assert ceiling.sum() > 10_000
    for channel in range(3):
        want = plain[..., channel][ceiling] * gains[channel] / gains[1]
        assert np.abs(tinted[..., channel][ceiling] - want).max() <= 1.0
    r, b = tinted[..., 0][ceiling].mean(), tinted[..., 2][ceiling].mean()
    r0, b0 = plain[..., 0][ceiling].mean(), plain[..., 2][ceiling].mean()
    assert (r / b) / (r0 / b0) == pytest.approx(expected_rb, rel=0.02)


def test_the_colour_follows_the_panels_pitch() -> None:
    cam = camera(white_balance_k=6500.0, cct_k=(4230.0, 5500.0))
    under = cam.ceiling.light_first_y_m
    assert cam.light_cct_k(np.array([0.0, under, 0.0])) == pytest.approx(4230.0)
    assert cam.light_cct_k(np.array([0.0, under + cam.ceiling.light_pitch_m / 2, 0.0])) == pytest.approx(5500.0)


def test_the_default_renders_todays_frames_and_the_option_changes_them() -> None:
    default = frames(seed=4)
    off = frames(seed=4, white_balance_k=0.0, cct_k=(0.0, 0.0))
    neutral = frames(seed=4, white_balance_k=5000.0, cct_k=(5000.0, 5000.0))  # per-channel path, equal gains
    assert all(np.array_equal(a, b) for a, b in zip(default, off))
    assert all(np.array_equal(a, b) for a, b in zip(default, neutral))
    warm = frames(seed=4, **WARM)
    assert not any(np.array_equal(a, b) for a, b in zip(default, warm))
    assert all(w[..., 0].mean() > d[..., 0].mean() and w[..., 2].mean() < d[..., 2].mean() for w, d in zip(warm, default))


def test_the_light_colour_is_deterministic() -> None:
    fields = {"white_balance_k": 6500.0, "cct_k": (4230.0, 5500.0)}
    a, b = frames(seed=7, **fields), frames(seed=7, **fields)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        (
            {"white_balance_k": 1000.0, "cct_k": (4000.0, 4000.0)},
            "white_balance_k must be 0 (off) or in 2000..15000 K, got 1000.0",
        ),
        ({"white_balance_k": -5.0}, "white_balance_k must be 0 (off) or in 2000..15000 K, got -5.0"),
        ({"white_balance_k": 6500.0, "cct_k": (4000.0, 20000.0)}, "cct_k must lie in 2000..15000 K, got [4000.0, 20000.0]"),
        ({"cct_k": (4000.0, 5500.0)}, "cct_k [4000.0, 5500.0] needs white_balance_k"),
        ({"white_balance_k": 6500.0, "cct_k": (4000.0, 4000.0, 4000.0)}, "cct_k: expected 2 values, got 3"),
    ],
)
def test_bad_light_colours_name_the_field_and_value(fields: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=r"(ceiling_)?camera\." + re.escape(message)):
        camera(**fields)
