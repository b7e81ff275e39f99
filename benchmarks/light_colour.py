"""The ceiling camera's light colour: its cost, and what the shipped colour thresholds do under it.

1. The cost: the best time of one :meth:`CeilingCamera.render` (a moving frame: the motion-blur path,
   noise on) and of :meth:`CeilingCamera.channel_gains`, without and with each option, with no target in
   view and under T1.
2. The finding: the ``ceiling_target`` localizer's shipped thresholds (``configs/localizers/ceiling_target.yaml``,
   fitted under a colourless light; nothing tuned here) on images of the second target (the illumination
   study's) from ``--seeds`` poses under it, under a colourless light, a 4000 K light seen by a camera
   balanced for 6500 K or by one with a grey-world auto white balance, each without and with the glare of
   pendant lamps (``GLARE``), at brightness gains 0.6, 1.0 and 1.4: per target colour the share of its labelled pixels
   inside its HSV box and inside its RGB box (no motion blur, so the labels are exact; noise on), and the images
   from which the localizer gets a fix in each colour space.

Run: ``.venv/bin/python -m benchmarks.light_colour [--seeds 20]``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from agents.papers.ceiling_target.fit import _HSV_SCALE, inside
from agents.papers.ceiling_target.static import LAMP_BY_TARGET_M, Rig
from envs.features.ceiling import colour_label
from envs.sensors.light_colour import cct_white_rgb, white_balance_gains
from localizers.ceiling_target.vision import hsv8

COLOUR = {"white_balance_k": 6500.0, "cct_k": (4000.0, 4000.0)}
AUTO = {"auto_white_balance": True, "cct_k": (4000.0, 4000.0)}
#: pendant lamps hung 0.5 m below the ceiling over the centre line midway between the panels (every 2.4 m from
#: y = 0; the nearest to T1 0.3 m beyond it), the scene of envs/sensors/glare.py's GlareConfig
GLARE = {"glare": {"lamps_m": [[0.0, 2.4 * k, 2.0] for k in range(10)]}}
#: one lamp 0.5 m below the ceiling, 0.2 m across the corridor from T1's centre: its spot lies on T1's line
SPOT = {"glare": {"lamps_m": [list(LAMP_BY_TARGET_M)]}}
#: the lights of the finding: camera fields and the channel gains handed to the render (the raw light's colour
#: under the auto white balance, which the render balances by the frame)
LIGHTS = {
    "colourless": ({}, np.ones(3)),
    "4000 K, WB 6500 K": (COLOUR, white_balance_gains(4000.0, 6500.0)),
    "4000 K, auto WB": (AUTO, cct_white_rgb(4000.0)),
    "colourless, glare": (GLARE, np.ones(3)),
    "4000 K, WB 6500 K, glare": ({**COLOUR, **GLARE}, white_balance_gains(4000.0, 6500.0)),
    "4000 K, auto WB, glare": ({**AUTO, **GLARE}, cct_white_rgb(4000.0)),
    "colourless, spot on T1": (SPOT, np.ones(3)),
    "4000 K, auto WB, spot on T1": ({**AUTO, **SPOT}, cct_white_rgb(4000.0)),
}


def cost() -> None:
    """Print the best render and channel-gain times without and with each option, a target out of view and in view."""
    poses = {"no target in view": np.array([0.0, 3.0, math.pi / 2]), "under T1": np.array([0.0, 6.9, math.pi / 2])}
    for name, fields in (
        ("colourless", None),
        ("4000 K, WB 6500 K", COLOUR),
        ("4000 K, auto WB", AUTO),
        ("glare", GLARE),
        ("spot on T1", SPOT),
    ):
        cam = Rig.make(camera=fields).camera
        cam.seed_noise(np.random.default_rng(0))
        for where, pose in poses.items():
            previous = pose - np.array([0.0, 0.02, 0.02])
            gains = cam.channel_gains(pose, 1.0)
            render, gain = [], []
            for _ in range(2000):
                t = time.perf_counter()
                cam.render(pose, None, gains, 5, previous=previous)
                render.append(time.perf_counter() - t)
                t = time.perf_counter()
                cam.channel_gains(pose, 1.0)
                gain.append(time.perf_counter() - t)
            print(
                f"{name:18s} {where:18s} render {1e6 * min(render[1:]):.0f} us, channel_gains {1e6 * min(gain):.1f} us"
                " (best of 2000)"
            )


def thresholds(seeds: int) -> None:
    """Print each colour's pixels kept by its HSV and RGB boxes, and the fixes, per light and gain."""
    for light, (fields, balance) in LIGHTS.items():
        camera = {"exposure_s": 0.0, **fields}
        rigs = {space: Rig.make(camera=camera, localizer={"colour_space": space}) for space in ("hsv", "rgb")}
        ranges = rigs["hsv"].localizer._params.thresholds
        cam, target = rigs["hsv"].camera, rigs["hsv"].target
        colours = list(dict.fromkeys(target.code))
        for gain in (0.6, 1.0, 1.4):
            kept = {c: {"hsv": 0, "rgb": 0, "all": 0} for c in colours}
            fixes = {"hsv": 0, "rgb": 0}
            for seed in range(seeds):
                rng = np.random.default_rng([seed, 77])
                pose = np.array([target.x_m, target.y_m, math.pi / 2]) + rng.uniform([-0.1, -0.1, -0.35], [0.1, 0.1, 0.35])
                cam.seed_noise(rng)
                image, labels = cam.render(pose, None, gain * balance, int(rng.integers(1 << 30)), labels=True)
                assert labels is not None
                hsv, rgb, lab = (
                    hsv8(image).reshape(-1, 3) / _HSV_SCALE,
                    image.reshape(-1, 3).astype(np.float64),
                    labels.reshape(-1),
                )
                for c in colours:
                    mine = lab == colour_label(c)
                    kept[c]["all"] += int(mine.sum())
                    for space in ("hsv", "rgb"):
                        kept[c][space] += int(inside(ranges[c], hsv, rgb, space)[mine].sum())
                for space, rig in rigs.items():
                    fixes[space] += rig.sight(pose, np.random.default_rng([seed, 78]), gain * balance) is not None
            cells = "  ".join(
                f"{c} hsv {kept[c]['hsv'] / kept[c]['all']:.3f} rgb {kept[c]['rgb'] / kept[c]['all']:.3f}" for c in colours
            )
            print(f"{light:26s} gain {gain}: {cells} | fixes hsv {fixes['hsv']}/{seeds} rgb {fixes['rgb']}/{seeds}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args()
    print(
        "channel gains (r, g, b) of a 4000 K light under a 6500 K white balance:",
        np.round(white_balance_gains(4000.0, 6500.0), 3),
    )
    cost()
    thresholds(args.seeds)


if __name__ == "__main__":
    main()
