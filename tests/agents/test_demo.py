"""The demo: part 1 (worlds) and part 2 (active localization) write their report sections."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents.demo import SHIPPED_MODELS, run_active, run_worlds
from agents.policies import FIXED_POLICIES


def test_worlds_part_reports_speed_visibility_and_frames(tmp_path: Path) -> None:
    report = run_worlds(tmp_path, steps=40, densities={"crowdloc/RoboCupCrowded-v0": (0, 3), "crowdloc/CrowdedRoom-v0": (4,)})
    text = report.read_text()
    assert "steps/s" in text and "k=8" in text and "wall beams" in text
    assert (tmp_path / "RoboCupCrowded-v0.png").stat().st_size > 1000
    assert (tmp_path / "CrowdedRoom-v0.png").stat().st_size > 1000


@pytest.mark.parametrize("with_model", [False, True])
def test_active_part_evaluates_every_policy_and_judges_only_with_enough_seeds(tmp_path: Path, with_model: bool) -> None:
    if with_model:
        for path in SHIPPED_MODELS.values():
            assert path.is_file(), f"the shipped PPO policy {path} is part of the repository"
    models = SHIPPED_MODELS if with_model else {loc: tmp_path / "missing.zip" for loc in SHIPPED_MODELS}
    section = run_active(tmp_path, seeds=1, models=models, workers=1, episode_steps=20)
    for policy in FIXED_POLICIES:
        assert f"| {policy} | candidate_sets | 10 |" in section
    assert (tmp_path / "episode.gif").is_file() and (tmp_path / "summary.csv").is_file()
    if with_model:
        for path in SHIPPED_MODELS.values():
            assert f"| ppo:{path} | mcl_bearing | 6 |" in section  # every policy runs with every localizer
        assert "no verdict" in section and "No trained policy" not in section
    else:
        assert "No trained policy" in section and "ppo:" not in section


def test_verdict_compares_with_the_best_fixed_policy_of_each_metric() -> None:
    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, verdict
    from agents.evaluate import EvalResult, EvalSpec, Stat, SummaryRow

    def row(policy: str, localizer: str, crowd: int, error: tuple[float, float, float], fix: tuple[float, float, float],
            available: tuple[float, float, float]) -> SummaryRow:  # fmt: skip
        stats = {"position_error_mean_m": Stat(*error, 10), "first_fix_s": Stat(*fix, 10), "availability": Stat(*available, 10)}
        return SummaryRow(policy, localizer, crowd, 10, stats)

    rows = []
    for localizer in ACTIVE_LOCALIZERS:
        for crowd in ACTIVE_DENSITIES:
            rows += [
                row("ppo:m.zip", localizer, crowd, (0.05, 0.04, 0.06), (1.0, 0.9, 1.1), (0.5, 0.4, 0.6)),
                row("spin", localizer, crowd, (0.08, 0.07, 0.09), (2.0, 1.8, 2.2), (0.3, 0.2, 0.35)),  # best on error
                # best on first fix and availability (higher is better)
                row("greedy_info_gain", localizer, crowd, (0.20, 0.10, 0.30), (1.05, 0.95, 1.15), (0.9, 0.85, 0.95)),
                row("ppo:other.zip", localizer, crowd, (0.01, 0.00, 0.02), (0.1, 0.0, 0.2), (1.0, 1.0, 1.0)),  # not fixed
            ]
    result = EvalResult(EvalSpec(policies=("spin", "greedy_info_gain")), (), tuple(rows), 0.0)
    lines = verdict(result, dict.fromkeys(ACTIVE_LOCALIZERS, "ppo:m.zip"))
    error_lines = [line for line in lines if "position_error_mean_m" in line]
    fix_lines = [line for line in lines if "first_fix_s" in line]
    assert len(error_lines) == len(fix_lines) == len(ACTIVE_LOCALIZERS) * (len(ACTIVE_DENSITIES) - 1)
    assert all("spin: 0.080" in line and "PPO better" in line for line in error_lines)
    assert all("greedy_info_gain: 1.050" in line and "no significant difference" in line for line in fix_lines)
    available = [line for line in lines if "availability" in line]
    assert len(available) == len(error_lines)
    assert all("greedy_info_gain: 0.900" in line and "PPO worse" in line for line in available)
    only = verdict(result, {"candidate_sets": "ppo:m.zip"})  # a localizer without its own policy is not judged
    assert any("| candidate_sets |" in line for line in only) and not any("| mcl_bearing |" in line for line in only)


def test_first_fix_split_shows_the_trained_and_the_fastest_fixed_policy() -> None:
    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, first_fix_split
    from agents.evaluate import EvalResult, EvalSpec, Stat, SummaryRow

    def row(policy: str, localizer: str, crowd: int, fix: float, third: float) -> SummaryRow:
        values = {"first_fix_s": fix, "third_landmark_s": third, "fix_after_third_s": fix - third}
        return SummaryRow(policy, localizer, crowd, 10, {k: Stat(v, v - 0.1, v + 0.1, 10) for k, v in values.items()})

    rows = [
        row(policy, localizer, crowd, fix, third)
        for localizer in ACTIVE_LOCALIZERS
        for crowd in ACTIVE_DENSITIES
        for policy, fix, third in (("ppo:m.zip", 1.0, 0.3), ("spin", 2.0, 0.9), ("landmark_seeking", 1.25, 0.5))
    ]
    lines = first_fix_split(EvalResult(EvalSpec(), (), tuple(rows), 0.0), {"candidate_sets": "ppo:m.zip"})
    body = lines[2:]
    assert len(body) == 2 * (len(ACTIVE_DENSITIES) - 1)  # the policy and the fastest fixed one per density
    assert all("| candidate_sets |" in line for line in body)
    assert "| candidate_sets | 6 | ppo:m.zip | 1.00 [0.90, 1.10] | 0.30 [0.20, 0.40] | 0.70 [0.60, 0.80] |" in body
    assert "| candidate_sets | 6 | landmark_seeking | 1.25 [1.15, 1.35] | 0.50 [0.40, 0.60] | 0.75 [0.65, 0.85] |" in body
    assert not any("spin" in line for line in body)
    assert "third landmark seen [s]" in lines[0]


def test_caveats_report_identical_first_fixes_and_the_spread_of_episode_errors() -> None:
    from types import SimpleNamespace

    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, caveats
    from agents.evaluate import Cell, EvalResult, EvalSpec, Stat, SummaryRow

    rows, episodes = [], []
    for localizer in ACTIVE_LOCALIZERS:
        for crowd in ACTIVE_DENSITIES:
            for policy, error in (("spin", 0.05), ("greedy_info_gain", 0.7)):
                fix = 0.03 if localizer == "candidate_sets" else 1.0 + error  # identical only for candidate_sets
                rows.append(SummaryRow(policy, localizer, crowd, 1, {"first_fix_s": Stat(fix, fix, fix, 1)}))
                episodes.append(SimpleNamespace(cell=Cell(policy, localizer, crowd, 0), metrics={"position_error_mean_m": error}))
    notes = "\n".join(caveats(EvalResult(EvalSpec(), tuple(episodes), tuple(rows), 0.0)))  # type: ignore[arg-type]
    assert "With `candidate_sets` every policy has its first fix at 0.03 s" in notes
    assert "With `mcl_bearing` every policy" not in notes
    assert "run from 0.050 to 0.700 m" in notes
    assert "sonar" not in notes
    with_sonar = EvalResult(EvalSpec(env_kwargs={"sonar": {}}), tuple(episodes), tuple(rows), 0.0)  # type: ignore[arg-type]
    assert "the sonar ring included" in "\n".join(caveats(with_sonar))


def test_every_shipped_policy_was_trained_in_the_conditions_the_demo_evaluates() -> None:
    from agents.demo import SHIPPED_CONFIG, SHIPPED_MODELS
    from agents.train import load_train_config

    from stable_baselines3 import PPO

    conditions = load_train_config(SHIPPED_CONFIG).env_kwargs
    for localizer, path in SHIPPED_MODELS.items():
        config = load_train_config(f"ppo_{localizer}")
        assert config.localizer == localizer and config.env_kwargs == conditions
        # and the zip is not stale: it observes what an env in those conditions gives (the sonar too)
        env = gym.make(config.env_id, localizer=localizer, **dict(config.env_kwargs))
        assert PPO.load(path, device="cpu").observation_space == env.observation_space, path
        env.close()

