"""What ``crowdloc benchmark`` costs: seconds per episode in each world of the protocol, and the
full protocol's time on one core estimated from them.

Per world, one full-length episode of every localizer the world runs, driven by the world's paper
policy at the world's default crowd on the first test seed (``score_task``, in this process, after
one warm-up episode per world that pays numba's compilation and the scene maps' loading). The
figure is the median over the localizers, the range their min and max. The estimate multiplies
each world's mean cost by its number of episodes in the protocol.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from benchmarks.common import Result


def run_all(quick: bool = False) -> list[Result]:
    from agents.benchmark.protocol import load_protocol
    from agents.benchmark.run import plan_benchmark, score_task
    from agents.evaluate.spec import world_of

    protocol = load_protocol()
    plan = plan_benchmark(protocol, seeds=1)
    results, total_s = [], 0.0
    for world in plan.worlds:
        crowd = world_of(world.env_id, {}).crowd
        default = crowd.count if crowd is not None else 0
        steps = 100 if quick else world.spec.episode_steps
        tasks = [dataclasses.replace(t, spec=dataclasses.replace(t.spec, episode_steps=steps)) for t in plan.tasks()
                 if t.env_id == world.env_id and t.cell.policy == world.policies[0] and t.cell.crowd_size == default]  # fmt: skip
        score_task(dataclasses.replace(tasks[0], spec=dataclasses.replace(tasks[0].spec, episode_steps=20)))  # warm-up
        seconds = []
        for task in tasks:
            start = time.perf_counter()
            score_task(task)
            seconds.append(time.perf_counter() - start)
        episodes = len(world.localizers) * len(world.policies) * len(world.world.crowd_sizes) * protocol.seeds.count
        total_s += float(np.mean(seconds)) * episodes * world.spec.episode_steps / steps
        results.append(Result(
            "benchmark",
            f"{world.env_id}: one episode ({steps} steps, {world.policies[0]}, crowd {default}, {len(tasks)} localizers)",
            float(np.median(seconds)), "s", f"{min(seconds):.2f}-{max(seconds):.2f} s over localizers",
        ))  # fmt: skip
    results.append(Result("benchmark", f"the full protocol {protocol.name} on one core (estimated from the rows above)",
                          total_s / 60.0, "min", f"{len(protocol.seeds.seeds)} seeds"))  # fmt: skip
    return results
