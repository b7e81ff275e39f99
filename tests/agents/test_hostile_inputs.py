"""Hostile input gets one clear line, before any work, instead of a traceback from deep inside
yaml, stable-baselines3, pathlib or a prepare hook; and settings that would be silently
meaningless are refused."""

from __future__ import annotations

import zipfile
from pathlib import Path

import gymnasium as gym
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents import tune
from agents.cli import main
from agents.evaluate import EvalSpec
from agents.evaluate.kidnap import Kidnap
from core.schema import ConfigError
from localizers.candidate_sets import CandidateSetParams
from localizers.registry import load_params


def _one_line(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``crowdloc ARGV``, expect the usage error (exit 2) and return its last line."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def test_an_override_that_is_not_yaml_is_one_line(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    line = _one_line(["train", "ppo_candidate_sets", "--set", "env_kwargs={prior: [", "--out", str(tmp_path),
                      "--no-progress"], capsys)  # fmt: skip
    assert "--set 'env_kwargs={prior: [': the value is not valid YAML" in line
    assert not any(tmp_path.iterdir())  # nothing written


@pytest.mark.parametrize("command", ["eval", "benchmark"])
@pytest.mark.parametrize("content", ["not a zip", "a zip without a model"])
def test_a_model_file_stable_baselines3_cannot_load_is_one_line(
    command: str, content: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    model = tmp_path / "model.zip"
    if content == "not a zip":
        model.write_text("not a zip")
    else:
        with zipfile.ZipFile(model, "w") as archive:
            archive.writestr("notes.txt", "no data inside")
    out = tmp_path / "out"
    argv = [command, "--policies", f"ppo:{model}", "--out", str(out), "--no-progress"]
    argv += ["--quick"] if command == "benchmark" else ["--seeds", "1", "--episode-steps", "5"]
    line = _one_line(argv, capsys)
    assert str(model) in line
    assert ("is not a zip archive" if content == "not a zip" else "cannot be loaded by stable-baselines3") in line
    assert not out.exists()  # refused before the first episode


def test_a_kidnap_farther_than_the_arena_allows_is_refused_before_the_first_episode() -> None:
    with pytest.raises(ConfigError, match=r"kidnap.min_distance_m 1e\+09 cannot be placed in world 'robocup_crowded'.*"
                                          r"use less than 4.24 m"):  # fmt: skip
        EvalSpec(policies=("spin",), seeds=1, episode_steps=1000, kidnap=Kidnap(at_s=0.5, min_distance_m=1e9))
    EvalSpec(policies=("spin",), seeds=1, episode_steps=1000, kidnap=Kidnap(at_s=0.5, min_distance_m=4.0))  # placeable


def test_a_world_that_is_not_a_name_or_a_path_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match=r"world must be a shipped world's name, a YAML path or a WorldConfig, got int 123"):
        gym.make("crowdloc/CrowdedRoom-v0", world=123)


@pytest.mark.parametrize(("env_id", "localizer"), [("crowdloc/StereoCampus-v0", "far_landmark_pf"),
                                                   ("crowdloc/CrowdedRoom-v0", "mcl_lidar")])  # fmt: skip
def test_localizer_params_that_are_not_a_mapping_are_refused_before_any_prepare_hook(env_id: str, localizer: str) -> None:
    with pytest.raises(ConfigError, match=rf"localizer_params for '{localizer}' must be a mapping, got str 'fast'"):
        gym.make(env_id, localizer=localizer, localizer_params="fast")


def test_a_campus_crowd_whose_cars_cannot_fit_is_refused_at_make() -> None:
    with pytest.raises(ConfigError, match=r"lane 'eastbound' of crowd 'campus' \(140.0 m\) has no room for 50 cars 4 m apart "
                                          r"\(100 of the crowd's 200 are cars\)"):  # fmt: skip
        gym.make("crowdloc/StereoCampus-v0", crowd={"campus": {"count": 200, "car_share": 0.5}})


def test_an_abort_threshold_above_the_prune_threshold_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"abort_error_rad 7.0 must not be above prune_error_rad 6.0"):
        CandidateSetParams(prune_error_rad=6.0, abort_error_rad=7.0)
    with pytest.raises(ConfigError, match=r"abort_error_rad 7.0 must not be above prune_error_rad 6.0"):
        load_params("candidate_sets", {"abort_error_rad": 7.0})
    CandidateSetParams(prune_error_rad=6.0, abort_error_rad=6.0)  # equal: abort is the prune's own limit


@pytest.mark.parametrize("name", ["beam_stride", "recovery_beam_stride"])
def test_a_beam_stride_not_below_the_beam_count_is_refused_at_make(name: str) -> None:
    with pytest.raises(ConfigError, match=rf"mcl_lidar.{name} 1081 is not below the 1081 beams of sensor 'lidar'"):
        gym.make("crowdloc/CrowdedRoom-v0", localizer="mcl_lidar", localizer_params={name: 1081})


# ------------------------------------------------------------------ a capped range in a search space


def test_the_shipped_candidate_sets_space_never_draws_abort_above_prune() -> None:
    import optuna

    space = tune.load_search_space("candidate_sets")
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=3))
    for _ in range(200):
        drawn = space.suggest(study.ask())
        assert drawn["abort_error_rad"] <= drawn["prune_error_rad"]
        load_params("candidate_sets", space.applied(drawn))  # every draw is a valid localizer


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("  abort_error_rad: {low: 0.3, high: 40.0, at_most: prune_error_rad}\n"
         "  prune_error_rad: {low: 0.5, high: 60.0}\n", r"at_most 'prune_error_rad' must name a parameter searched before it"),
        ("  prune_error_rad: {low: 0.5, high: 60.0}\n"
         "  abort_error_rad: {low: 0.6, high: 40.0, at_most: prune_error_rad}\n", r"whose low is above abort_error_rad's low 0.6"),
        ("  prune_error_rad: {low: 0.5, high: 60.0}\n"
         "  abort_error_rad: {low: 0.3, high: 40.0, at_most: 5}\n", r"at_most must name another searched parameter, got 5"),
    ],
)  # fmt: skip
def test_a_bad_cap_is_refused(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "space.yaml"
    path.write_text("parameters:\n" + text)
    with pytest.raises(ConfigError, match=message):
        tune.load_search_space("candidate_sets", path)


def test_a_space_without_the_cap_is_refused_where_it_would_draw_abort_above_prune(tmp_path: Path) -> None:
    path = tmp_path / "space.yaml"
    path.write_text("parameters:\n  prune_error_rad: {low: 0.5, high: 60.0}\n  abort_error_rad: {low: 0.3, high: 40.0}\n")
    with pytest.raises(ConfigError, match=r"prune_error_rad = 0.5 is not a valid value: .*abort_error_rad 4.0 must not be above"):
        tune.load_search_space("candidate_sets", path)
