"""The benchmark's position error is evo's absolute pose error (APE, translation part, no alignment):
each episode exported as TUM files (estimate and ground truth, as ``crowdloc eval`` writes them),
read by evo, associated by timestamp, gives the same mean, RMSE and maximum as the benchmark's
per-episode errors (docs/benchmark.md, "The metrics")."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from evo.core import metrics as evo_metrics
from evo.core import sync
from evo.tools import file_interface

from agents.benchmark.protocol import load_protocol
from agents.benchmark.run import plan_benchmark, score_task
from agents.evaluate.episode import run_episode
from agents.evaluate.outputs import write_tum


@pytest.mark.parametrize(
    ("world", "localizer"),
    [("crowdloc/RoboCupCrowded-v0", "candidate_sets"), ("crowdloc/CrowdedRoom-v0", "mcl_lidar")],
)
def test_the_benchmark_error_is_evos_ape(world: str, localizer: str, tmp_path: Path) -> None:
    plan = plan_benchmark(load_protocol(), worlds=[world], localizers=[localizer], policies=["random_walk"], seeds=1)
    task = next(t for t in plan.tasks() if t.cell.crowd_size > 0)
    task = dataclasses.replace(task, spec=dataclasses.replace(task.spec, episode_steps=200))
    score = score_task(task)
    episode = run_episode(task.spec, task.cell)  # the same episode again (same seed): export it
    est = write_tum(tmp_path / "estimate.tum", episode.time_s, episode.estimates, episode.valid)
    ref = write_tum(tmp_path / "groundtruth.tum", episode.time_s, episode.true_pose)

    traj_ref, traj_est = sync.associate_trajectories(file_interface.read_tum_trajectory_file(str(ref)),
                                                     file_interface.read_tum_trajectory_file(str(est)))  # fmt: skip
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((traj_ref, traj_est))
    assert traj_est.num_poses == score.errors_m.size > 100  # every step with a pose, from the first fix on
    stats = ape.get_all_statistics()
    # TUM files hold 6 decimals: agreement to a few micrometres
    assert stats["mean"] == pytest.approx(score.values["error_mean_m"], abs=5e-6)
    assert stats["rmse"] == pytest.approx(float(np.sqrt(np.mean(score.errors_m**2))), abs=5e-6)
    assert stats["max"] == pytest.approx(float(score.errors_m.max()), abs=5e-6)
