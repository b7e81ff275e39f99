"""Dead reckoning ("odometry only", every paper's first baseline) runs in every world: it needs
odometry and the start pose, nothing else. Where the world has a bearing camera it reads (and validates) the
bearings; elsewhere it reads its registry entry's fallback kind, the odometry itself."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from agents.cli import main
from envs import ENV_WORLDS
from localizers.dead_reckoning import DeadReckoningParams, dead_reckon
from localizers.registry import load_params, measurement_in

WORLD_IDS = sorted(ENV_WORLDS)


@pytest.mark.parametrize("env_id", WORLD_IDS)
def test_dead_reckoning_runs_through_gym_make_in_every_world(env_id: str) -> None:
    env = gym.make(env_id, localizer="dead_reckoning", crowd_size=2)
    try:
        obs, info = env.reset(seed=0)
        sensors = env.unwrapped.sensor_metadata  # type: ignore[attr-defined]
        has_camera = any(meta["type"] == "bearing_camera" for meta in sensors.values())
        assert env.get_wrapper_attr("measurement") == ("bearings" if has_camera else "odometry")
        # the estimate is the odometry integrated from the true start pose, nothing else
        p: DeadReckoningParams = load_params("dead_reckoning")
        pose, cov = np.asarray(info["true_pose"], dtype=np.float64), np.diag([1e-6, 1e-6, 1e-6])
        rng = np.random.default_rng(0)
        for _ in range(15):
            obs, _, _, _, info = env.step(rng.uniform(-1, 1, 2).astype(np.float32))
            d = np.asarray(obs["odometry"], dtype=np.float64)
            pose, cov = dead_reckon(pose, cov, d, p.position_var_m2_per_m, p.heading_var_rad2_per_m, p.heading_var_rad2_per_rad)
        est = info["estimate"]
        assert est.valid
        np.testing.assert_array_equal(est.as_array(), pose)
        np.testing.assert_array_equal(est.covariance, cov)
    finally:
        env.close()


def test_the_fallback_applies_only_without_a_bearing_camera() -> None:
    camera = {"odometry": {"type": "odometry"}, "camera": {"type": "bearing_camera"}}
    lidar = {"odometry": {"type": "odometry"}, "lidar": {"type": "lidar"}}
    assert measurement_in("dead_reckoning", camera) == "bearings"  # with a bearing camera it reads the bearings
    assert measurement_in("dead_reckoning", lidar) == "odometry"
    assert measurement_in("candidate_sets", lidar) == "bearings"  # no fallback: refused by the wrapper, naming the sensor


@pytest.mark.slow
def test_crowdloc_eval_runs_dead_reckoning_in_the_corridor(tmp_path: Path) -> None:
    # refused before: "needs a bearing_camera sensor"
    out = tmp_path / "eval"
    argv = ["eval", "--env-id", "crowdloc/CeilingCorridor-v0", "--localizers", "dead_reckoning", "--policies", "random_walk",
            "--crowd-sizes", "0", "--seeds", "1", "--episode-steps", "10", "--workers", "1", "--no-gif", "--no-progress",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert "dead_reckoning" in (out / "summary.md").read_text()
