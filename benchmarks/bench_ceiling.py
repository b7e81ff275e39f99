"""The ceiling-target pipeline on one 320 x 240 image of the corridor's camera.

Images are rendered at poses near the targets (one target in view in every image: the
pipeline's full path) and, separately, along the corridor between targets (most frames of a
drive: no target in view). Each ``update`` of ``ceiling_target`` is timed.
"""

from __future__ import annotations

import math

import numpy as np

from agents.papers.ceiling_target.fit import camera_of
from benchmarks.common import Result, per_call_ms
from envs.localization_env import LocalizationEnv
from localizers.ceiling_target import CeilingImage, CeilingTargetLocalizer
from localizers.ceiling_target.vision import CameraIntrinsics
from localizers.registry import make_localizer


def _images(near_target: bool, count: int) -> tuple[list[CeilingImage], CeilingTargetLocalizer]:
    env = LocalizationEnv("ceiling_corridor")
    camera = camera_of(env)
    intrinsics = CameraIntrinsics.from_metadata(camera.metadata())
    rng = np.random.default_rng(0)
    camera.seed_noise(rng)
    targets = camera.ceiling.targets
    images = []
    for i in range(count):
        y = targets[i % len(targets)].y_m + rng.uniform(-0.15, 0.15) if near_target else rng.uniform(1.0, 6.0)
        pose = np.array([rng.uniform(-0.15, 0.15), y, math.pi / 2 + rng.uniform(-0.3, 0.3)])
        image, _ = camera.render(pose, None, 1.0, int(rng.integers(1 << 30)))
        images.append(CeilingImage(image, intrinsics))
    localizer = make_localizer("ceiling_target", env.landmark_map, dt_s=env.config.dt_s)
    assert isinstance(localizer, CeilingTargetLocalizer)
    localizer.reset(rng, None)
    return images, localizer


def run_all(quick: bool = False) -> list[Result]:
    count = 50 if quick else 400
    results = []
    for near, what, target in ((True, "a target in view", "<= 1 ms"), (False, "no target in view", "")):
        images, localizer = _images(near, count)
        frames = iter(images * 2)
        for _ in range(10):
            localizer.update(next(frames))  # warm up
        med, p99 = per_call_ms(lambda loc=localizer, it=frames: loc.update(next(it)), count)
        passed = med <= 1.0 if target else None
        results.append(
            Result(
                "ceiling", f"ceiling_target pipeline, one 320 x 240 image, {what}", med, "ms", f"p99 {p99:.2g}", target, passed
            )
        )
    return results
