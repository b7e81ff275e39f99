"""``crowdloc eval`` on a world task: a trained policy observes the task's observation, the
fixed policies the raw sensors; the goal's metrics; the paired verdict against the best fixed policy."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from agents.cli import build_parser
from agents.evaluate import EvalSpec, run_cli
from agents.evaluate.goal import goal_metrics
from agents.evaluate.paired import paired_difference, paired_verdict, verdict_metrics, verdict_policy
from agents.evaluate.plugins import Track
from agents.evaluate.spec import Cell
from agents.evaluate.stats import EvalResult
from agents.rl.config import load_train_config
from agents.rl.train import make_task_env
from core.schema import ConfigError


@pytest.fixture(scope="module")
def room_model(tmp_path_factory: pytest.TempPathFactory) -> str:
    """An untrained PPO on ppo_room_lidar's task observation, saved: what a trained one looks like to eval."""
    from stable_baselines3 import PPO

    env = make_task_env(load_train_config("ppo_room_lidar"), 8)
    path = tmp_path_factory.mktemp("room") / "model.zip"
    PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu").save(path)
    env.close()
    return f"ppo:{path}"


def _eval_args(tmp_path: Path, *extra: str) -> list[str]:
    return ["eval", "--conditions", "ppo_room_lidar", "--crowd-sizes", "8", "--seeds", "2", "--episode-steps", "12",
            "--workers", "1", "--no-gif", "--no-progress", "--out", str(tmp_path), *extra]  # fmt: skip


