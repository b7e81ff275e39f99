"""PPO training throughput: env steps per second of each shipped task's training config, in process.

The shipped training config (``configs/experiments/ppo_candidate_sets.yaml``: 4 envs, 450-step
rollouts, 64x64 MLP) runs for a few rollouts; the figure is the steady-state rate between the
end of the first rollout and the end of the last (start-up and numba compilation excluded),
including PPO's gradient updates. The target applies to the shipped config; the same config
with the envs in subprocesses is measured beside it for reference (the choice between the two
is a config key, ``vec_env``; both give the same weights). The other worlds' tasks (the
room, the corridor, the campus) are measured the same way, each its shipped config, against
a target of 500 steps/s on 2 cores. The soccer and room tasks are measured again with a 4 x 32 x 32
belief map in the observation (``observation.belief_map``) and its CNN
(:class:`agents.rl.extractor.BeliefMapExtractor`), against 1,000 steps/s, and the map's own cost per
step on four localizers' beliefs (:func:`belief_map_costs`).

With the belief map, on 2 cores (``make bench``, 2 rollouts timed, 2026-12-07): the soccer task 1,273
env steps/s (3,557 without the map in the same run), meeting its target; the room 759 (1,333 without),
missing it. Of the soccer task's training with the map (cProfile, 3
rollouts, 5,400 env steps, on a busy machine) the CNN takes about 37 % (its forward passes 17 %,
the updates' backward passes 20 %) and the envs 48 % (the map itself 70-152 us a step, BENCHMARKS.md). The convolutions are already
strided (a third of the cost of 3 x 3 convolutions with pooling, :mod:`agents.rl.extractor`); what
remains of the CNN is mostly torch's cost per call on batches of 4 maps.

The campus task misses it (380-410 env steps/s in process on a quiet host). Where its time goes
(cProfile of 3 rollouts of the shipped config, 18,000 env steps, 2026-12-04): the world and its
sensors 48 % (the stereo camera's fast mode 25 %, of which the line kernel 11 %; physics and the
crowd 14 %; the LIDAR 6 %), ``far_landmark_pf`` 33 % (its search of the scene map, run while it is
lost, 20 %: 1,792 searches of 51 headings x 33 x 33 cells; the rest is the 500 particles' weights and
the lost test), SB3's policy, buffers and the task's wrappers 13 %, the gradient updates 2 %. The
policy early in training is lost most of the time (the campus analysis in models/README), so the
search runs on about one step in ten. The floor with this behaviour is the rate above. To reach 500
a fifth of the step must go. The search's headings are independent and split across the two cores
halve it on an idle machine (6.5 to 3.5 ms per search, measured), but they ran three times slower when
the other core was busy (training runs side by side, as `--workers 2` does), so that was not kept;
searching less often, or a policy that stays localized, would change what is trained on.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.common import Result

TARGET = 1500  # env steps/s on 2 cores
WORLD_TASKS = ("ppo_room_lidar", "ppo_corridor_targets", "ppo_campus_stereo")
WORLD_TASK_TARGET = 500  # env steps/s on 2 cores
#: the tasks measured with the belief map on (agents.rl.belief_map), and their target
BELIEF_TASKS = ("ppo_candidate_sets", "ppo_room_lidar")
BELIEF_MAP = {"cells": 32, "heading_bins": 4, "frame": "estimate", "extent_m": 4.0}
BELIEF_TARGET = 1000  # env steps/s on 2 cores


#: the localizers whose belief map's cost is measured, and the world each runs in
BELIEF_MAP_LOCALIZERS = (
    ("mcl_bearing", "crowdloc/RoboCupCrowded-v0"),
    ("candidate_sets", "crowdloc/RoboCupCrowded-v0"),
    ("kalman", "crowdloc/RoboCupCrowded-v0"),
    ("mcl_lidar", "crowdloc/CrowdedRoom-v0"),
)


def belief_map_costs(quick: bool = False) -> list[Result]:
    """The belief map's cost per step (``agents.rl.belief_map.belief_map`` on the localizer's overlay, one
    core), median and 99th percentile over the steps of a random drive with a known start."""
    import time

    import gymnasium as gym
    import numpy as np

    import agents  # noqa: F401  (registers the ids)
    from agents.rl.belief_map import BeliefMapConfig, belief_map

    config = BeliefMapConfig(**BELIEF_MAP)
    steps = 100 if quick else 600
    results = []
    for name, env_id in BELIEF_MAP_LOCALIZERS:
        env = gym.make(env_id, localizer=name, prior="start")
        env.reset(seed=0)
        env.action_space.seed(0)
        localizer = env.get_wrapper_attr("localizer")
        bounds = env.unwrapped.landmark_map.bounds_m
        times = []
        for _ in range(steps):
            env.step(env.action_space.sample())
            start = time.perf_counter()
            belief_map(config, localizer.overlay(), localizer.estimate, bounds)
            times.append(time.perf_counter() - start)
        env.close()
        us = np.asarray(times) * 1e6
        label = f"belief map 4 x 32 x 32 of {name} ({env_id.split('/')[1]}): overlay and histogram per step"
        results.append(Result("belief map", label, float(np.median(us)), "us", f"p99 {np.percentile(us, 99):.0f}"))
    return results


def run_all(quick: bool = False) -> list[Result]:
    from agents.rl import train as training
    from agents.rl.config import load_train_config

    rollouts = 3 if quick else 6
    shipped = load_train_config("ppo_candidate_sets")
    variants: list[tuple[dict[str, Any], bool]] = [({}, True)]  # (overrides, is the shipped config)
    other = "subproc" if shipped.vec_env == "dummy" else "dummy"
    variants.append(({"vec_env": other}, False))
    results = []
    for overrides, is_shipped in variants:
        config = load_train_config(
            "ppo_candidate_sets",
            {**overrides, "total_timesteps": shipped.rollout_steps * rollouts, "checkpoint_every": 10**9},
        )
        rate = _steps_per_second(training, config)
        where = "in-process (DummyVecEnv)" if config.vec_env == "dummy" else "in subprocesses (SubprocVecEnv)"
        label = f"PPO, candidate_sets wrapper, {config.n_envs} envs {where}" + (", shipped config" if is_shipped else "")
        results.append(
            Result(
                "training",
                label,
                rate,
                "env steps/s",
                f"{rollouts - 1} rollouts timed",
                f">= {TARGET:,}" if is_shipped else "(reference)",
                rate >= TARGET if is_shipped else None,
            )  # fmt: skip
        )
    for name in WORLD_TASKS:
        shipped = load_train_config(name)
        timed = 1 if quick else 2
        config = load_train_config(name, {"total_timesteps": shipped.rollout_steps * (timed + 1), "checkpoint_every": 10**9})
        rate = _steps_per_second(training, config)
        label = f"PPO, {name} ({config.localizer}), {config.n_envs} envs in-process, shipped config"
        target = f">= {WORLD_TASK_TARGET:,}"
        results.append(
            Result("training", label, rate, "env steps/s", f"{timed} rollouts timed", target, rate >= WORLD_TASK_TARGET)
        )
    for name in BELIEF_TASKS:
        shipped = load_train_config(name)
        timed = 1 if quick else 2
        config = load_train_config(
            name,
            {
                "total_timesteps": shipped.rollout_steps * (timed + 1),
                "checkpoint_every": 10**9,
                "observation.belief_map": BELIEF_MAP,
            },
        )
        rate = _steps_per_second(training, config)
        label = f"PPO, {name} ({config.localizer}) with a 4 x 32 x 32 belief map and its CNN, {config.n_envs} envs in-process"
        target = f">= {BELIEF_TARGET:,}"
        results.append(Result("training", label, rate, "env steps/s", f"{timed} rollouts timed", target, rate >= BELIEF_TARGET))
    return results + belief_map_costs(quick)


def _steps_per_second(training: Any, config: Any) -> float:
    from stable_baselines3.common.callbacks import BaseCallback

    marks: list[tuple[float, int]] = []

    class Clock(BaseCallback):
        def _on_step(self) -> bool:
            return True

        def _on_rollout_start(self) -> None:
            marks.append((time.perf_counter(), self.model.num_timesteps))

        def _on_training_end(self) -> None:
            marks.append((time.perf_counter(), self.model.num_timesteps))

    with tempfile.TemporaryDirectory() as out:
        training.train(config, Path(out), progress_bar=False, extra_callbacks=[Clock()])
    (t0, s0), (t1, s1) = marks[1], marks[-1]
    return (s1 - s0) / (t1 - t0)
