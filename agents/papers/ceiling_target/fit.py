"""``crowdloc fit ceiling_target``: learn the colour thresholds from rendered, labelled images.

The upward camera renders the corridor's ceiling at poses near the targets and the signs,
under illumination gains wider than the camera's own variation, with its noise and
vignetting and the heads of passers-by; it also says which pixel shows what (the labels of
:mod:`envs.features.ceiling`). Each target colour's threshold box holds ``coverage`` of its
labelled pixels (:func:`localizers.ceiling_target.vision.fit_colour_range`), in HSV as the paper and
in RGB for comparison. Held-out images (other seeds) then measure, per colour, the share of
its pixels inside its box and the share of every other kind of pixel (tiles, lights, the
exit sign, the other colours) that falls inside it too.

The thresholds and the record of the data behind them are written into the localizer's YAML,
below a marker line; everything above it is kept.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from tqdm import tqdm

from agents.common.util import at_least, check_output_file, seed_int
from core.schema import ConfigError, check
from envs.features.ceiling import LABEL_NAMES, PALETTE, colour_label
from envs.localization_env import LocalizationEnv
from envs.sensors.ceiling_camera import CeilingCamera
from localizers.ceiling_target.vision import ColourRange, fit_colour_range, hsv8
from localizers.registry import params_path

MARKER = "# --- learned by `crowdloc fit ceiling_target` (do not edit below by hand) ---"
#: a fitted threshold that keeps less than this share of its own colour's held-out pixels is
#: flagged: the box is fitted to hold 99.5 % of the training pixels, so far less on fresh images
#: means the training images showed too few of that colour's pixels, under too few illuminations
MIN_KEPT_SHARE = 0.9
_HSV_SCALE = np.array([256.0, 255.0, 255.0])  # OpenCV's 8-bit HSV_FULL -> the paper's units


@dataclass(frozen=True)
class FitPlan:
    """Which images the thresholds are learned from and tested on."""

    world: str = "ceiling_corridor"
    train_images: int = 160
    test_images: int = 80
    seed: int = 0  # training images from this seed, held-out ones from seed + 1
    gain_range: tuple[float, float] = (0.6, 1.4)  # illumination gains drawn per image
    near_target_share: float = 0.75  # the rest of the images are near a sign or anywhere
    coverage: float = 0.995
    margin: float = 0.02  # S, V and RGB
    hue_margin: float = 0.005
    #: the camera's overrides (the light's colour, auto white balance, glare); the light's colour at
    #: each image's pose times its gain (cct_k's middle value; a per-episode daylight is not drawn here)
    camera: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        check(self.train_images >= 10 and self.test_images >= 10, "fit: need at least 10 training and 10 test images")
        lo, hi = self.gain_range
        check(0 < lo <= hi, f"fit: gain_range must be 0 < low <= high, got {self.gain_range}")
        check(0 <= self.near_target_share <= 1, f"fit: near_target_share must be in [0, 1], got {self.near_target_share}")


def camera_of(env: LocalizationEnv) -> CeilingCamera:
    """The env's ceiling camera, or a ConfigError."""
    camera = env.sensor_of_type("ceiling_camera")
    if not isinstance(camera, CeilingCamera):
        raise ConfigError(f"world {env.config.name!r} has no ceiling_camera sensor")
    return camera


def light_colour(camera: CeilingCamera, pose: NDArray[np.float64]) -> NDArray[np.float64]:
    """The ``(3,)`` channel gains per unit brightness of the light at ``pose``: ones under a colourless light;
    the light's colour against the white balance, or its raw colour under the auto white balance (which the
    render balances by the frame). An image at brightness ``gain`` is rendered with ``gain * light_colour``."""
    return camera.channel_gains(pose, 0.0) / camera.gain(pose, 0.0)


def labelled_images(plan: FitPlan, seed: int, count: int) -> Iterator[tuple[NDArray[np.uint8], NDArray[np.uint8]]]:
    """``count`` rendered images and their pixel labels, without motion blur (labels are exact)."""
    env = LocalizationEnv(plan.world, camera={**plan.camera, "exposure_s": 0.0})
    camera = camera_of(env)
    ceiling = camera.ceiling
    rng = np.random.default_rng(seed)
    camera.seed_noise(rng)
    xmin, ymin, xmax, ymax = env.config.field_m
    spots = [(t.x_m, t.y_m) for t in ceiling.targets]
    signs = [(s.x_m, s.y_m) for s in ceiling.signs]
    for i in range(count):
        if spots and rng.random() < plan.near_target_share:
            cx, cy = spots[i % len(spots)]  # every target in turn: each colour is seen
            xy = (cx + rng.uniform(-0.3, 0.3), cy + rng.uniform(-0.4, 0.4))
        elif signs and rng.random() < 0.5:
            cx, cy = signs[rng.integers(len(signs))]
            xy = (cx + rng.uniform(-0.3, 0.3), cy + rng.uniform(-0.3, 0.3))
        else:
            xy = (rng.uniform(-0.7, 0.7), rng.uniform(ymin + 0.5, ymax - 0.5))
        pose = np.array([[xy[0], xy[1], rng.uniform(-math.pi, math.pi)]])
        heads = pose[:, :2] + rng.normal(0.0, 0.45, size=(int(rng.integers(0, 3)), 2))
        heads = heads[np.hypot(*(heads - pose[:, :2]).T) > 0.45]  # people stand outside the robot
        # gains spread evenly over the range (a low-discrepancy sequence), whatever the count
        lo, hi = plan.gain_range
        gain = lo + (hi - lo) * ((i * 0.6180339887498949 + rng.uniform(0, 0.05)) % 1.0)
        image, labels = camera.render(pose, heads, gain * light_colour(camera, pose[0]), int(rng.integers(1 << 30)), labels=True)
        assert labels is not None
        yield image, labels


