"""agents.tune: every shipped search space against its localizer, the tunable set, worlds, failures, the report's resolution."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import optuna
import pytest

import crowdloc_configs
from agents import tune
from agents.cli import main
from agents.common.util import nest
from agents.experiments.replay import Recording
from agents.papers.lidar_far_point import experiment
from agents.tune.report import compare_held_out
from agents.tune.study import _stored_attr
from core.schema import ConfigError
from envs.config import load_world
from localizers.registry import BUILTIN_LOCALIZERS, load_params

# ------------------------------------------------------------------------------------ the shipped spaces


@pytest.mark.parametrize("name", tune.tunable_localizers())
def test_shipped_space_fits_its_localizer(name: str) -> None:
    """Every name is a parameter (load checks it), every range holds its default, and the defaults are the first trial."""
    space = tune.load_search_space(name)
    defaults = space.defaults()
    assert set(defaults) == set(space.names)
    outside = [
        f"{r.name}={defaults[r.name]!r} not in {r.describe()}" for r in space.params if not r.contains(defaults[r.name], defaults)
    ]
    assert not outside, f"{space.path}: defaults outside their range: {outside}"
    assert space.applied(defaults) == defaults  # the defaults trial is the YAML, bit for bit
    load_params(name, nest(space.applied(defaults)))
    for group in space.sum_to_one:
        assert math.fsum(defaults[n] for n in group) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("name", tune.tunable_localizers())
def test_shipped_space_comments_every_range(name: str) -> None:
    """The house style of configs/tuning: a comment above each parameter and a 'Not searched' paragraph."""
    lines = tune.space_path(name).read_text().splitlines()
    assert any(line.startswith("# Not searched") for line in lines), f"{name}: no 'Not searched' paragraph"
    for i, line in enumerate(lines):
        if re.match(r"^  [\w.]+: \{", line):
            above = lines[i - 1].strip()
            assert above.startswith("#") or re.match(r"^[\w.]+: \{", above), f"{name}: {line.strip()} has no comment"


def test_tunable_localizers_are_exactly_those_with_a_file() -> None:
    shipped = set(crowdloc_configs.names("tuning"))
    assert set(tune.tunable_localizers()) == shipped
    assert shipped <= set(BUILTIN_LOCALIZERS)
    untuned = set(tune.UNTUNED)
    assert not shipped & untuned
    assert shipped | untuned == set(BUILTIN_LOCALIZERS)  # every shipped localizer is decided
    assert {"kalman", "mcl_lidar", "far_point_mcl", "mcl_bearing_paper", "resection"} <= shipped
    assert "dead_reckoning" in untuned


def test_cli_help_lists_exactly_the_tunable_localizers(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["tune", "--help"])
    assert exc.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    listed = re.search(r"a localizer with a search space: ([\w, ]+) \(not tunable: ([\w, ]+);", text)
    assert listed, text
    assert listed.group(1).split(", ") == list(tune.tunable_localizers())
    assert set(listed.group(2).split(", ")) == set(tune.UNTUNED)


# ------------------------------------------------------------------------------------ sum_to_one


def _space(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "space.yaml"
    path.write_text(text)
    return path


_MIXTURE = """parameters:
  z_hit: {low: 0.2, high: 1.0}
  z_short: {low: 0.0, high: 0.5}
  z_max: {low: 0.0, high: 0.3}
  z_rand: {low: 0.0, high: 0.5}
