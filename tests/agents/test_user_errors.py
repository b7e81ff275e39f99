"""Bad input from a user gets a one-line error naming it (issue: the command line and the make call)."""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import Iterator
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import crowdloc_configs
import envs  # noqa: F401  (registers crowdloc/*)
from agents.cli import build_parser, main
from agents.evaluate import EvalSpec
from core.schema import ConfigError


def _parse_error(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    with pytest.raises(SystemExit) as exc:
        build_parser(list(argv)).parse_args(list(argv))
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize(
    "argv",
    [
        ("train", "ppo_candidate_sets", "--seed", "-1"),
        ("train", "ppo_candidate_sets", "--seeds", "0", "-2"),
        ("demo", "--seed", "-3"),
        ("tune", "candidate_sets", "--seed", "-1"),
        ("train", "ppo_candidate_sets", "--seed", "one"),
    ],
)
def test_a_bad_seed_is_a_one_line_error_naming_the_flag(capsys: pytest.CaptureFixture[str], argv: tuple[str, ...]) -> None:
    err = _parse_error(capsys, *argv)
    assert "--seed" in err and "expected a seed (an integer >= 0)" in err and argv[-1] in err


def test_resume_from_a_missing_file_says_so(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    missing = tmp_path / "missing.zip"
    with pytest.raises(SystemExit):
        main(["train", "ppo_candidate_sets", "--resume", str(missing), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert f"--resume {missing}: no such checkpoint file" in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()  # nothing written


def test_reproduce_into_a_folder_that_cannot_be_made(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    with pytest.raises(SystemExit):
        main(["reproduce", "bearing-candidates", "--quick", "--out", str(blocker / "out")])
    err = capsys.readouterr().err
    assert "cannot create the output folder" in err and str(blocker / "out") in err


def test_tune_lists_only_the_localizers_it_has_a_search_space_for(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser(["tune", "--help"]).parse_args(["tune", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    listed = re.search(r"with a search space: ([a-z_, ]+) \(not tunable: ([a-z_, ]+);", text)
    assert listed is not None, text
    shipped = {p.stem for p in crowdloc_configs.path("tuning").glob("*.yaml")}
    assert set(listed.group(1).split(", ")) == shipped
    assert set(listed.group(2).split(", ")) == {"dead_reckoning", "ceiling_target"}


def test_a_localizer_that_is_neither_a_name_nor_a_localizer_is_refused_at_make() -> None:
    with pytest.raises(ConfigError, match="registered name or an object with the Localizer interface.*int 3"):
        gym.make("crowdloc/RoboCupCrowded-v0", localizer=3)


def test_the_unknown_keyword_message_names_what_gym_make_also_takes() -> None:
    with pytest.raises(ConfigError) as exc:
        gym.make("crowdloc/RoboCupCrowded-v0", localiser="candidate_sets")
    for word in ("'localiser'", "localizer, localizer_params, prior, belief_spread, localizer_sensor, max_episode_steps"):
        assert word in str(exc.value)


def test_an_unknown_reset_option_is_refused() -> None:
    env = gym.make("crowdloc/RoboCupStatic-v0")
    with pytest.raises(ValueError, match="unknown reset option 'robot_pos' \\(options: robot_pose\\)"):
        env.reset(seed=0, options={"robot_pos": [1.0, 1.0, 0.0]})
    obs, _ = env.reset(seed=0, options={"robot_pose": [1.0, 1.0, 0.0]})
    assert np.isfinite(obs["odometry"]).all()


def test_eval_records_its_conditions_and_takes_the_config_localizer(tmp_path: Path) -> None:
    out = tmp_path / "eval"
    argv = ["eval", "--conditions", "ppo_mcl_bearing", "--policies", "spin", "--crowd-sizes", "2", "--seeds", "1",
            "--episode-steps", "20", "--workers", "1", "--no-gif", "--no-progress", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["spec"]["localizers"] == ["mcl_bearing"]  # the config's localizer, not the default
    assert record["spec"]["env_kwargs"]["camera"]["fov_rad"] == pytest.approx(math.pi / 2)
    assert record["spec"]["env_kwargs"]["prior"] == "none" and record["episodes"] == 1
    assert set(record) >= {"command", "versions", "git_commit"} and record["versions"]["gymnasium"]
    summary = (out / "summary.md").read_text()
    assert "Conditions: " in summary and "camera.fov_rad=1.5708" in summary and "prior='none'" in summary
    episodes = (out / "episodes.csv").read_text().splitlines()
    assert episodes[1].startswith("spin,mcl_bearing,2,")
    # --localizers still chooses
    assert main([*argv[:-1], str(tmp_path / "cs"), "--localizers", "candidate_sets"]) == 0
    assert json.loads((tmp_path / "cs" / "run.json").read_text())["spec"]["localizers"] == ["candidate_sets"]


@pytest.mark.parametrize(
    ("override", "fragments"),
    [
        ("localizer=candidate_set", ["unknown localizer 'candidate_set'"]),
        ("crowd_sizes=[2, 60]", ["crowd size 60", "crowd.count must be in [0, 14], got 60"]),
        ("env_kwargs.prior=nowhere", ["prior must be 'start' or 'none', got 'nowhere'"]),
        ("env_kwargs.camera.fov=1", ["unknown key 'fov'", "BearingCameraConfig"]),
    ],
)
def test_a_bad_training_config_fails_before_anything_is_written(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, override: str, fragments: list[str]
) -> None:
    with pytest.raises(SystemExit):
        main(["train", "ppo_candidate_sets", "--set", override, "--out", str(tmp_path / "out"), "--no-progress"])
    err = capsys.readouterr().err
    assert "Traceback" not in err and "training config 'ppo_candidate_sets'" in err
    for fragment in fragments:
        assert fragment in err, (fragment, err)
    assert not (tmp_path / "out").exists()


def test_a_run_folder_that_holds_a_run_is_not_overwritten_unless_asked(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    from agents.common.output_folder import open_output_folder
    from agents.rl.config import load_train_config
    from agents.rl.train import TRAIN_OUTPUTS, open_run_dir, run_dir

    config = load_train_config("ppo_candidate_sets")
    folder = run_dir(config, tmp_path)
    (folder / "checkpoints").mkdir(parents=True)
    (folder / "model.zip").write_text("not a run's: no manifest lists it")
    with pytest.raises(SystemExit):
        main(["train", "ppo_candidate_sets", "--out", str(tmp_path), "--no-progress", "--overwrite"])
    assert "model.zip would be replaced, but crowdloc train has no record of writing it" in capsys.readouterr().err
    assert (folder / "model.zip").is_file()  # nothing deleted
    (folder / "model.zip").unlink()
    with open_output_folder(folder, TRAIN_OUTPUTS, command="crowdloc train", overwrite=True):  # an earlier run's
        (folder / "model.zip").write_text("an earlier run")
        (folder / "checkpoints" / "step_8.zip").write_text("an earlier run")
    (folder / "checkpoints" / "notes.txt").write_text("the user's")
    with pytest.raises(SystemExit):
        main(["train", "ppo_candidate_sets", "--out", str(tmp_path), "--no-progress"])
    err = capsys.readouterr().err
    assert "already holds a run" in err and "--resume latest" in err and "--overwrite" in err
    assert (folder / "model.zip").read_text() == "an earlier run"  # untouched
    with pytest.raises(SystemExit):
        main(["train", "ppo_candidate_sets", "--out", str(tmp_path), "--resume", "latest", "--overwrite"])
    open_run_dir(config, tmp_path, resume=False, overwrite=True)
    assert not (folder / "model.zip").exists() and not (folder / "checkpoints" / "step_8.zip").exists()
    assert (folder / "checkpoints" / "notes.txt").read_text() == "the user's"  # the run's files only


def test_version_and_the_demo_help_say_what_they_should(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exc:
        build_parser(["--version"]).parse_args(["--version"])
    assert exc.value.code == 0 and capsys.readouterr().out.startswith("crowdloc ")
    with pytest.raises(SystemExit):
        build_parser(["demo", "--help"]).parse_args(["demo", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for part in ("random-walk policy", "active-localization table", "the verdict"):
        assert part in text


def test_an_error_after_parsing_prints_the_subcommand_usage(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["demo", "--active-seeds", "-1"])
    err = capsys.readouterr().err
    assert err.startswith("usage: crowdloc demo") and "--active-seeds must be >= 0, got -1" in err


@pytest.mark.parametrize("value", ["-5", str(2**30 + 1)])
def test_a_bad_first_seed_names_the_flag(capsys: pytest.CaptureFixture[str], tmp_path: Path, value: str) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["eval", "--first-seed", value, "--policies", "spin", "--out", str(tmp_path / "eval")])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("usage: crowdloc eval") and "Traceback" not in err
    assert f"--first-seed must be an integer from 0 to {2**30}, got {value}" in err and "first_seed" not in err
    assert not (tmp_path / "eval").exists()  # nothing run, nothing written
    with pytest.raises(ConfigError, match=rf"^first_seed must be an integer from 0 to {2**30}, got {value}$"):
        EvalSpec(policies=("spin",), first_seed=int(value))  # the Python API names its keyword


@pytest.mark.parametrize("experiment", ["bearing-candidates", "lidar-far-point", "ceiling-target"])
def test_reproduce_never_replaces_a_report_unasked(experiment: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import main

    (tmp_path / "report.md").write_text("mine")
    with pytest.raises(SystemExit) as exc:
        main(["reproduce", experiment, "--quick", "--out", str(tmp_path)])
    assert exc.value.code == 2
    assert "report.md exists; give --overwrite to replace it" in capsys.readouterr().err
    assert (tmp_path / "report.md").read_text() == "mine"


def _every_command_parser() -> Iterator[tuple[str, argparse.ArgumentParser]]:
    """Every (sub-)command's parser, each experiment's and fitter's own options included."""
    from agents.cli import FITTERS
    from agents.papers import EXPERIMENTS

    def leaves(name: str, parser: argparse.ArgumentParser) -> Iterator[tuple[str, argparse.ArgumentParser]]:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        yield name, parser
        for sub in subs:
            for child, child_parser in sub.choices.items():
                yield from leaves(f"{name} {child}".strip(), child_parser)

    argvs = [["tune"], *(["reproduce", e] for e in EXPERIMENTS), *(["fit", f] for f in FITTERS)]
    for argv in argvs:
        yield from leaves("", build_parser(argv))


def test_every_list_option_takes_its_values_separated_by_spaces() -> None:
    lists = set()
    for name, parser in _every_command_parser():
        for action in parser._actions:
            text = f"{name} {'/'.join(action.option_strings)}: {action.help}"
            assert "comma" not in (action.help or "").lower(), text  # one convention: nargs, values separated by spaces
            if action.nargs in ("+", "*"):
                lists.add(f"{name} {action.option_strings[0]}")
    assert {"eval --crowd-sizes", "train --seeds", "reproduce stereo-far-landmarks --crowd-sizes"} <= lists