def _pixels(images: Any, count: int, desc: str) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.uint8]]:
    """HSV (paper units), RGB and labels of every pixel of ``images``, flattened."""
    hsv, rgb, lab = [], [], []
    for image, labels in tqdm(images, total=count, desc=desc, unit="image", leave=False):
        hsv.append(hsv8(image).reshape(-1, 3) / _HSV_SCALE)
        rgb.append(image.reshape(-1, 3).astype(np.float64))
        lab.append(labels.reshape(-1))
    return np.concatenate(hsv), np.concatenate(rgb), np.concatenate(lab)


def inside(rng: ColourRange, hsv: NDArray[np.float64], rgb: NDArray[np.float64], space: str) -> NDArray[np.bool_]:
    """Which pixels (paper-unit HSV and RGB, ``(n, 3)`` each) fall in a colour's box."""
    if space == "rgb":
        return np.all((rgb >= rng.rgb_lo) & (rgb <= rng.rgb_hi), axis=1)
    lo, hi = rng.hsv_lo, rng.hsv_hi
    h = hsv[:, 0]
    hue = (h >= lo[0]) & (h <= hi[0]) if lo[0] <= hi[0] else (h >= lo[0]) | (h <= hi[0])
    return hue & np.all((hsv[:, 1:] >= lo[1:]) & (hsv[:, 1:] <= hi[1:]), axis=1)


def fit(plan: FitPlan) -> tuple[dict[str, ColourRange], dict[str, Any]]:
    """Learn the ranges of every colour the world's targets use; measure them on held-out images.

    Returns the ranges and the record: the plan, pixel counts, and per colour and space the
    held-out true-positive share and the false-positive share of every other pixel kind.
    """
    env = LocalizationEnv(plan.world)
    colours = sorted({c for t in camera_of(env).ceiling.targets for c in t.code}, key=list(PALETTE).index)
    hsv, rgb, lab = _pixels(labelled_images(plan, plan.seed, plan.train_images), plan.train_images, "fit: training images")
    ranges: dict[str, ColourRange] = {}
    counts = {}
    for colour in colours:
        mine = lab == colour_label(colour)
        counts[colour] = int(mine.sum())
        if counts[colour] < 10:
            raise ConfigError(f"fit: colour {colour!r} has only {counts[colour]} labelled pixels in {plan.train_images} images")
        ranges[colour] = fit_colour_range(hsv[mine], rgb[mine], plan.coverage, plan.margin, plan.hue_margin)
    hsv, rgb, lab = _pixels(labelled_images(plan, plan.seed + 1, plan.test_images), plan.test_images, "fit: held-out images")
    held_out: dict[str, Any] = {}
    for colour, rng in ranges.items():
        mine = lab == colour_label(colour)
        per_space = {}
        for space in ("hsv", "rgb"):
            hit = inside(rng, hsv, rgb, space)
            others = {
                LABEL_NAMES[int(k)]: round(float(hit[lab == k].mean()), 6) for k in np.unique(lab) if k != colour_label(colour)
            }
            per_space[space] = {
                "true_positive": round(float(hit[mine].mean()), 4) if mine.any() else None,
                "false_positive": others,
            }
        held_out[colour] = per_space
    record = {
        "plan": {k: list(v) if isinstance(v, tuple) else v for k, v in asdict(plan).items()},
        "training_pixels": counts,
        "held_out": held_out,
    }
    warnings = fit_warnings(record)
    if warnings:
        record["warnings"] = warnings
    return ranges, record