"""


def test_sum_to_one_group_is_normalized(tmp_path: Path) -> None:
    space = tune.load_search_space("mcl_lidar", _space(tmp_path, _MIXTURE + "sum_to_one:\n  - [z_hit, z_short, z_max, z_rand]\n"))
    applied = space.applied({"z_hit": 1.0, "z_short": 0.5, "z_max": 0.25, "z_rand": 0.25})
    assert applied == {"z_hit": 0.5, "z_short": 0.25, "z_max": 0.125, "z_rand": 0.125}
    load_params("mcl_lidar", applied)
    with pytest.raises(ConfigError, match="drew weights summing to 0.0"):
        space.applied({"z_hit": 0.0, "z_short": 0.0, "z_max": 0.0, "z_rand": 0.0})


def test_mixture_weights_without_sum_to_one_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"z_hit = 0.2 is not a valid value: .*must be 1"):
        tune.load_search_space("mcl_lidar", _space(tmp_path, _MIXTURE))


@pytest.mark.parametrize(
    ("groups", "message"),
    [
        ("  - [z_hit, hit_std_m]\n", "sum_to_one names 'hit_std_m', which is not searched"),
        ("  - [z_hit]\n", "each sum_to_one group must list at least 2 parameter names"),
        ("  - [z_hit, z_short]\n  - [z_short, z_max, z_rand]\n", "'z_short' is in two sum_to_one groups"),
    ],
)
def test_bad_sum_to_one_groups(tmp_path: Path, groups: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        tune.load_search_space("mcl_lidar", _space(tmp_path, _MIXTURE + "sum_to_one:\n" + groups))


# ------------------------------------------------------------------------------------ worlds


def test_default_worlds_by_measurement_kind() -> None:
    bearing = tune.default_setup("candidate_sets")
    assert (bearing.env_id, bearing.scenario, bearing.episode_steps) == ("crowdloc/RoboCupCrowded-v0", "soccer", 900)
    for name in ("mcl_lidar", "far_point_mcl"):
        lidar = tune.default_setup(name)
        assert (lidar.env_id, lidar.scenario, lidar.measurement) == ("crowdloc/CrowdedRoom-v0", "square", "scan")
        assert lidar.episode_steps == experiment.episode_steps(3) + 10  # the paper's 3 laps
        assert lidar.world_overrides() == {}  # the room as shipped: its queue heads give way to the robot
        assert tune.default_fail_m(lidar.env_id) == 1.0  # paper B's failure
    assert tune.default_fail_m(bearing.env_id) == tune.DEFAULT_FAIL_M
    assert tune.default_setup("mcl_lidar", env_id="crowdloc/RoboCupCrowded-v0").scenario == "soccer"


def test_stereo_edge_localizers_are_tuned_on_the_campus_route() -> None:
    setup = tune.default_setup("far_landmark_pf")
    assert (setup.env_id, setup.scenario, setup.measurement) == ("crowdloc/StereoCampus-v0", "route", "stereo_edges")
    assert setup.episode_steps == load_world("stereo_campus").max_episode_steps  # the drive ends at the route's end
    assert tune.default_setup("mcl_lidar", env_id="crowdloc/StereoCampus-v0").scenario == "route"
    with pytest.raises(ConfigError, match="scenario 'route' drives the world's route; crowdloc/CrowdedRoom-v0 has none"):
        tune.default_setup("mcl_lidar", scenario="route").world()


def test_route_scenario_steers_on_the_reference_and_replays_with_the_prepared_map(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The route is driven on the LIDAR reference (its estimates are in the recording, never the
    tuned localizer's); far_landmark_pf gets the world's default scene map, made once per study."""
    monkeypatch.setenv("CROWDLOC_CACHE", str(tmp_path))
    setup = tune.default_setup("far_landmark_pf", crowd_size=0, episode_steps=120)
    fixed = setup.prepared_params("far_landmark_pf")
    assert Path(fixed["scene_map"]).is_file() and Path(fixed["scene_map"]).is_relative_to(tmp_path)
    assert setup.prepared_params("far_landmark_pf") == fixed  # cached: the same map for every trial
    assert tune.default_setup("mcl_lidar").prepared_params("mcl_lidar") == {}  # no preparation hook
    rec = setup.record(0)
    assert rec.steps == 121 and rec.estimates.shape == (121, 3) and np.all(np.isfinite(rec.estimates))
    ahead = rec.true_pose[-1, :2] - rec.true_pose[0, :2]
    assert np.hypot(*ahead) > 5.0  # it drove along the route
    shipped = tune.score_episode(rec, "far_landmark_pf", fixed, 1.0, failure_penalty_m=1.0, fail_m=0.5)
    assert shipped.availability == 1.0 and shipped.position_error_m < 0.5
    widened = tune.score_episode(
        rec, "far_landmark_pf", {**fixed, "sigma_theta_rad": 0.1}, 1.0, failure_penalty_m=1.0, fail_m=0.5
    )
    assert widened.objective != shipped.objective  # the searched parameters reach the replay


