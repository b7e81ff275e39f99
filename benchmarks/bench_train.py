"""PPO training throughput: env steps per second on RoboCupCrowded-v0 with the candidate_sets wrapper.

The shipped training config (4 envs in subprocesses, 450-step rollouts, 64x64 MLP) runs for
a few rollouts; the figure is the steady-state rate between the end of the first rollout
and the end of the last (process start-up and numba compilation excluded), including PPO's
gradient updates.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from benchmarks.common import Result


def run_all(quick: bool = False) -> list[Result]:
    from stable_baselines3.common.callbacks import BaseCallback

    from agents import train as training

    rollouts = 3 if quick else 6
    results = []
    for n_envs in (2, 4):
        config = training.load_train_config(
            "ppo_candidate_sets", {"n_envs": n_envs, "total_timesteps": 450 * n_envs * rollouts, "checkpoint_every": 10**9}
        )
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
        rate = (s1 - s0) / (t1 - t0)
        results.append(
            Result("training", f"PPO, candidate_sets wrapper, {n_envs} envs in subprocesses", rate, "env steps/s",
                   f"{rollouts - 1} rollouts timed", ">= 1,500", rate >= 1500)
        )
    return results

