"""Environment stepping speed, beside plain-pymunk reference loops measured on the same machine."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pymunk

import envs  # noqa: F401  (registers the ids)
from benchmarks.common import Result, rate


def _env_rate(env_id: str, steps: int, **kwargs: object) -> tuple[float, float, float]:
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(steps, 2)).astype(np.float32)
    env.step(actions[0])  # compile kernels outside the timing

    def run(n: int) -> None:
        for a in actions[:n]:
            _, _, terminated, truncated, _ = env.step(a)
            if terminated or truncated:
                env.reset()

    out = rate(run, steps)
    env.close()
    return out


def _pymunk_reference(bodies: int, queries_per_step: int, steps: int) -> tuple[float, float, float]:
    """A plain pymunk loop: ``bodies`` moving circles, then ``queries_per_step`` segment_query_first."""
    space = pymunk.Space()
    rng = np.random.default_rng(0)
    moving = []
    for _ in range(bodies):
        body = pymunk.Body(10.0, pymunk.moment_for_circle(10.0, 0, 0.23))
        body.position = tuple(rng.uniform(0.5, 4.5, 2))
        space.add(body, pymunk.Circle(body, 0.23))
        moving.append(body)
    for a, b in [((0, 0), (5, 0)), ((5, 0), (5, 5)), ((5, 5), (0, 5)), ((0, 5), (0, 0))]:
        space.add(pymunk.Segment(space.static_body, a, b, 0.02))
    robot = moving[0]
    angles = np.linspace(-math.pi, math.pi, queries_per_step, endpoint=False)
    ends = [(10 * math.cos(t), 10 * math.sin(t)) for t in angles]
    flt = pymunk.ShapeFilter()

    def run(n: int) -> None:
        for _ in range(n):
            for body in moving:
                body.velocity = (1.0, 0.5)
            space.step(1 / 30)
            x, y = robot.position
            for ex, ey in ends:
                space.segment_query_first((x, y), (x + ex, y + ey), 0.0, flt)

    return rate(run, steps)


def run_all(quick: bool = False) -> list[Result]:
    n = 2000 if quick else 20000
    results = []
    med, lo, hi = _env_rate("crowdloc/RoboCupCrowded-v0", n, crowd_size=14)
    results.append(
        Result(
            "envs",
            "RoboCupCrowded-v0, 14 robots, no rendering",
            med,
            "steps/s",
            f"{lo:,.0f}-{hi:,.0f}",
            ">= 10,000",
            med >= 10_000,
        )
    )
    med, lo, hi = _env_rate("crowdloc/RoboCupCrowded-v0", n)
    results.append(Result("envs", "RoboCupCrowded-v0, default 6 robots", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}"))
    med, lo, hi = _env_rate("crowdloc/RoboCupStatic-v0", n)
    results.append(Result("envs", "RoboCupStatic-v0", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}"))
    m = n // 4
    med, lo, hi = _env_rate("crowdloc/CrowdedRoom-v0", m, crowd_size=30)
    results.append(
        Result(
            "envs",
            "CrowdedRoom-v0, 1081-beam LIDAR, 30 people with legs (60 leg discs at 0.2 m), furnished room",
            med,
            "steps/s",
            f"{lo:,.0f}-{hi:,.0f}",
            ">= 5,000",
            med >= 5_000,
        )
    )
    med, lo, hi = _env_rate("crowdloc/CrowdedRoom-v0", m, crowd_size=30, crowd={"queues": {"shape": "column"}})
    results.append(
        Result("envs", "CrowdedRoom-v0, the same with people as footprint columns", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}")
    )
    med, lo, hi = _env_rate("crowdloc/CrowdedRoom-v0", m, crowd_size=20, crowd={"walkers": {"count": 10}})
    results.append(
        Result("envs", "CrowdedRoom-v0, 20 queueing + 10 social-force walkers", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}")
    )
    c = n // 10
    med, lo, hi = _env_rate("crowdloc/CeilingCorridor-v0", c, crowd_size=20)
    results.append(
        Result(
            "envs",
            "CeilingCorridor-v0, 320 x 240 image every step, 20 people, random actions",
            med,
            "steps/s",
            f"{lo:,.0f}-{hi:,.0f}",
            ">= 2,000",
            med >= 2_000,
        )  # fmt: skip
    )
    med, lo, hi = _env_rate("crowdloc/CeilingCorridor-v0", c, crowd_size=20, camera={"exposure_s": 0.0})
    results.append(Result("envs", "CeilingCorridor-v0, as above without motion blur", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}"))
    med, lo, hi = _pymunk_reference(15, 8, n // 2)
    results.append(
        Result("reference", "plain pymunk: 15 circles + 8 segment_query_first per step", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}")
    )
    med, lo, hi = _pymunk_reference(31, 1081, max(m // 20, 20))
    results.append(
        Result(
            "reference", "plain pymunk: 31 circles + 1081 segment_query_first per step", med, "steps/s", f"{lo:,.0f}-{hi:,.0f}"
        )
    )
    return results