def test_square_scenario_drives_the_lidar_papers_path() -> None:
    setup = tune.default_setup("far_point_mcl", episode_steps=200)
    assert setup.facts().crowd_size == experiment.CROWD_SIZE
    rec = setup.record(0)
    assert rec.steps == 201 and rec.lidar is not None
    assert tuple(rec.true_pose[0]) == pytest.approx(experiment.start_pose())
    assert rec.true_pose[-1, 0] - rec.true_pose[0, 0] == pytest.approx(200 * rec.dt_s * 0.15, abs=0.02)  # along +x at 0.15 m/s


# ------------------------------------------------------------------------------------ failures


@pytest.fixture(scope="module")
def walk() -> Recording:
    setup = tune.EpisodeSetup("crowdloc/RoboCupStatic-v0", scenario="random_walk", episode_steps=30)
    return setup.record(3)


def test_failures_count_valid_estimates_beyond_the_threshold(walk: Recording) -> None:
    base = tune.score_episode(walk, "candidate_sets", None, 1.0)
    everything = tune.score_episode(walk, "candidate_sets", None, 1.0, failure_penalty_m=2.0, fail_m=1e-9)
    nothing = tune.score_episode(walk, "candidate_sets", None, 1.0, failure_penalty_m=2.0, fail_m=1e9)
    valid_steps = round(base.availability * 31)
    assert everything.failures == valid_steps > 0  # every valid estimate fails, no invalid one does
    assert everything.failure_share == pytest.approx(base.availability)
    assert everything.objective == pytest.approx(base.objective + 2.0 * base.availability)
    assert nothing.failures == 0 and nothing.objective == base.objective
    assert base.failures == tune.score_episode(walk, "candidate_sets", None, 1.0, failure_penalty_m=5.0).failures


#: trial values of a 3-trial candidate_sets study (crowd 4, 90 steps, train seeds 0 and 1, sampler
#: seed 0) in the soccer field without systematic odometry and distractors (``_THEN``). The first is
#: the defaults trial, whose value the objective gave before it counted failures: failure penalty 0
#: must repeat it; the others pin TPE's seeded draws of the shipped space (abort_error_rad capped by
#: prune_error_rad)
_OLD_TRIAL_VALUES = (0.04472797229968151, 0.3679741682115709, 0.07258621609528808)
_THEN = ("--env-set", "odometry.wheel_diameter_ratio=1.0", "--env-set", "odometry.wheelbase_ratio=1.0",
         "--env-set", "camera.distractors=[]")  # fmt: skip


def _tiny(tmp_path: Path, *extra: str) -> list[float]:
    storage = f"sqlite:///{tmp_path / 'tuning.db'}"
    argv = ["tune", "candidate_sets", "--trials", "3", "--storage", storage, "--study-name", "tiny", "--out",
            str(tmp_path / "out"), "--crowd-size", "4", "--episode-steps", "90", "--train-seeds", "2", "--eval-seeds",
            "2", "--quiet", *_THEN, *extra]  # fmt: skip
    assert main(argv) == 0
    study = optuna.load_study(study_name="tiny", storage=storage)
    return [float(t.value) for t in study.trials if t.value is not None]


def test_failure_penalty_zero_repeats_the_old_objective(tmp_path: Path) -> None:
    assert tuple(_tiny(tmp_path, "--failure-penalty-m", "0")) == _OLD_TRIAL_VALUES
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["failure_penalty_m"] == 0.0 and summary["fail_m"] == 0.5
    assert set(summary["paired_differences"]) == {"objective_m", "position_error_m", "availability", "failures", "failure_share"}
    assert summary["paired_differences"]["objective_m"]["ci95"] == summary["paired_objective_difference_ci95_m"]
    report = (tmp_path / "out" / "report.md").read_text()
    assert "failures [steps/run]" in report and "| failure share |" in report
    assert summary["resolution"] in report


