"""Does global localization in the crowded room keep the truth in its belief long enough to act on?

The room is nearly symmetric: a pose turned 90 or 180 degrees about its centre explains many scans
almost as well as the truth. A particle filter that gathers all its weight on such a twin after
its first scan leaves a policy nothing to choose between, so before a policy can learn to look
where the twins differ, the belief must still hold the truth when it acts.

For each setting of ``mcl_lidar`` below, each crowd size and seed: ``crowdloc/CrowdedRoom-v0``
with ``prior="none"`` (particles uniform over the room), the robot turning on the spot (``spin``,
the look-around every room policy starts with), and at each check time the script records

- **truth held**: the belief's weight within ``0.5 m`` and ``20 deg`` of the true pose is at
  least 5 % (the truth is one of the modes a policy could act on);
- **on a twin**: the localizer claims a pose more than 1 m or 45 deg off (the room task's
  ``wrong_pose``); a belief can hold the truth and still claim a twin.

Run: ``.venv/bin/python -m benchmarks.belief_retention [--seeds 50] [--crowds 0 16 30]``.
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import agents  # noqa: F401  (registers the ids)
from agents.policies import make_policy
from core.geometry import wrap_angle

ENV_ID = "crowdloc/CrowdedRoom-v0"
#: (label, mcl_lidar overrides): the task's settings first, then what could keep a twin from winning
SETTINGS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("task's mcl_lidar (1000 particles, 1081 beams)", {}),
    ("5000 particles", {"n_particles": 5000}),
    ("KLD-sampling from 5000 (100..5000)", {"kld": True, "n_particles": 5000}),
    ("30 beams (amcl's max_beams: beam_stride 36)", {"beam_stride": 36}),
    ("5000 particles, 30 beams", {"n_particles": 5000, "beam_stride": 36}),
    ("first scan draws from 20000 poses (global_candidates)", {"global_candidates": 20_000}),
    ("first scan draws from 100000 poses (global_candidates)", {"global_candidates": 100_000}),
)
CHECK_S = (1.0, 3.0)
HELD_M, HELD_RAD, HELD_MASS = 0.5, math.radians(20.0), 0.05
TWIN_M, TWIN_RAD = 1.0, math.radians(45.0)


def truth_mass(poses: NDArray[np.float64], weights: NDArray[np.float64], truth: NDArray[np.float64]) -> float:
    """The share of the belief's weight within ``HELD_M`` and ``HELD_RAD`` of ``truth``."""
    if len(poses) == 0 or not np.any(weights > 0):
        return 0.0
    near = (np.hypot(poses[:, 0] - truth[0], poses[:, 1] - truth[1]) <= HELD_M) & (
        np.abs(wrap_angle(poses[:, 2] - truth[2])) <= HELD_RAD
    )
    return float(weights[near].sum() / weights.sum())


def run(overrides: dict[str, Any], crowd: int, seed: int) -> list[tuple[bool, bool]]:
    """One episode: (truth held, on a twin) at each of ``CHECK_S``."""
    env = gym.make(ENV_ID, localizer="mcl_lidar", prior="none", crowd_size=crowd, localizer_params=overrides)
    observation, info = env.reset(seed=seed)
    policy = make_policy("spin", env, seed=seed)
    localizer = env.get_wrapper_attr("localizer")
    dt = env.unwrapped.config.dt_s
    out = []
    step = 0
    for check in CHECK_S:
        while step * dt < check - 1e-9:
            action, _ = policy.predict(observation)
            observation, _, _, _, info = env.step(action)
            step += 1
        truth = np.asarray(info["true_pose"], dtype=float)
        overlay = localizer.overlay()
        estimate = localizer.estimate
        twin = bool(estimate.valid) and (
            math.hypot(estimate.x_m - truth[0], estimate.y_m - truth[1]) > TWIN_M
            or abs(wrap_angle(estimate.theta_rad - truth[2])) > TWIN_RAD
        )
        out.append((truth_mass(overlay.poses, overlay.weights, truth) >= HELD_MASS, twin))
    env.close()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=50, help="seeds per crowd size (default 50)")
    parser.add_argument("--crowds", type=int, nargs="+", default=[0, 16, 30], help="crowd sizes (default 0 16 30)")
    parser.add_argument("--settings", type=int, nargs="+", help="the settings to run, by index (default: all)")
    args = parser.parse_args()
    head = " | ".join(f"truth held at {c:g} s | on a twin at {c:g} s" for c in CHECK_S)
    print(f"{ENV_ID}, prior none, spin; {args.seeds} seeds per crowd; shares of seeds\n")
    print(f"| mcl_lidar | crowd | {head} | s per run |")
    print("|---|---:|" + "---:|" * (2 * len(CHECK_S)) + "---:|")
    for index, (label, overrides) in enumerate(SETTINGS):
        if args.settings is not None and index not in args.settings:
            continue
        for crowd in args.crowds:
            t0 = time.perf_counter()
            rows = np.array([run(overrides, crowd, seed) for seed in range(args.seeds)], dtype=float)
            seconds = (time.perf_counter() - t0) / args.seeds
            cells = " | ".join(f"{rows[:, i, 0].mean():.0%} | {rows[:, i, 1].mean():.0%}" for i in range(len(CHECK_S)))
            print(f"| {label} | {crowd} | {cells} | {seconds:.2f} |", flush=True)


if __name__ == "__main__":
    main()