def test_a_room_task_policy_is_evaluated_beside_a_fixed_one_with_a_paired_verdict(tmp_path: Path, room_model: str) -> None:
    args = build_parser(["eval"]).parse_args(
        _eval_args(tmp_path, "--policies", room_model, "route_follower", "--verdict", room_model)
    )
    result = run_cli(args)
    trained = load_train_config("ppo_room_lidar")
    spec = result.spec
    assert (spec.route, spec.observation, spec.reward) == (trained.route, trained.observation, trained.reward)
    # the trained policy's cells observe the task's observation, the fixed policy's the raw LIDAR it reads
    ppo_env, fixed_env = (spec.make_env(p, "mcl_lidar", 8) for p in (room_model, "route_follower"))
    ppo_keys, fixed_keys = set(ppo_env.observation_space.spaces), set(fixed_env.observation_space.spaces)
    assert {"lidar_summary", "waypoint"} <= ppo_keys and "lidar" not in ppo_keys
    assert "lidar" in fixed_keys and not {"lidar_summary", "waypoint"} & fixed_keys
    ppo_env.close(), fixed_env.close()
    assert len(result.episodes) == 4 and all(len(e.time_s) == 13 for e in result.episodes)
    assert all(np.isfinite(e.metrics["episode_return"]) for e in result.episodes)
    # the room has no goal: no goal rows; its localizer starts lost (prior: none): the first fix is judged
    assert "goal_missed" not in {m.key for m in spec.metrics}
    with open(tmp_path / "verdict.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["metric"] for r in rows] == ["position_error_mean_m", "failure_rate", "first_fix_s", "collisions"]
    assert {r["best_fixed"] for r in rows} == {"route_follower"} and all(r["crowd_size"] == "8" for r in rows)
    # the room's map has no route: route_follower drives the task's square (the config's route points)
    assert spec.drives_task_route("route_follower") and spec.drives_task_route("look_then_route")
    assert not spec.drives_task_route("patrol")
    assert "paired verdict on ppo:model" in (tmp_path / "verdict.md").read_text()
    run = (tmp_path / "run.json").read_text()
    assert '"lidar_sectors": 12' in run and '"points_m"' in run  # run.json records the observation and the route


def test_a_verdict_needs_a_policy_of_the_grid_and_a_fixed_one_to_judge_it_against(tmp_path: Path, room_model: str) -> None:
    parse = build_parser(["eval"]).parse_args
    with pytest.raises(ConfigError, match=r"--verdict 'patrol' is not one of --policies \(spin\)"):
        run_cli(parse(_eval_args(tmp_path, "--policies", "spin", "--verdict", "patrol")))
    with pytest.raises(ConfigError, match=r"needs a fixed policy to be judged against"):
        run_cli(parse(_eval_args(tmp_path, "--policies", room_model, "--verdict", room_model)))
    assert not any(tmp_path.iterdir())  # refused before anything ran or was written
    spec = EvalSpec(policies=("spin", "patrol"), localizers=("mcl_lidar",), crowd_sizes=(8,), seeds=1, episode_steps=2,
                    env_id="crowdloc/CrowdedRoom-v0")  # fmt: skip
    assert verdict_policy("patrol", spec) == "patrol"  # a fixed policy may be judged against the others


def test_a_task_observation_that_drops_the_odometry_is_refused(room_model: str) -> None:
    from agents.rl.observation import ObservationConfig

    trained = load_train_config("ppo_room_lidar")
    with pytest.raises(ConfigError, match="observation.drop removes 'odometry', the odometry the evaluation records"):
        EvalSpec(policies=(room_model, "spin"), localizers=("mcl_lidar",), crowd_sizes=(8,), seeds=1, env_id=trained.env_id,
                 reward=trained.reward, route=trained.route, observation=ObservationConfig(drop=("odometry",)))  # fmt: skip
    with pytest.raises(ConfigError, match="reward weight progress = 5.0 needs a route"):  # the room has no route of its own
        EvalSpec(policies=("spin",), localizers=("mcl_lidar",), crowd_sizes=(8,), seeds=1, env_id=trained.env_id,
                 reward=trained.reward)  # fmt: skip


def _track(steps: int, dt_s: float) -> Track:
    t = np.arange(steps + 1) * dt_s
    pose = np.zeros((steps + 1, 3))
    return Track(t, pose, pose, np.ones(steps + 1, bool), np.zeros(steps + 1, np.int64), np.zeros((steps, 3)), np.zeros(steps))


def test_time_to_goal_is_the_time_of_the_step_the_world_ended_the_episode_at_its_goal() -> None:
    assert goal_metrics(_track(40, 0.05), reached=True) == {"goal_missed": 0.0, "time_to_goal_s": pytest.approx(2.0)}
    missed = goal_metrics(_track(40, 0.05), reached=False)
    assert missed["goal_missed"] == 1.0 and math.isnan(missed["time_to_goal_s"])  # never reached: NaN, counted as missed


def test_a_goal_world_ending_early_has_goal_metrics_and_no_nan_where_a_value_exists() -> None:
    from agents.evaluate import run_episode

    config = load_train_config("ppo_corridor_targets")
    spec = EvalSpec(policies=("corridor_follower",), localizers=("ceiling_target",), crowd_sizes=(0,), seeds=1,
                    episode_steps=30, env_id=config.env_id, reward=config.reward, route=config.route)  # fmt: skip
    assert spec.metrics[-2:] == tuple(m for m in spec.metrics if m.key in ("goal_missed", "time_to_goal_s"))
    episode = run_episode(spec, spec.cells()[0])
    assert episode.metrics["goal_missed"] == 1.0 and math.isnan(episode.metrics["time_to_goal_s"])  # 1.5 s: not there yet
    assert all(np.isfinite(episode.metrics[k]) for k in ("position_error_mean_m", "collisions", "episode_return"))
    # the verdict judges the goal here, and the first fix: ceiling_target is not given its start (it fixes under a target)
    assert verdict_metrics(spec, "ceiling_target") == ("position_error_mean_m", "failure_rate", "first_fix_s", "goal_missed",
                                                       "time_to_goal_s", "collisions")  # fmt: skip
    campus = EvalSpec(policies=("route_follower",), localizers=("far_landmark_pf",), crowd_sizes=(0,), seeds=1,
                      env_id="crowdloc/StereoCampus-v0")  # fmt: skip
    assert "first_fix_s" not in verdict_metrics(campus, "far_landmark_pf") and campus.has_goal  # given its start: no first fix


def test_the_paired_interval_excludes_zero_for_a_steady_gain_and_holds_it_for_noise() -> None:
    rng = np.random.default_rng(0)
    base = rng.normal(1.0, 0.5, 100)  # what the seed does to both policies
    better = paired_difference(base - 0.1 + rng.normal(0, 0.02, 100), base, resamples=2000, rng=np.random.default_rng(1))
    assert better.outcome == -1 and better.high < 0 and better.n == 100 and better.mean == pytest.approx(-0.1, abs=0.01)
    worse = paired_difference(base + 0.1, base - rng.normal(0, 0.02, 100), resamples=2000, rng=np.random.default_rng(1))
    assert worse.outcome == 1 and worse.low > 0
    same = paired_difference(base + rng.normal(0, 0.3, 100), base, resamples=2000, rng=np.random.default_rng(1))
    assert same.outcome == 0 and same.low < 0 < same.high
    # a pair counts only where both have a value; no pair at all: no interval, no verdict
    partial = paired_difference([1.0, np.nan, 3.0], [0.5, 2.0, np.nan], resamples=50, rng=np.random.default_rng(0))
    assert (partial.mean, partial.n) == (0.5, 1)
    none = paired_difference([np.nan], [1.0], resamples=50, rng=np.random.default_rng(0))
    assert none.n == 0 and math.isnan(none.mean) and none.outcome == 0
    with pytest.raises(ValueError, match="one value of each per seed"):
        paired_difference([1.0, 2.0], [1.0], resamples=10, rng=np.random.default_rng(0))


def test_the_verdict_picks_each_metrics_best_fixed_policy_and_pairs_by_seed() -> None:
    from types import SimpleNamespace

    spec = EvalSpec(policies=("patrol", "spin", "random_walk"), localizers=("mcl_lidar",), crowd_sizes=(8,), seeds=30,
                    env_id="crowdloc/CrowdedRoom-v0", env_kwargs={"prior": "none"})  # fmt: skip
    rng = np.random.default_rng(3)
    hard = rng.normal(2.0, 1.0, spec.seeds)  # per seed, shared by every policy
    values = {"patrol": (hard - 0.3, 4.0), "spin": (hard, 1.0), "random_walk": (hard + 0.2, 2.0)}  # (error, collisions)
    episodes = [SimpleNamespace(cell=Cell(p, "mcl_lidar", 8, s),
                                metrics={"position_error_mean_m": values[p][0][i], "failure_rate": 0.1, "collisions": values[p][1],
                                         "first_fix_s": math.nan if p == "patrol" else 1.0})
                for p in spec.policies for i, s in enumerate(spec.eval_seeds)]  # fmt: skip
    rows = {r.metric: r for r in paired_verdict(EvalResult(spec, tuple(episodes), (), 0.0), "patrol")}  # type: ignore[arg-type]
    assert list(rows) == ["position_error_mean_m", "failure_rate", "first_fix_s", "collisions"]  # prior none: the first fix too
    assert rows["position_error_mean_m"].best_fixed == "spin" and rows["position_error_mean_m"].word == "A better"
    assert rows["position_error_mean_m"].difference.mean == pytest.approx(-0.3)
    assert rows["collisions"].best_fixed == "spin" and rows["collisions"].word == "B better"
    assert rows["failure_rate"].word == "no significant difference"
    assert rows["first_fix_s"].word == "no pair" and rows["first_fix_s"].difference.n == 0  # patrol never fixed
    with pytest.raises(ConfigError, match="every episode of the grid"):
        paired_verdict(EvalResult(spec, tuple(episodes[:-1]), (), 0.0), "patrol")  # type: ignore[arg-type]