def test_failure_penalty_changes_the_objective_by_its_term(tmp_path: Path) -> None:
    values = _tiny(tmp_path, "--fail-m", "0.01", "--failure-penalty-m", "3")
    assert values[0] > _OLD_TRIAL_VALUES[0]  # the defaults fail at 1 cm, so the term is positive
    study = optuna.load_study(study_name="tiny", storage=f"sqlite:///{tmp_path / 'tuning.db'}")
    first = study.trials[0]
    assert first.value == pytest.approx(_OLD_TRIAL_VALUES[0] + 3.0 * first.user_attrs["failure_share"])


def test_report_is_not_overwritten_without_overwrite(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "report.md").write_text("mine")
    with pytest.raises(SystemExit) as exc:
        _tiny(tmp_path)
    assert exc.value.code == 2
    assert "report.md exists; give --overwrite" in capsys.readouterr().err
    assert (tmp_path / "out" / "report.md").read_text() == "mine"


def test_study_from_before_failures_continues_only_without_them() -> None:
    old = {"penalty_m": 1.0}  # a stored study's attributes, made before failures were counted
    new = {"failure_penalty_m": 0.0, "fail_m": 0.5}
    assert _stored_attr(old, "failure_penalty_m", new) == 0.0
    assert _stored_attr(old, "fail_m", new) == 0.5
    assert _stored_attr(old, "fail_m", {"failure_penalty_m": 1.0, "fail_m": 0.5}) is None  # differs: refused


# ------------------------------------------------------------------------------------ what the seeds resolve


def _score(objective: float) -> tune.EpisodeScore:
    return tune.EpisodeScore(objective, 0.0, 1.0, 0.0, objective)


def test_resolution_text_is_computed_from_the_interval() -> None:
    better = [(_score(1.0), _score(1.0 - d)) for d in (0.10, 0.11, 0.09, 0.10, 0.12, 0.08)]
    held = compare_held_out(range(6), better, seed=0)
    text = tune.resolution_text(held)
    low, high = held.paired_ci_m
    assert high < 0 and "excludes zero: the tuned parameters are better" in text
    assert f"{high - low:.4f} m wide (half-width {(high - low) / 2:.4f} m)" in text
    noisy = [(_score(1.0), _score(1.0 + d)) for d in (0.3, -0.3, 0.2, -0.25, 0.05, -0.01)]
    held = compare_held_out(range(6), noisy, seed=0)
    text = tune.resolution_text(held)
    assert "does not exclude zero" in text and "would take about" in text
    few = compare_held_out(range(3), better[:3], seed=0)
    assert "fewer than 5 seeds" in tune.resolution_text(few)
    one = compare_held_out(range(1), better[:1], seed=0)
    assert "single point" in tune.resolution_text(one)


def test_a_far_landmark_pf_study_names_its_scene_map_and_keeps_it_out_of_best_params(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("CROWDLOC_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "out"
    argv = ["tune", "far_landmark_pf", "--crowd-size", "0", "--episode-steps", "60", "--trials", "2", "--train-seeds", "1",
            "--eval-seeds", "1", "--storage", f"sqlite:///{tmp_path / 'tuning.db'}", "--out", str(out), "--quiet"]  # fmt: skip
    assert main(argv) == 0
    scene_map = tune.default_setup("far_landmark_pf", crowd_size=0).prepared_params("far_landmark_pf")["scene_map"]
    assert f"`scene_map` = `{scene_map}`" in (out / "report.md").read_text()
    best = json.loads((out / "summary.json").read_text())["best_params"]
    assert set(best) == set(tune.load_search_space("far_landmark_pf").names)  # the map is given, never tuned
