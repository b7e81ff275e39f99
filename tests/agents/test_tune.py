"""agents.tune: a tiny end-to-end study on SQLite, persistence, search-space checks, seed separation."""

from __future__ import annotations

import json
from pathlib import Path

import optuna
import pytest

from agents import tune
from agents.cli import main
from agents.evaluate import metrics
from agents.rl.config import EVAL_SEED_BASE
from core.schema import ConfigError, load_yaml
from localizers.registry import load_params

TINY = ["--crowd-size", "4", "--episode-steps", "90", "--train-seeds", "1", "--eval-seeds", "1", "--quiet"]


def _tune(tmp_path: Path, trials: int, out: str = "out") -> int:
    argv = ["tune", "candidate_sets", "--trials", str(trials), "--storage", f"sqlite:///{tmp_path / 'db' / 'tuning.db'}",
            "--study-name", "tiny", "--out", str(tmp_path / out), *TINY]  # fmt: skip
    return main(argv)


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One 3-trial run of ``crowdloc tune candidate_sets`` (tiny episodes); returns its folder."""
    tmp = tmp_path_factory.mktemp("tune")
    assert _tune(tmp, 3) == 0
    return tmp


def test_tune_writes_report_params_and_plots(tiny_study: Path) -> None:
    out = tiny_study / "out"
    report = (out / "report.md").read_text()
    assert "| defaults |" in report and "| tuned |" in report
    assert (out / "importance.png").stat().st_size > 1000
    assert (out / "history.png").stat().st_size > 1000
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"]["complete"] + summary["trials"]["pruned"] + summary["trials"]["fail"] == 3
    assert set(summary["importances"]) == set(tune.load_search_space("candidate_sets").names)


def test_best_params_yaml_loads_as_localizer_params(tiny_study: Path) -> None:
    data = load_yaml(tiny_study / "out" / "best_params.yaml")
    summary = json.loads((tiny_study / "out" / "summary.json").read_text())
    assert data == summary["best_params"]
    params = load_params("candidate_sets", data)
    for key, value in data.items():
        assert getattr(params, key) == value


def test_first_trial_is_the_yaml_defaults(tiny_study: Path) -> None:
    study = optuna.load_study(study_name="tiny", storage=f"sqlite:///{tiny_study / 'db' / 'tuning.db'}")
    assert study.trials[0].params == tune.load_search_space("candidate_sets").defaults()
    assert study.trials[0].user_attrs["defaults"] is True


def test_study_persists_and_continues(tiny_study: Path) -> None:
    assert _tune(tiny_study, 2, out="continued") == 0
    study = optuna.load_study(study_name="tiny", storage=f"sqlite:///{tiny_study / 'db' / 'tuning.db'}")
    assert len(study.trials) == 5
    params = [tuple(sorted(t.params.items())) for t in study.trials]
    assert len(set(params)) == 5  # the continued sampler does not repeat earlier draws


def test_study_refuses_another_setup(tiny_study: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["tune", "candidate_sets", "--trials", "1", "--storage", f"sqlite:///{tiny_study / 'db' / 'tuning.db'}",
            "--study-name", "tiny", "--out", str(tiny_study / "other"), *TINY, "--episode-steps", "60"]  # fmt: skip
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "study 'tiny'" in err and "created with episode_steps=90" in err and "episode_steps=60" in err


def test_tuning_and_eval_seeds_are_disjoint(tiny_study: Path) -> None:
    summary = json.loads((tiny_study / "out" / "summary.json").read_text())
    assert summary["train_seeds"] == [0]
    assert summary["eval_seeds"] == [EVAL_SEED_BASE]
    many_train, many_eval = tune.tuning_seeds(10_000), tune.eval_seeds(10_000)
    assert not set(many_train) & set(many_eval)
    assert max(many_train) < EVAL_SEED_BASE <= min(many_eval)


def _space(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "space.yaml"
    path.write_text(text)
    return path


def test_space_rejects_unknown_parameter(tmp_path: Path) -> None:
    path = _space(tmp_path, "parameters:\n  prune_error_rad: {low: 1.0, high: 9.0}\n  pruning_error: {low: 1.0, high: 2.0}\n")
    with pytest.raises(ConfigError, match=r"space\.yaml: 'pruning_error' is not a parameter of localizer 'candidate_sets'"):
        tune.load_search_space("candidate_sets", path)


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ("{low: 9.0, high: 1.0}", r"prune_error_rad: low \(9.0\) must be < high \(1.0\)"),
        ("{low: 2.0, high: 2.0}", r"prune_error_rad: low \(2.0\) must be < high \(2.0\)"),
        ("{low: 0.0, high: 2.0, log: true}", r"prune_error_rad: a log range needs low > 0"),
        ("{low: -1.0, high: 2.0}", r"prune_error_rad = -1.0 is not a valid value"),
        ("{low: 1.0}", r"prune_error_rad: missing 'high'"),
        ("{low: 1.0, high: 2.0, scale: log}", r"prune_error_rad: unknown key 'scale'"),
    ],
)
def test_space_rejects_bad_bounds(tmp_path: Path, entry: str, message: str) -> None:
    path = _space(tmp_path, f"parameters:\n  prune_error_rad: {entry}\n")
    with pytest.raises(ConfigError, match=message):
        tune.load_search_space("candidate_sets", path)


def test_space_needs_integer_bounds_for_integer_parameter(tmp_path: Path) -> None:
    path = _space(tmp_path, "parameters:\n  determine_below: {low: 2.5, high: 100}\n")
    with pytest.raises(ConfigError, match=r"determine_below: low must be an integer, got 2.5"):
        tune.load_search_space("candidate_sets", path)


@pytest.mark.parametrize("name", tune.tunable_localizers())
def test_shipped_spaces_load(name: str) -> None:
    space = tune.load_search_space(name)
    assert space.names and set(space.defaults()) == set(space.names)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["tune", "no_such_localizer"], "unknown localizer 'no_such_localizer'"),
        (["tune", "dead_reckoning"], "localizer 'dead_reckoning' is not tunable: it has nothing to tune"),
        (["tune", "ceiling_target"], "localizer 'ceiling_target' is not tunable: its colour thresholds are fitted"),
        (["tune", "candidate_sets", "--trials", "0"], "argument --trials: expected an integer >= 1, got 0"),
        (["tune", "candidate_sets", "--env-id", "crowdloc/CrowdedRoom-v0"], "CrowdedRoom-v0 has no bearing_camera"),
        (["tune", "mcl_lidar", "--env-id", "crowdloc/RoboCupCrowded-v0"], "RoboCupCrowded-v0 has no lidar"),
        (["tune", "mcl_lidar", "--scenario", "soccer"], "scenario 'soccer' needs a world with a ball"),
        (["tune", "candidate_sets", "--scenario", "square"], "scenario 'square' is the LIDAR paper's path in crowdloc/Crowd"),
        (["tune", "candidate_sets", "--fail-m", "0"], "--fail-m must be a finite number > 0, got 0.0"),
        (["tune", "candidate_sets", "--failure-penalty-m", "-1"], "--failure-penalty-m must be a finite number >= 0, got -1.0"),
    ],
)
def test_cli_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str) -> None:
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--storage", f"sqlite:///{tmp_path / 't.db'}", "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert message in err[-1]
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("storage", "message"),
    [
        (
            "notadb://x",
            "--storage 'notadb://x': cannot open the database (NoSuchModuleError: Can't load plugin: sqlalchemy.dialects:notadb)",
        ),  # fmt: skip
        ("not a url", "--storage 'not a url': not a database URL"),
        ("sqlite:///{blocker}/sub/t.db", "cannot create its folder"),
    ],
)
def test_a_bad_storage_is_one_line_naming_the_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], storage: str, message: str
) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit) as exc:
        main(["tune", "resection", "--trials", "1", "--storage", storage.format(blocker=blocker), "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert message in err.strip().splitlines()[-1] and "Traceback" not in err


def test_tune_config_rejects_zero_trials() -> None:
    with pytest.raises(ConfigError, match="trials must be >= 1, got 0"):
        tune.tune(tune.TuneConfig("candidate_sets", trials=0))


def test_tune_help_exits_zero(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["tune", "--help"])
    assert exc.value.code == 0
    assert "--trials" in capsys.readouterr().out


def test_parallel_workers_share_the_study(tmp_path: Path) -> None:
    storage = f"sqlite:///{tmp_path / 'parallel.db'}"
    argv = ["tune", "candidate_sets", "--trials", "4", "--workers", "2", "--storage", storage, "--study-name", "par",
            "--out", str(tmp_path / "out"), *TINY]  # fmt: skip
    assert main(argv) == 0
    study = optuna.load_study(study_name="par", storage=storage)
    assert len(study.trials) == 4
    assert all(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials)
    assert sum(bool(t.user_attrs.get("defaults")) for t in study.trials) == 1


def test_random_walk_scenario_and_unavailability_penalty() -> None:
    setup = tune.EpisodeSetup("crowdloc/RoboCupStatic-v0", scenario="random_walk", episode_steps=30)
    setup.world()
    rec = setup.record(3)
    assert rec.steps == 31 and rec.seed == 3
    assert metrics.travelled(rec.true_pose)[-1] > 0.5  # the random walk drives
    score = tune.score_episode(rec, "candidate_sets", None, 5.0)
    assert 0.0 < score.availability < 1.0  # no pose before the first fix
    assert score.objective == pytest.approx(score.position_error_m + 5.0 * (1.0 - score.availability))


def test_localizer_that_never_fixes_scores_diagonal_plus_penalty() -> None:
    setup = tune.EpisodeSetup(crowd_size=2, episode_steps=20, env_overrides={"camera": {"dropout_probability": 1.0}})
    score = tune.score_episode(setup.record(1), "candidate_sets", None, 1.0)
    assert score.availability == 0.0 and score.first_fix_s == float("inf")
    assert score.objective == pytest.approx(50.0**0.5 + 1.0)  # 5 m x 5 m field: diagonal + 1 m x (1 - 0)


def test_soccer_scenario_needs_a_ball() -> None:
    with pytest.raises(ConfigError, match="scenario 'soccer' needs a world with a ball; crowdloc/RoboCupStatic-v0 has none"):
        tune.EpisodeSetup("crowdloc/RoboCupStatic-v0", scenario="soccer").world()