def fit_warnings(record: dict[str, Any]) -> list[str]:
    """One line per colour whose fitted HSV threshold keeps less than :data:`MIN_KEPT_SHARE` of
    its own held-out pixels, naming the colour, the share kept and the training pixels behind it.

    The fit itself is sound (a box holding 99.5 % of the training pixels on each channel, and
    that is what it keeps of them); a low share on held-out images means the training images
    showed the colour too rarely: a colour that only some targets carry (blue, magenta) gets a
    few hundred pixels from a few images, under a few illumination gains, so its value range is
    too narrow for the gains the held-out images have. More ``--train-images`` cure it."""
    plan = record["plan"]
    lines = []
    for colour, spaces in record["held_out"].items():
        kept = spaces["hsv"]["true_positive"]
        if kept is not None and kept < MIN_KEPT_SHARE:
            lines.append(
                f"the fitted threshold of {colour} keeps only {100 * kept:.0f} % of {colour}'s own pixels on the held-out "
                f"images (under {100 * MIN_KEPT_SHARE:.0f} %): it was fitted to {record['training_pixels'][colour]} pixels "
                f"of {plan['train_images']} training images; give more --train-images (default {FitPlan.train_images})"
            )
    return lines


def thresholds_yaml(ranges: dict[str, ColourRange], record: dict[str, Any]) -> str:
    """The YAML block written below :data:`MARKER`."""

    def short(values: tuple[float, ...]) -> list[float]:
        return [round(v, 4) for v in values]

    thresholds = {
        name: {"hsv_lo": short(r.hsv_lo), "hsv_hi": short(r.hsv_hi), "rgb_lo": short(r.rgb_lo), "rgb_hi": short(r.rgb_hi)}
        for name, r in ranges.items()
    }
    return yaml.safe_dump({"thresholds": thresholds, "fitted_on": record}, sort_keys=False, default_flow_style=None, width=120)


def write(path: Path, ranges: dict[str, ColourRange], record: dict[str, Any], overwrite: bool, base: Path | None = None) -> Path:
    """Write the localizer YAML ``path``: the text above the marker of ``path`` (or of ``base``,
    the shipped file, for a new one) and the learned block.

    Raises:
        ConfigError: if ``path`` exists and ``overwrite`` is false.
    """
    if path.exists() and not overwrite:
        raise ConfigError(f"{path} exists; give --overwrite to replace its thresholds")
    source = path if path.exists() else (base or params_path("ceiling_target"))
    head = source.read_text().split(MARKER)[0].rstrip() + "\n\n" if source.is_file() else ""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(head + MARKER + "\n" + thresholds_yaml(ranges, record))
    return path


def camera_json(text: str) -> dict[str, Any]:
    """``--camera``: a JSON mapping of the camera's fields (their names and values are checked by the env)."""
    try:
        value = json.loads(text)
    except ValueError:
        value = None
    if not isinstance(value, dict):
        raise argparse.ArgumentTypeError(f"--camera must be a JSON mapping of the camera's fields, got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", type=Path, default=Path("results/fit/ceiling_target.yaml"),
                        help="the localizer YAML to write (default results/fit/ceiling_target.yaml; the shipped one is "
                        "configs/localizers/ceiling_target.yaml)")  # fmt: skip
    parser.add_argument("--overwrite", action="store_true", help="replace the thresholds of an existing --out file")
    parser.add_argument("--train-images", type=at_least(10), default=FitPlan.train_images,
                        help=f"rendered, labelled images the thresholds are learned from (>= 10; default "
                        f"{FitPlan.train_images}; fewer leave a colour that few targets carry with a box too narrow)")  # fmt: skip
    parser.add_argument(
        "--test-images",
        type=at_least(10),
        default=FitPlan.test_images,
        help=f"held-out images the thresholds are measured on (>= 10; default {FitPlan.test_images})",
    )
    parser.add_argument(
        "--camera",
        type=camera_json,
        default={},
        help="the camera's overrides as JSON, to fit under the light's colour, e.g. "
        '\'{"white_balance_k": 6500, "cct_k": [4230, 5500]}\' (default: the world\'s camera)',
    )
    parser.add_argument(
        "--seed",
        type=seed_int,
        default=FitPlan.seed,
        help=f"seed of the training images; the held-out ones use seed + 1 (default {FitPlan.seed})",
    )


def run_cli(args: argparse.Namespace) -> Path:
    check_output_file(args.out, args.overwrite)  # before the fit, not after it
    plan = FitPlan(train_images=args.train_images, test_images=args.test_images, seed=args.seed, camera=args.camera)
    ranges, record = fit(plan)
    for colour, spaces in record["held_out"].items():
        worst = max(spaces["hsv"]["false_positive"].items(), key=lambda kv: kv[1])
        print(
            f"{colour:8s} hsv: {spaces['hsv']['true_positive']:.3f} of its pixels inside, worst other: {worst[0]} {worst[1]:.4f}"
        )
    for line in record.get("warnings", []):
        print(f"warning: {line}", file=sys.stderr)
    return write(args.out, ranges, record, args.overwrite)
