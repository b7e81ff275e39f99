"""Contacts and pushes of our robot against crowd size, with people who do and do not see it.

For each world with a crowd of people (the crowded room, the ceiling corridor, the campus), its
crowd's ``sees_robot`` at 0 (today's invisible robot) and 1, a few crowd sizes and seeds:
the robot drives a fixed command (the room: a 1 m circle; the corridor and the campus: straight
on from the start pose, along the corridor and the north sidewalk) and the script counts the
contacts with crowd members that begin per run and the distance the robot was pushed per run
(the path length of its motion beyond the commanded chord of each step). Only the world is
stepped (no sensors), so the step rates printed are the crowds' and physics' cost.

Run: ``.venv/bin/python -m benchmarks.sees_robot [--seeds 2]``.
"""

from __future__ import annotations

import argparse
import math
import time

import gymnasium as gym
import numpy as np

import envs  # noqa: F401

#: (world id, crowd name, crowd sizes, seconds per run, action (v, omega) as shares of the robot's top speeds); the
#: first crowd's size is ``crowd_size``, another's (the room's walkers, beside its 16 queueing people) its ``count``
SETTINGS: tuple[tuple[str, str, tuple[int, ...], float, tuple[float, float]], ...] = (
    ("crowdloc/CrowdedRoom-v0", "queues", (10, 20, 30), 30.0, (1.0, 1.0 / 3.0)),  # 0.5 m/s, 0.5 rad/s: a 1 m circle
    ("crowdloc/CrowdedRoom-v0", "walkers", (5, 10, 20), 30.0, (1.0, 1.0 / 3.0)),
    ("crowdloc/CeilingCorridor-v0", "corridor", (20, 40), 40.0, (1.0, 0.0)),  # 20 m along the corridor
    ("crowdloc/StereoCampus-v0", "campus", (30, 100, 200), 50.0, (1.0, 0.0)),  # 50 m west along the north sidewalk
)
FIRST_CROWD = {
    "crowdloc/CrowdedRoom-v0": "queues",
    "crowdloc/CeilingCorridor-v0": "corridor",
    "crowdloc/StereoCampus-v0": "campus",
}


def run(
    env_id: str, crowd: str, size: int, sees: float, seed: int, seconds: float, action: tuple[float, float]
) -> tuple[int, float, float]:
    """One run: (contacts with crowd members, pushed distance m, world steps per second)."""
    if FIRST_CROWD[env_id] == crowd:
        env = gym.make(env_id, crowd_size=size, crowd={crowd: {"sees_robot": sees}})
    else:
        env = gym.make(env_id, crowd={crowd: {"count": size, "sees_robot": sees}})
    env.reset(seed=seed)
    base = env.unwrapped
    world, rng, dt = base.world, base._world_rng, base.config.dt_s
    v = action[0] * base.max_speed_mps
    omega = action[1] * base.max_turn_rate_rps
    contacts, pushed = 0, 0.0
    steps = round(seconds / dt)
    elapsed = 0.0
    for _ in range(steps):
        x, y, theta = world.robot_pose
        heading = theta + 0.5 * omega * dt
        velocity = np.array([v * math.cos(heading), v * math.sin(heading)])
        t0 = time.perf_counter()
        world.step(velocity, omega, rng)
        elapsed += time.perf_counter() - t0
        contacts += sum(1 for event in world.contacts if event.other == "crowd")
        dx, dy = world.robot_pose[:2] - (x, y) - velocity * dt
        pushed += math.hypot(dx, dy)
    env.close()
    return contacts, pushed, steps / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    args = parser.parse_args()
    for env_id, crowd, sizes, seconds, action in SETTINGS:
        run(env_id, crowd, sizes[0], 1.0, 99, 2.0, action)  # compile the kernels before timing
        print(f"\n{env_id} ({crowd}, {seconds:g} s per run, seeds 0..{args.seeds - 1})")
        print("| crowd | contacts/run sees 0 | sees 1 | pushed m/run sees 0 | sees 1 | steps/s sees 0 | sees 1 |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for size in sizes:
            cells: dict[float, list[tuple[int, float, float]]] = {0.0: [], 1.0: []}
            for sees in cells:
                for seed in range(args.seeds):
                    cells[sees].append(run(env_id, crowd, size, sees, seed, seconds, action))
            mean = {s: np.mean(np.array(r, dtype=float), axis=0) for s, r in cells.items()}
            print(
                f"| {size} | {mean[0.0][0]:.1f} | {mean[1.0][0]:.1f} | {mean[0.0][1]:.2f} | {mean[1.0][1]:.2f} "
                f"| {mean[0.0][2]:,.0f} | {mean[1.0][2]:,.0f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
