"""The kidnapping study of ``crowdloc eval`` (agents.evaluate.kidnap): the jump, its metrics, its checks."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from agents.cli import main
from agents.evaluate import KIDNAP_METRICS, EvalSpec, Kidnap, Track, kidnap_metrics, run_episode
from core.schema import ConfigError


def hand_made(valid: list[bool], errors: list[float]) -> Track:
    """A 1 Hz track along x whose estimates are ``errors`` metres off in y."""
    n = len(valid)
    truth = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    est = truth + np.column_stack([np.zeros(n), errors, np.zeros(n)])
    return Track(np.arange(n, dtype=float), truth, est, valid, np.zeros(n, int), np.zeros((n - 1, 3)), np.zeros(n - 1))


def test_the_metrics_of_a_hand_made_kidnapping() -> None:
    # the jump between rows 2 and 3 (t = 2 s): 2 s confidently wrong, 2 s without a pose, back within 0.2 m at t = 7 s
    valid = [True, True, True, True, True, False, False, True, True, True]
    errors = [0.0, 0.0, 0.0, 3.0, 2.0, 0.0, 0.0, 0.1, 0.5, 0.1]
    got = kidnap_metrics(hand_made(valid, errors), Kidnap(at_s=2.0, window_s=6.0), jump_index=3)
    assert got == {"recovered": 1.0, "recovery_s": 5.0, "wrong_valid_s": 2.0, "lost_s": 2.0}
    # a window that closes before the good pose: not recovered, and nothing after it counts
    short = kidnap_metrics(hand_made(valid, errors), Kidnap(at_s=2.0, window_s=4.0), jump_index=3)
    assert short["recovered"] == 0.0 and math.isnan(short["recovery_s"]) and short["lost_s"] == 2.0
    # passing near the truth and wandering off again is no recovery: only the good pose after the last wrong one counts
    errors = [0.0, 0.0, 0.0, 3.0, 0.1, 2.0, 0.0, 0.1, 0.5, 0.1]
    valid = [True] * 10
    wander = kidnap_metrics(hand_made(valid, errors), Kidnap(at_s=2.0, window_s=6.0), jump_index=3)
    assert wander == {"recovered": 1.0, "recovery_s": 4.0, "wrong_valid_s": 2.0, "lost_s": 0.0}
    again_off = kidnap_metrics(hand_made(valid, [*errors[:9], 1.5]), Kidnap(at_s=2.0, window_s=7.0), jump_index=3)
    assert again_off["recovered"] == 0.0 and again_off["wrong_valid_s"] == 3.0
    # no jump (the episode ended first): no values
    assert all(math.isnan(v) for v in kidnap_metrics(hand_made(valid, errors), Kidnap(), None).values())


def test_an_evaluated_episode_jumps_once_at_the_time_and_reports_the_recovery() -> None:
    kidnap = Kidnap(at_s=2.0, window_s=3.0)
    spec = EvalSpec(policies=("random_walk",), localizers=("mcl_bearing",), crowd_sizes=(0,), seeds=2,
                    episode_steps=160, env_id="crowdloc/RoboCupStatic-v0", kidnap=kidnap)  # fmt: skip
    assert spec.metrics[-len(KIDNAP_METRICS) :] == KIDNAP_METRICS
    episode = run_episode(spec, spec.cells()[0])
    steps = np.hypot(*np.diff(episode.true_pose[:, :2], axis=0).T)
    jumps = np.flatnonzero(steps > 1.0)
    assert jumps.tolist() == [int(round(2.0 * 30))]  # one jump, right after the step at 2 s (30 Hz)
    assert steps[jumps[0]] >= kidnap.min_distance_m
    for m in KIDNAP_METRICS:
        assert m.key in episode.metrics
    assert episode.metrics["recovered"] in (0.0, 1.0)
    again = run_episode(spec, spec.cells()[0])
    assert again.metrics == pytest.approx(episode.metrics, nan_ok=True)  # the jump is seeded too
    plain = EvalSpec(policies=("random_walk",), localizers=("mcl_bearing",), crowd_sizes=(0,), seeds=2,
                     episode_steps=160, env_id="crowdloc/RoboCupStatic-v0")  # fmt: skip
    assert "recovered" not in run_episode(plain, plain.cells()[0]).metrics
    assert not any(m.key == "recovered" for m in plain.metrics)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"at_s": -1.0}, "kidnap.at_s must be a finite number >= 0, got -1.0"),
        ({"window_s": 0.0}, "kidnap.window_s must be a finite number > 0, got 0.0"),
        ({"recover_m": math.nan}, "kidnap.recover_m must be a finite number > 0, got nan"),
        ({"recover_m": 2.0, "wrong_m": 1.0}, "kidnap.wrong_m 1.0 must be at least recover_m 2.0"),
        ({"max_distance_m": 2.0}, "kidnap.max_distance_m must be a number above min_distance_m 2.0, got 2.0"),
        ({"max_distance_m": math.nan}, "kidnap.max_distance_m must be a number above min_distance_m 2.0, got nan"),
        ({"keep_heading": "yes"}, "kidnap.keep_heading must be true or false, got 'yes'"),
    ],
)
def test_bad_kidnaps_are_refused_with_the_value(kwargs: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")):
        Kidnap(**kwargs)


def test_an_episode_shorter_than_the_recovery_window_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"ends before the kidnap's recovery window.*raise episode_steps to at least 1200"):
        EvalSpec(policies=("random_walk",), crowd_sizes=(0,), seeds=1, episode_steps=450, env_id="crowdloc/RoboCupStatic-v0",
                 kidnap=Kidnap(at_s=10.0, window_s=30.0))  # fmt: skip


def test_the_cli_runs_a_kidnapping_and_refuses_its_flags_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    args = ["eval", "--policies", "spin", "--localizers", "resection", "--crowd-sizes", "0", "--seeds", "1",
            "--env-id", "crowdloc/RoboCupStatic-v0", "--workers", "1", "--no-gif", "--no-progress"]  # fmt: skip
    assert (
        main([*args, "--episode-steps", "90", "--kidnap-at-s", "1", "--recover-window-s", "2", "--out", str(tmp_path / "k")]) == 0
    )
    summary = (tmp_path / "k" / "summary.md").read_text()
    assert "recovered after the kidnap" in summary and "confident wrong pose after the kidnap" in summary
    with pytest.raises(SystemExit):  # a usage error: one line under the command's usage
        main([*args, "--episode-steps", "90", "--kidnap-m", "3", "--out", str(tmp_path / "x")])
    assert "--kidnap-m only applies with --kidnap-at-s" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main([*args, "--episode-steps", "90", "--kidnap-max-m", "5", "--kidnap-keep-heading", "--out", str(tmp_path / "y")])
    assert "--kidnap-max-m, --kidnap-keep-heading only applies with --kidnap-at-s" in capsys.readouterr().err


def test_the_cli_kidnaps_by_a_short_pure_translation(tmp_path: Path) -> None:
    args = ["eval", "--policies", "spin", "--localizers", "resection", "--crowd-sizes", "0", "--seeds", "1",
            "--env-id", "crowdloc/RoboCupStatic-v0", "--workers", "1", "--no-gif", "--no-progress", "--episode-steps", "90",
            "--kidnap-at-s", "1", "--recover-window-s", "2", "--kidnap-m", "2", "--kidnap-max-m", "3", "--kidnap-keep-heading",
            "--out", str(tmp_path / "k")]  # fmt: skip
    assert main(args) == 0
    kidnap = json.loads((tmp_path / "k" / "run.json").read_text())["spec"]["kidnap"]
    assert kidnap["max_distance_m"] == 3.0 and kidnap["keep_heading"] is True
    tum = sorted((tmp_path / "k" / "tum").rglob("*groundtruth.tum"))
    assert tum, "the truth's TUM file"
    truth = np.loadtxt(tum[0])  # t x y z qx qy qz qw
    step = np.hypot(*np.diff(truth[:, 1:3], axis=0).T)
    jump = int(np.argmax(step))
    assert 2.0 <= step[jump] <= 3.0 + 0.1  # the jump, plus at most a step's motion
    turned = 2.0 * np.arctan2(truth[:, 6], truth[:, 7])
    spin = np.abs(np.angle(np.exp(1j * np.diff(turned))))
    assert spin[jump] <= 2.0 * np.median(spin) + 1e-6  # the jump turned the robot no more than a step does
