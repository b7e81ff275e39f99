"""The benchmark's policy track (agents/benchmark/policy_track.py): fixed policies, belief_greedy, the shipped
models and a user's entrants ranked on each task's unseen test layouts."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import agents  # noqa: F401
from agents.benchmark.policy_track import load_policy_track, ranking, run_policy_track, task_spec, track_specs
from agents.cli import build_parser, main
from agents.policies import FIXED_POLICIES
from agents.policies.base import FixedPolicy
from agents.rl.config import load_train_config
from core.schema import ConfigError


def test_the_shipped_track_runs_each_task_on_its_test_layouts_with_policies_that_can_drive_it() -> None:
    track = load_policy_track()
    assert track.tasks
    for name, task in track.tasks.items():
        config = load_train_config(name)
        spec = task_spec(track, name, seeds=3)
        assert spec.layouts == config.layouts.test and spec.first_seed == 0 and spec.seeds == 3
        assert spec.policies[: len(task.policies)] == task.policies
        assert spec.episode_steps == task.episode_steps and spec.crowd_sizes == task.crowd_sizes


def test_a_track_task_without_layouts_and_bad_choices_are_refused(tmp_path: Path) -> None:
    bad = tmp_path / "track.yaml"
    bad.write_text(
        "name: t\ndescription: d\ntasks:\n  ppo_candidate_sets: {crowd_sizes: [6], episode_steps: 10, policies: [spin]}\n"
    )
    with pytest.raises(ConfigError, match="task 'ppo_candidate_sets' has no layouts"):
        load_policy_track(bad)
    track = load_policy_track()
    with pytest.raises(ConfigError, match="unknown task 'nope' of the policy track"):
        task_spec(track, "nope")
    with pytest.raises(ConfigError, match="--seeds must be from 1 to 100, got 101"):
        task_spec(track, "ppo_candidate_sets_layouts", seeds=101)
    # a model trained on another task's observations (no belief map) cannot enter
    with pytest.raises(ConfigError, match="was trained on other observations"):
        task_spec(track, "ppo_candidate_sets_layouts", ["ppo:models/ppo_candidate_sets.zip"])


class _Still(FixedPolicy):
    """A user's plug-in: stands still."""

    def _act(self, observation: object) -> np.ndarray:
        return np.zeros(2)


def test_a_users_policy_enters_the_table_ranked_by_return(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(FIXED_POLICIES, "still", _Still)
    track = load_policy_track()
    specs = track_specs(track, ["ppo_candidate_sets_layouts"], ["still"], quick=True)
    written = run_policy_track(track, specs, tmp_path, quick=True, workers=1, progress=False)
    result = written["results"]["ppo_candidate_sets_layouts"]
    assert "still" in result.spec.policies
    for _, rows in ranking(result):
        returns = [row.stats["episode_return"].mean for row in rows]
        assert returns == sorted(returns, reverse=True) and all(math.isfinite(r) for r in returns)
        assert {row.policy for row in rows} == set(result.spec.policies)
    board = written["leaderboard"].read_text()
    assert "| still |" in board and "quick: not comparable" in board
    assert (tmp_path / "ppo_candidate_sets_layouts" / "episodes.csv").is_file()
    # the shipped model's paired verdict against the best fixed policy of the same episodes
    verdict = (tmp_path / "ppo_candidate_sets_layouts" / "verdict.md").read_text()
    assert "paired verdict on ppo:ppo_candidate_sets_layouts" in verdict and "| candidate_sets | 6 |" in verdict


def test_a_task_without_its_shipped_model_has_no_verdict(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from agents.benchmark import policy_track

    monkeypatch.setattr(policy_track, "model_path", lambda name: tmp_path / "absent.zip")
    track = load_policy_track()
    specs = track_specs(track, ["ppo_candidate_sets_layouts"], quick=True)
    assert policy_track.shipped_model(track, "ppo_candidate_sets_layouts", specs["ppo_candidate_sets_layouts"]) is None
    run_policy_track(track, specs, tmp_path / "out", quick=True, workers=1, progress=False)
    assert not (tmp_path / "out" / "ppo_candidate_sets_layouts" / "verdict.md").exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--worlds", "crowdloc/CrowdedRoom-v0"], "--worlds belongs to the localizer track"),
        (["--resume"], "--track policies does not resume"),
    ],
)
def test_the_policy_tracks_command_line_refuses_the_localizer_tracks_options(
    extra: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["benchmark", "--track", "policies", "--quick", "--out", str(tmp_path / "o"), *extra])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_tasks_belong_to_the_policy_track(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["benchmark", "--quick", "--tasks", "ppo_room_lidar_layouts", "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2 and "--tasks belongs to the policy track" in capsys.readouterr().err
    assert build_parser().parse_args(["benchmark"]).track == "localizers"


def test_an_unknown_track_lists_the_shipped_ones() -> None:
    with pytest.raises(ConfigError, match=r"policy track 'v0': no such file .*; shipped: v1"):
        load_policy_track("v0")
