"""``crowdloc eval``: the files it writes, its metrics, bootstrap intervals, TUM files, bad input."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import re
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from agents.cli import build_parser, main
from agents.evaluate import (
    CORE_METRICS,
    Cell,
    EvalSpec,
    Track,
    bearing_metrics,
    bootstrap_ci,
    episode_metrics,
    evaluate,
    read_tum,
    run_episode,
    summarize,
    write_outputs,
    write_tum,
)
from agents.rl.config import EVAL_SEED_BASE, load_train_config
from agents.rl.train import train
from core.schema import ConfigError


def test_cli_eval_writes_tables_plots_trajectories_and_a_gif(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from PIL import Image

    out = tmp_path / "eval"
    argv = ["eval", "--policies", "spin", "random_walk", "--localizers", "candidate_sets", "--crowd-sizes", "3",
            "--seeds", "2", "--episode-steps", "60", "--workers", "1", "--out", str(out), "--no-progress"]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| spin | candidate_sets | 3 |" in printed and "| random_walk | candidate_sets | 3 |" in printed

    with open(out / "episodes.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 4
    assert sorted(int(r["seed"]) for r in rows) == [EVAL_SEED_BASE, EVAL_SEED_BASE, EVAL_SEED_BASE + 1, EVAL_SEED_BASE + 1]
    assert all(int(r["steps"]) == 60 and 0.0 <= float(r["availability"]) <= 1.0 for r in rows)
    with open(out / "summary.csv") as f:
        summary = list(csv.DictReader(f))
    assert [(r["policy"], r["episodes"]) for r in summary] == [("spin", "2"), ("random_walk", "2")]
    for r in summary:
        assert float(r["availability_ci_low"]) <= float(r["availability"]) <= float(r["availability_ci_high"])
    md = (out / "summary.md").read_text()
    assert "| policy | localizer | crowd |" in md and "| spin | candidate_sets | 3 |" in md
    # the consistency columns, right after the error columns
    assert (
        "| heading error RMS [deg] | singular covariance (share of steps) | NEES median (consistent: 2.37) "
        "| inside 95% region (consistent: 0.95) | failure rate" in md
    )
    assert "nees_mean" not in rows[0]  # inf after one singular step: not reported
    for r in rows:
        assert 0.0 <= float(r["singular_share"]) <= 1.0 and 0.0 <= float(r["inside_95"]) <= 1.0 and float(r["nees_median"]) >= 0.0
    assert all(0.0 <= float(r["covariance_missing"]) <= 1.0 for r in rows)
    for r in summary:
        assert float(r["inside_95_ci_low"]) <= float(r["inside_95"]) <= float(r["inside_95_ci_high"])
        assert "no covariance" not in r.values()  # candidate_sets reports one

    pngs = list((out / "plots").glob("*.png"))
    assert len(pngs) >= 1 and all(p.stat().st_size > 1000 for p in pngs)
    assert (out / "plots" / "error_vs_spread.png").stat().st_size > 1000

    tum = sorted((out / "tum").glob("*.tum"))
    assert len(tum) == 8  # an estimate and a ground truth per episode
    for path in tum:
        table = np.loadtxt(path, comments="#", ndmin=2)
        assert table.shape[1] == 8
        assert np.all(np.diff(table[:, 0]) > 0)
        np.testing.assert_allclose(np.linalg.norm(table[:, 4:8], axis=1), 1.0, atol=1e-6)
        np.testing.assert_array_equal(table[:, 3], 0.0)
    truth = [p for p in tum if p.name.endswith("_groundtruth.tum")]
    assert all(np.loadtxt(p, ndmin=2).shape[0] == 61 for p in truth)  # the reset and 60 steps

    with Image.open(out / "episode.gif") as gif:
        assert gif.n_frames > 1
    assert (out / "episode.gif").stat().st_size < 5_000_000


def test_metrics_of_a_hand_made_episode() -> None:
    time_s = np.arange(5) * 0.5
    truth = np.column_stack([np.arange(5.0), np.zeros(5), np.zeros(5)])  # 1 m per step along x
    valid = np.array([False, False, True, True, True])
    est = np.array([[99, 99, 99], [99, 99, 99], [2.3, 0.4, 0.1], [3.0, 0.0, -0.2], [5.2, 1.6, 0.0]], dtype=float)
    # position errors 0.5, 0, 2 m from the first fix (step 2); heading errors 0.1, 0.2, 0 rad
    # landmarks 0 and 1 in view at step 0, 2 at step 3 (the third distinct one), 0 again at step 4
    visible = np.zeros((5, 4), bool)
    visible[0, [0, 1]] = visible[3, 2] = visible[4, 0] = True
    track = Track(time_s, truth, est, valid, [0, 1, 0, 2, 0], np.zeros((4, 3)), [-1.0, -1.0, 0.5, -0.5])
    core = episode_metrics(track)
    assert list(core) == [m.key for m in CORE_METRICS]
    m = {**core, **bearing_metrics(track, visible, np.full(5, 0.25))}  # the bearings plug-in's on top
    rms_pos = math.sqrt((0.25 + 0.0 + 4.0) / 3)
    assert m["position_error_mean_m"] == pytest.approx(2.5 / 3)
    assert m["position_error_rms_m"] == pytest.approx(rms_pos)
    assert m["heading_error_mean_deg"] == pytest.approx(math.degrees(0.1))
    assert m["heading_error_rms_deg"] == pytest.approx(math.degrees(math.sqrt(0.05 / 3)))
    assert m["failure_rate"] == pytest.approx(1 / 3)
    assert m["availability"] == pytest.approx(3 / 5)
    assert m["fixed"] == 1.0
    assert m["first_fix_s"] == pytest.approx(1.0)
    assert m["first_fix_distance_m"] == pytest.approx(2.0)
    assert m["third_landmark_s"] == pytest.approx(1.5)
    assert m["fix_after_third_s"] == pytest.approx(-0.5)  # this fix came before the third landmark
    assert m["collisions"] == 3.0
    assert m["episode_return"] == pytest.approx(-2.0)
    assert m["bound_rmse_m"] == pytest.approx(0.25)
    assert m["error_bound_ratio"] == pytest.approx(rms_pos / 0.25)


def test_consistency_metrics_of_a_hand_made_episode() -> None:
    truth = np.zeros((4, 3))
    est = np.array([[0.0, 0.0, 0.0], [0.2, 0.3, 0.1], [9.0, 9.0, 0.0], [0.0, 0.0, 0.0]])
    cov = np.diag([0.04, 0.09, 0.01])
    covs = np.stack([cov, cov, cov, np.full((3, 3), np.nan)])  # step 2: far outside; step 3: no covariance
    track = Track(np.arange(4.0), truth, est, np.array([False, True, True, True]), [0] * 4, np.zeros((3, 3)), [0.0] * 3, covs)
    m = episode_metrics(track)
    far = 81 / 0.04 + 81 / 0.09
    assert "nees_mean" not in m
    assert m["nees_median"] == pytest.approx((3.0 + far) / 2)  # step 0 is not valid, step 3 has no covariance
    assert m["inside_95"] == 0.5 and m["covariance_missing"] == pytest.approx(1 / 3) and m["singular_share"] == 0.0
    np.testing.assert_allclose(track.position_spreads_m, [np.nan, math.sqrt(0.13), math.sqrt(0.13), np.nan])
    with pytest.raises(ValueError, match=r"Track.covariances must have shape \(4, 3, 3\)"):
        Track(np.arange(4.0), truth, est, np.ones(4, bool), [0] * 4, np.zeros((3, 3)), [0.0] * 3, covs[:3])


def test_singular_covariances_are_counted_and_not_averaged() -> None:
    """A collapsed particle set (a zero covariance) claims certainty: its steps are counted as singular and
    lie outside the 95 % region, and an episode that is mostly singular has an infinite NEES median, which
    the summary leaves out of its mean (with the count of episodes that had a finite one)."""
    truth, est = np.zeros((5, 3)), np.full((5, 3), 0.1)
    cov, collapsed = np.diag([0.04, 0.09, 0.01]), np.zeros((3, 3))
    covs = np.stack([cov, collapsed, collapsed, collapsed, cov])
    track = Track(np.arange(5.0), truth, est, np.ones(5, bool), [0] * 5, np.zeros((4, 3)), [0.0] * 4, covs)
    m = episode_metrics(track)
    assert m["singular_share"] == pytest.approx(3 / 5) and m["nees_median"] == math.inf
    assert m["inside_95"] == pytest.approx(2 / 5) and m["covariance_missing"] == 0.0 and "nees_mean" not in m
    finite = {**m, "singular_share": 0.0, "nees_median": 2.0}
    eps = [SimpleNamespace(cell=Cell("spin", "mcl_bearing", 0, seed), metrics=v) for seed, v in enumerate((m, finite))]
    (row,) = summarize(eps, resamples=20, metrics=CORE_METRICS)
    assert (row.stats["nees_median"].mean, row.stats["nees_median"].n) == (2.0, 1)
    assert (row.stats["singular_share"].mean, row.stats["singular_share"].n) == (pytest.approx(0.3), 2)
    assert "nees_mean" not in {info.key for info in CORE_METRICS}


@pytest.fixture
def resection_without_covariance() -> Iterator[str]:
    from localizers.registry import LOCALIZERS, register_localizer, spec

    name = "resection_no_covariance"
    register_localizer(name, dataclasses.replace(spec("resection"), covariance=False))
    yield name
    LOCALIZERS.pop(name, None)


def test_a_localizer_without_covariance_says_so(resection_without_covariance: str, tmp_path: Path) -> None:
    spec = EvalSpec(policies=("spin",), localizers=("resection", resection_without_covariance), crowd_sizes=(0,), seeds=1,
                    episode_steps=20)  # fmt: skip
    result = evaluate(spec, workers=1, progress=False)
    plain, marked = result.episodes
    assert plain.metrics["position_error_mean_m"] == marked.metrics["position_error_mean_m"]  # the same localizer
    assert np.isfinite(plain.metrics["nees_median"]) and np.isfinite(plain.covariances[1:]).all()
    assert math.isnan(marked.metrics["nees_median"]) and np.isnan(marked.covariances).all()
    write_outputs(result, tmp_path, gif=False)
    md = (tmp_path / "summary.md").read_text()
    row = next(line for line in md.splitlines() if f"| {resection_without_covariance} |" in line)
    assert row.split(" | ").count("no covariance") == 3 and "nan" not in row  # singular share, NEES median, inside 95%
    assert "singular covariance: share of steps whose covariance is singular" in md and "collapsed onto one pose" in md
    with open(tmp_path / "summary.csv") as f:
        by_name = {r["localizer"]: r for r in csv.DictReader(f)}
    assert by_name[resection_without_covariance]["singular_share"] == "no covariance"
    assert float(by_name["resection"]["singular_share"]) >= 0.0
    with open(tmp_path / "episodes.csv") as f:
        assert [r["inside_95"] == "no covariance" for r in csv.DictReader(f)] == [False, True]
    assert (tmp_path / "plots" / "error_vs_spread.png").is_file()


def test_an_episode_without_a_fix_has_nan_errors_and_first_fix() -> None:
    truth = np.zeros((4, 3))
    visible = np.ones((4, 8), bool)
    track = Track(np.arange(4.0), truth, np.full((4, 3), np.nan), np.zeros(4, bool), [0] * 4, np.zeros((3, 3)), [-1.0] * 3)
    m = {**episode_metrics(track), **bearing_metrics(track, visible, np.ones(4))}
    assert m["third_landmark_s"] == 0.0
    assert m["fixed"] == 0.0 and m["availability"] == 0.0 and m["episode_return"] == -3.0
    for key in ("position_error_mean_m", "heading_error_rms_deg", "failure_rate", "first_fix_s", "first_fix_distance_m",
                "fix_after_third_s", "error_bound_ratio"):  # fmt: skip
        assert math.isnan(m[key]), key
    for key in ("singular_share", "nees_median", "inside_95", "covariance_missing"):  # no valid step at all
        assert math.isnan(m[key]), key


def test_bootstrap_ci_of_a_constant_sample_has_zero_width() -> None:
    assert bootstrap_ci([2.5] * 7, rng=np.random.default_rng(0)) == (2.5, 2.5)
    assert bootstrap_ci([1.0, np.nan, 1.0], rng=np.random.default_rng(0)) == (1.0, 1.0)  # NaN dropped
    lo, hi = bootstrap_ci([np.nan], rng=np.random.default_rng(0))
    assert math.isnan(lo) and math.isnan(hi)


def test_bootstrap_ci_matches_the_normal_interval_and_covers_the_mean() -> None:
    rng = np.random.default_rng(1)
    # a large normal sample: the interval is about mean +- 1.96 sd / sqrt(n)
    x = rng.normal(3.0, 2.0, 400)
    lo, hi = bootstrap_ci(x, 2000, rng=rng)
    half = 1.96 * x.std(ddof=1) / math.sqrt(x.size)
    assert lo == pytest.approx(x.mean() - half, abs=0.1 * half)
    assert hi == pytest.approx(x.mean() + half, abs=0.1 * half)
    # coverage of the true mean over repeated samples of 30 is close to 95%
    covered = [lo <= 0.0 <= hi for lo, hi in (bootstrap_ci(rng.normal(0.0, 1.0, 30), 2000, rng=rng) for _ in range(300))]
    assert 0.88 <= np.mean(covered) <= 0.99
    # the same generator state gives the same interval
    assert bootstrap_ci(x, rng=np.random.default_rng(5)) == bootstrap_ci(x, rng=np.random.default_rng(5))


def test_tum_round_trip_keeps_positions_and_yaw(tmp_path: Path) -> None:
    t = np.linspace(0.0, 2.0, 9)
    yaw = np.linspace(-math.pi + 1e-3, math.pi - 1e-3, 9)
    poses = np.column_stack([np.linspace(0, 4, 9), np.linspace(1, -1, 9), yaw])
    valid = np.ones(9, dtype=bool)
    valid[[0, 4]] = False
    path = write_tum(tmp_path / "traj.tum", t, poses, valid)
    t_back, poses_back = read_tum(path)
    np.testing.assert_allclose(t_back, t[valid], atol=1e-6)
    np.testing.assert_allclose(poses_back[:, :2], poses[valid, :2], atol=1e-6)
    np.testing.assert_allclose(poses_back[:, 2], yaw[valid], atol=1e-8)


def test_eval_seeds_are_held_out_and_episodes_replay() -> None:
    spec = EvalSpec(policies=("random_walk",), crowd_sizes=(3,), seeds=3, episode_steps=20)
    assert spec.eval_seeds == (EVAL_SEED_BASE, EVAL_SEED_BASE + 1, EVAL_SEED_BASE + 2)
    assert all(c.seed >= EVAL_SEED_BASE for c in spec.cells())
    a, b = run_episode(spec, spec.cells()[0]), run_episode(spec, spec.cells()[0])
    np.testing.assert_array_equal(a.true_pose, b.true_pose)
    np.testing.assert_array_equal(a.estimates, b.estimates)
    assert a.metrics == pytest.approx(b.metrics, nan_ok=True)
    other = run_episode(spec, spec.cells()[1])
    assert not np.array_equal(a.true_pose, other.true_pose)
    assert a.true_pose.shape == (21, 3) and a.odometry.shape == (20, 3) and a.rewards.shape == (20,)
    # validation seeds: another range, disjoint from the test seeds, and other episodes
    validation = EvalSpec(policies=("random_walk",), crowd_sizes=(3,), seeds=3, first_seed=1000, episode_steps=20)
    assert validation.eval_seeds == (EVAL_SEED_BASE + 1000, EVAL_SEED_BASE + 1001, EVAL_SEED_BASE + 1002)
    assert not set(validation.eval_seeds) & set(spec.eval_seeds)
    assert not np.array_equal(run_episode(validation, validation.cells()[0]).true_pose, a.true_pose)


def test_evaluate_runs_only_the_groups_asked_for_on_all_seeds() -> None:
    spec = EvalSpec(policies=("spin", "random_walk"), crowd_sizes=(0, 3), seeds=2, first_seed=7, episode_steps=5)
    result = evaluate(spec, workers=1, progress=False, groups=[("random_walk", "candidate_sets", 3)])
    assert [e.cell for e in result.episodes] == [c for c in spec.cells() if c.group == ("random_walk", "candidate_sets", 3)]
    assert [(r.policy, r.crowd_size, r.episodes) for r in result.summary] == [("random_walk", 3, 2)]
    with pytest.raises(ConfigError, match=r"groups \[\('spin', 'candidate_sets', 6\)\] are not in the grid"):
        evaluate(spec, workers=1, progress=False, groups=[("spin", "candidate_sets", 3), ("spin", "candidate_sets", 6)])
    with pytest.raises(ConfigError, match="groups needs at least one"):
        evaluate(spec, workers=1, progress=False, groups=[])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"policies": ("teleport",)}, "unknown policy 'teleport'"),
        ({"policies": ("ppo:does/not/exist.zip",)}, "PPO model file 'does/not/exist.zip' does not exist"),
        ({"localizers": ("oracle",)}, "unknown localizer 'oracle'"),
        ({"crowd_sizes": (15,)}, "crowd size 15 out of range 0..14"),
        ({"crowd_sizes": (-1,)}, "crowd size -1 out of range 0..14"),
        ({"seeds": 0}, "seeds must be an integer >= 1, got 0"),
        ({"first_seed": -5}, "first_seed must be an integer from 0 to 1073741824, got -5"),
        # a bool is not a count (True passed as 1 before)
        ({"seeds": True}, "seeds must be an integer >= 1, got True"),
        ({"first_seed": True}, "first_seed must be an integer from 0 to 1073741824, got True"),
        ({"episode_steps": True}, "episode_steps must be an integer >= 1, got True"),
        ({"crowd_sizes": (True,)}, "crowd size True out of range 0..14"),
        ({"bootstrap_resamples": "5"}, "bootstrap_resamples must be an integer >= 1, got '5'"),
        ({"bootstrap_resamples": 2.5}, "bootstrap_resamples must be an integer >= 1, got 2.5"),
        ({"bootstrap_seed": -1}, "bootstrap_seed must be an integer >= 0, got -1"),
        ({"env_kwargs": {"prior": "maybe"}}, "prior must be 'start' or 'none', got 'maybe'"),
        ({"env_kwargs": {"belief_spread": "yes"}}, "belief_spread must be true or false, got 'yes'"),
        ({"env_kwargs": {"crowd_size": 3}}, "env_kwargs may not set 'crowd_size'"),
        ({"env_kwargs": {"camera": {"fov_rad": 9.0}}}, "camera.fov_rad must be in (0, 2 pi], got 9.0"),
        ({"env_kwargs": {"kamera": {}}}, "unknown env keyword 'kamera'"),
        ({"env_kwargs": "fov=1"}, "env_kwargs must be a mapping, got 'fov=1'"),
        (
            {"env_id": "crowdloc/Nowhere-v0"},
            "unknown env id 'crowdloc/Nowhere-v0'; known: crowdloc/CeilingCorridor-v0, crowdloc/CrowdedRoom-v0, ",
        ),
        ({"env_kwargs": {"world": 3}}, "env_kwargs world must be a YAML path or a shipped world name, got 3"),
        # a localizer whose world lacks the sensor its measurement kind reads
        (
            {"localizers": ("mcl_lidar",)},
            "localizer 'mcl_lidar' in world 'robocup_crowded' (crowdloc/RoboCupCrowded-v0) "
            "needs a lidar sensor (scan measurements); this world has odometry (odometry), camera (bearing_camera)",
        ),
        (
            {"env_id": "crowdloc/CrowdedRoom-v0", "policies": ("spin",)},
            "localizer 'candidate_sets' in world 'crowded_room' "
            "(crowdloc/CrowdedRoom-v0) needs a bearing_camera sensor (bearings measurements); this world has odometry "
            "(odometry), lidar (lidar)",
        ),
        # a policy that plans on the landmarks the camera sees, in a world without a camera
        (
            {"env_id": "crowdloc/CrowdedRoom-v0", "localizers": ("mcl_lidar",)},
            "policy 'landmark_seeking' needs a "
            "bearing_camera sensor and world 'crowded_room' (crowdloc/CrowdedRoom-v0) has none (its sensors: odometry, "
            "lidar); fixed policies it can run: random_walk, spin, stop_and_go, patrol",
        ),
    ],
)
def test_bad_specs_are_refused_with_the_value(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=re.escape(message)):
        EvalSpec(**kwargs)


def test_numpy_integers_are_taken_and_kept_as_python_integers() -> None:
    spec = EvalSpec(seeds=np.int64(2), first_seed=np.int32(3), episode_steps=np.int64(5), crowd_sizes=[np.int64(2)],
                    bootstrap_resamples=np.int64(10), bootstrap_seed=np.uint8(1))  # fmt: skip
    values = (spec.seeds, spec.first_seed, spec.episode_steps, *spec.crowd_sizes, spec.bootstrap_resamples, spec.bootstrap_seed)
    assert values == (2, 3, 5, 2, 10, 1)
    assert all(type(v) is int for v in values)  # what the run's files record as JSON


def test_the_odometry_an_episode_records_is_the_world_s_one_odometry_sensor() -> None:
    from agents.evaluate.spec import odometry_key_of

    lidar = {"type": "lidar", "key": "lidar"}
    assert odometry_key_of({"wheels": {"type": "odometry", "key": "odo"}, "lidar": lidar}) == "odo"
    with pytest.raises(
        ConfigError, match=r"an evaluated world \(its episode record\) needs an odometry sensor .*lidar \(lidar\)"
    ):
        odometry_key_of({"lidar": lidar})
    with pytest.raises(ConfigError, match=r"reads odometry from an odometry sensor, and this world has several: a, b"):
        odometry_key_of({"a": {"type": "odometry", "key": "a"}, "b": {"type": "odometry", "key": "b"}})


def test_conditions_reach_the_episode_and_the_bound() -> None:
    from core.geometry import in_field_of_view

    fov = 1.0
    spec = EvalSpec(policies=("spin",), localizers=("mcl_bearing",), crowd_sizes=(0,), seeds=1, episode_steps=30,
                    env_kwargs={"camera": {"fov_rad": fov}, "prior": "none"})  # fmt: skip
    assert not spec.known_start("mcl_bearing")
    assert EvalSpec(localizers=("kalman",)).known_start("kalman")  # the localizer's own default (the paper's KF)
    assert not EvalSpec(localizers=("mcl_bearing",)).known_start("mcl_bearing")
    episode = run_episode(spec, spec.cells()[0])
    from envs import load_world

    landmarks = np.array([(lm.x_m, lm.y_m) for lm in load_world("robocup_crowded").landmarks])
    for pose, seen in zip(episode.true_pose, episode.visible):
        assert np.array_equal(seen, in_field_of_view(pose[:2], pose[2], landmarks, fov))  # no crowd: only the view limits
    assert 0 < episode.visible.sum(axis=1).max() < len(landmarks)
    known = EvalSpec(policies=("spin",), localizers=("mcl_bearing",), crowd_sizes=(0,), seeds=1, episode_steps=30,
                     env_kwargs={"camera": {"fov_rad": fov}, "prior": "start"})  # fmt: skip
    # a known start makes the bound small from the first step; starting lost it is as wide as the field
    assert run_episode(known, known.cells()[0]).bound_rmse_m[0] < 0.01 < episode.bound_rmse_m[0]


def test_cli_takes_conditions_from_a_training_config_and_env_set(tmp_path: Path) -> None:
    from agents.evaluate import run_cli

    args = build_parser(["eval"]).parse_args(
        [
            "eval",
            "--conditions",
            "ppo_candidate_sets",
            "--env-set",
            "camera.fov_rad=1.0",
            "--env-set",
            "camera.max_range_m=4",
            "--policies",
            "spin",
            "--crowd-sizes",
            "0",
            "--seeds",
            "1",
            "--episode-steps",
            "3",
            "--no-gif",
            "--no-progress",
            "--out",
            str(tmp_path),
        ]  # fmt: skip
    )
    result = run_cli(args)
    trained = load_train_config("ppo_candidate_sets")
    camera = {**trained.env_kwargs["camera"], "fov_rad": 1.0, "max_range_m": 4}  # --env-set merges into the section
    assert result.spec.env_kwargs == {**trained.env_kwargs, "camera": camera}
    assert result.spec.reward == trained.reward
    with pytest.raises(ConfigError, match="differs from the env of --conditions"):
        run_cli(build_parser(["eval"]).parse_args(["eval", "--conditions", "ppo_candidate_sets", "--env-id",
                                                   "crowdloc/RoboCupStatic-v0"]))  # fmt: skip


def test_cli_refuses_a_missing_ppo_file_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["eval", "--policies", "ppo:missing/model.zip", "--no-progress"])
    assert exit_info.value.code == 2
    assert "error: PPO model file 'missing/model.zip' does not exist" in capsys.readouterr().err


def _commands() -> list[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return sorted(sub.choices)  # type: ignore[arg-type]


@pytest.mark.parametrize("command", _commands())
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    assert f"crowdloc {command}" in capsys.readouterr().out


def test_a_tiny_ppo_model_is_evaluated(tmp_path: Path) -> None:
    overrides = {"total_timesteps": 64, "n_envs": 2, "vec_env": "dummy", "crowd_sizes": [3], "ppo.n_steps": 32,
                 "ppo.batch_size": 32, "ppo.n_epochs": 1, "ppo.net_arch": [16]}  # fmt: skip
    config = load_train_config("ppo_candidate_sets", overrides)
    model = train(config, tmp_path, progress_bar=False)
    policy = f"ppo:{model}"
    # it was trained with a sonar ring and the belief spread: without them it has nothing to read, and says so up front
    with pytest.raises(ConfigError, match=r"other observations than these conditions give "
                       r"\(belief_spread: policy \(2,\), env absent; sonar: policy \(12,\), env absent\)"):  # fmt: skip
        EvalSpec(policies=(policy,), crowd_sizes=(3,), seeds=1)
    spec = EvalSpec(policies=(policy,), crowd_sizes=(3,), seeds=1, episode_steps=40, env_kwargs=config.env_kwargs)
    result = evaluate(spec, workers=1, progress=False)
    (episode,) = result.episodes
    assert episode.cell == Cell(policy, "candidate_sets", 3, EVAL_SEED_BASE)
    assert episode.true_pose.shape == (41, 3)
    assert np.isfinite(episode.metrics["episode_return"]) and 0.0 <= episode.metrics["availability"] <= 1.0
    (row,) = result.summary
    assert row.policy == policy and row.episodes == 1


def test_policy_labels_are_the_shortest_distinct_tails_of_their_paths() -> None:
    from agents.evaluate.spec import policy_labels

    labels = policy_labels(["spin", "ppo:/a/b/seed_0/model.zip", "ppo:/a/b/seed_1/model.zip", "ppo:/m/ppo_cs.zip"])
    assert labels == {
        "spin": "spin",
        "ppo:/a/b/seed_0/model.zip": "ppo:seed_0/model",
        "ppo:/a/b/seed_1/model.zip": "ppo:seed_1/model",
        "ppo:/m/ppo_cs.zip": "ppo:ppo_cs",
    }


# --------------------------------------------------------------------------- the output folder: checked, refused, cleared, resumed
#: a tiny eval: one policy, no crowd, two seeds of 10 steps, one process, no GIF
TINY_EVAL = ["eval", "--policies", "spin", "--localizers", "candidate_sets", "--crowd-sizes", "0", "--seeds", "2",
             "--episode-steps", "10", "--workers", "1", "--no-gif", "--no-progress"]  # fmt: skip


def test_eval_into_a_folder_that_cannot_be_made_fails_before_any_episode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import agents.evaluate.cli as eval_cli

    def no_episodes(*args: object, **kwargs: object) -> None:
        raise AssertionError("episodes ran before the output folder was checked")

    monkeypatch.setattr(eval_cli, "evaluate", no_episodes)
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit):
        main([*TINY_EVAL, "--out", str(blocker / "out")])
    err = capsys.readouterr().err
    assert f"--out {blocker / 'out'}: cannot create the output folder" in err and "Traceback" not in err


def test_eval_refuses_a_folder_that_is_not_empty_and_overwrite_clears_only_its_own_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "eval"
    assert main([*TINY_EVAL, "--crowd-sizes", "1", "--out", str(out)]) == 0  # an earlier run, at another crowd
    stale = out / "tum" / f"spin__candidate_sets__crowd1__seed{EVAL_SEED_BASE}_estimate.tum"
    assert stale.is_file()
    mine = out / "notes.txt"  # the user's own file
    mine.write_text("keep me")
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main([*TINY_EVAL, "--out", str(out)])
    err = capsys.readouterr().err
    assert f"--out {out} is not empty (episodes.csv, episodes.jsonl," in err and "give --overwrite" in err
    assert main([*TINY_EVAL, "--out", str(out), "--overwrite"]) == 0
    assert not stale.exists() and mine.read_text() == "keep me"
    assert len(list((out / "tum").glob("*.tum"))) == 4 and (out / "episodes.csv").is_file()
    with pytest.raises(SystemExit):
        main([*TINY_EVAL, "--out", str(out), "--overwrite", "--resume"])
    assert "not allowed with argument" in capsys.readouterr().err


def test_a_killed_eval_resumes_to_the_outputs_of_an_uninterrupted_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import agents.evaluate.stats as stats

    clean, killed = tmp_path / "clean", tmp_path / "killed"
    assert main([*TINY_EVAL, "--out", str(clean)]) == 0
    header, first, second = (clean / "episodes.jsonl").read_text().splitlines()
    assert json.loads(header)["spec"]["seeds"] == 2 and json.loads(first)["seed"] == EVAL_SEED_BASE
    # killed while writing the second episode's line: the header, one whole line, half of the next
    killed.mkdir()
    (killed / "episodes.jsonl").write_text(f"{header}\n{first}\n{second[: len(second) // 2]}")
    ran: list[Cell] = []
    run_task = stats.run_task
    monkeypatch.setattr(stats, "run_task", lambda task: ran.append(task[1]) or run_task(task))
    assert main([*TINY_EVAL, "--out", str(killed), "--resume"]) == 0
    assert ran == [Cell("spin", "candidate_sets", 0, EVAL_SEED_BASE + 1)]  # only the episode that was not done
    for name in ("episodes.csv", "summary.csv"):
        assert (killed / name).read_bytes() == (clean / name).read_bytes(), name
    # the journal's lines read the same; their pickles differ only in each episode's update cost, a timing
    readable = [[{k: v for k, v in json.loads(line).items() if k != "data"} for line in (d / "episodes.jsonl").read_text().splitlines()]
                for d in (killed, clean)]  # fmt: skip
    assert readable[0] == readable[1] and len(readable[0]) == 3
    for path in (clean / "tum").glob("*.tum"):
        assert (killed / "tum" / path.name).read_bytes() == path.read_bytes(), path.name

    # the summary page differs only in the wall time
    def without_time(path: Path) -> str:
        return re.sub(r"episodes in \d+ s", "", path.read_text())

    assert without_time(killed / "summary.md") == without_time(clean / "summary.md")

    # another evaluation into that folder is refused, naming what differs; so is a folder with nothing to resume
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main([*("12" if a == "10" else a for a in TINY_EVAL), "--out", str(killed), "--resume"])
    assert "is a run of another evaluation (episode_steps: 10 then, 12 now)" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*TINY_EVAL, "--out", str(tmp_path / "empty"), "--resume"])
    assert "--resume: no episodes.jsonl in" in capsys.readouterr().err


def test_localizer_set_reaches_one_localizer_and_names_bad_values(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """--localizer-set NAME.KEY=VALUE overrides one localizer's parameter (here the candidate sets'
    claim limit, which decides when a pose is given), and a bad name or field is refused, named."""
    base = ["eval", "--policies", "spin", "--localizers", "candidate_sets", "dead_reckoning", "--crowd-sizes", "0",
            "--seeds", "1", "--episode-steps", "60", "--workers", "1", "--no-progress", "--no-gif"]  # fmt: skip
    assert main([*base, "--out", str(tmp_path / "plain")]) == 0
    assert main([*base, "--localizer-set", "candidate_sets.max_spread_m=0.05", "--out", str(tmp_path / "strict")]) == 0

    def availability(folder: str) -> dict[str, float]:
        rows = list(csv.DictReader((tmp_path / folder / "episodes.csv").read_text().splitlines()))
        return {r["localizer"]: float(r["availability"]) for r in rows}

    plain, strict = availability("plain"), availability("strict")
    assert "Localizer parameters: candidate_sets.max_spread_m=0.05." in (tmp_path / "strict" / "summary.md").read_text()
    assert strict["candidate_sets"] < plain["candidate_sets"] and strict["dead_reckoning"] == plain["dead_reckoning"]
    for flag, named in (("kalman.max_spread_m=1", "'kalman', which is not a localizer of the grid"),
                        ("candidate_sets.no_such_field=1", "no_such_field"), ("candidate_sets", "--localizer-set 'candidate_sets' is not KEY=VALUE")):  # fmt: skip
        with pytest.raises(SystemExit):
            main([*base, "--localizer-set", flag, "--out", str(tmp_path / "bad")])
        assert named in capsys.readouterr().err
