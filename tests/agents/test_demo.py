"""The demo: part 1 (worlds) and part 2 (active localization) write their report sections."""

from __future__ import annotations

from pathlib import Path

import pytest

from agents.demo import SHIPPED_MODEL, run_active, run_worlds
from agents.policies import FIXED_POLICIES


def test_worlds_part_reports_speed_visibility_and_frames(tmp_path: Path) -> None:
    report = run_worlds(tmp_path, steps=40, densities={"crowdloc/RoboCupCrowded-v0": (0, 3), "crowdloc/CrowdedRoom-v0": (4,)})
    text = report.read_text()
    assert "steps/s" in text and "k=8" in text and "wall beams" in text
    assert (tmp_path / "RoboCupCrowded-v0.png").stat().st_size > 1000
    assert (tmp_path / "CrowdedRoom-v0.png").stat().st_size > 1000


@pytest.mark.parametrize("with_model", [False, True])
def test_active_part_evaluates_every_policy_and_judges_only_with_enough_seeds(tmp_path: Path, with_model: bool) -> None:
    model = SHIPPED_MODEL if with_model else tmp_path / "missing.zip"
    if with_model:
        assert SHIPPED_MODEL.is_file(), "the shipped PPO policy is part of the repository"
    section = run_active(tmp_path, seeds=1, model=model, workers=1, episode_steps=20)
    for policy in FIXED_POLICIES:
        assert f"| {policy} | candidate_sets | 10 |" in section
    assert (tmp_path / "episode.gif").is_file() and (tmp_path / "summary.csv").is_file()
    if with_model:
        assert f"| ppo:{SHIPPED_MODEL} |" in section and "no verdict" in section
    else:
        assert "No trained policy" in section
