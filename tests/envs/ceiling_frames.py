"""The corridor's ceiling images over a short seeded drive: the rollout the light-colour, glare and
auto-white-balance tests compare frames on."""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

import envs  # noqa: F401  (registers the ids)


def ceiling_frames(seed: int, steps: int, **camera: object) -> tuple[list[np.ndarray], Any]:
    """The ceiling images of ``steps`` steps of a gentle S-drive among 10 walkers (the reset's image
    first), with ``camera`` overrides, and the camera sensor (read after the drive)."""
    env = gym.make("crowdloc/CeilingCorridor-v0", camera=camera or None, crowd_size=10)
    obs, _ = env.reset(seed=seed)
    out = [obs["ceiling_image"]]
    for k in range(steps):
        obs, *_ = env.step(np.array([0.8, 0.3 * math.sin(k)], dtype=np.float32))
        out.append(obs["ceiling_image"])
    sensor = env.unwrapped.sensors["camera"]  # type: ignore[attr-defined]
    env.close()
    return out, sensor
