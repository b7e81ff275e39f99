"""The demo: part 1 (worlds) and part 2 (active localization) write their report sections."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from types import SimpleNamespace

import gymnasium as gym
import pytest

import envs  # noqa: F401  (registers crowdloc/*)
from agents.demo import SHIPPED_MODELS, run_active, run_worlds
from agents.evaluate import METRIC_KEYS, Cell
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
    section = run_active(tmp_path, seeds=1, models=models, workers=1, episode_steps=20, verdict_seeds=5)
    for policy in FIXED_POLICIES:  # every one that runs in the shipped policy's world (not the corridor's, the campus's)
        runs = policy not in ("corridor_follower", "route_follower", "look_then_route")
        assert (f"| {policy} | candidate_sets | 10 |" in section) == runs, policy
    assert (tmp_path / "episode.gif").is_file() and (tmp_path / "summary.csv").is_file()
    if with_model:
        for path in SHIPPED_MODELS.values():
            # every policy runs with every localizer; reports name a trained policy by its file's stem
            assert f"| ppo:{path.stem} | mcl_bearing | 6 |" in section and str(path) not in section
        assert "no verdict" in section and "No trained policy" not in section  # 1 seed cannot pick the best fixed
        assert not (tmp_path / "verdict").exists()
    else:
        assert "No trained policy" in section and "ppo:" not in section


def test_the_verdict_judges_the_table_s_best_fixed_policies_on_fresh_seeds(tmp_path: Path) -> None:
    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, MIN_VERDICT_SEEDS, verdict_groups
    from agents.evaluate import EvalResult, EvalSpec, summarize
    from agents.rl.config import EVAL_SEED_BASE

    seeds = MIN_VERDICT_SEEDS
    section = run_active(tmp_path, seeds=seeds, models={"candidate_sets": SHIPPED_MODELS["candidate_sets"]}, workers=1,
                         episode_steps=8, verdict_seeds=seeds + 1)  # fmt: skip
    assert f"fresh test seeds ({EVAL_SEED_BASE} + {seeds}..{2 * seeds}, after the table's)" in section
    table_rows = list(csv.DictReader((tmp_path / "episodes.csv").read_text().splitlines()))
    judged_rows = list(csv.DictReader((tmp_path / "verdict" / "episodes.csv").read_text().splitlines()))
    # the tables name policies by short labels; run.json gives each label's full name
    full = json.loads((tmp_path / "run.json").read_text())["policies"]
    full_judged = json.loads((tmp_path / "verdict" / "run.json").read_text())["policies"]
    for rows, names in ((table_rows, full), (judged_rows, full_judged)):
        for r in rows:
            r["policy"] = names[r["policy"]]
    assert {int(r["seed"]) for r in table_rows} == {EVAL_SEED_BASE + i for i in range(seeds)}
    assert {int(r["seed"]) for r in judged_rows} == {EVAL_SEED_BASE + seeds + i for i in range(seeds + 1)}
    # the groups judged: the trained policy and the table's best fixed policies, picked from the table's episodes
    fake = [SimpleNamespace(cell=Cell(r["policy"], r["localizer"], int(r["crowd_size"]), int(r["seed"])),
                            metrics={k: float(v) for k, v in r.items() if k in METRIC_KEYS}) for r in table_rows]  # fmt: skip
    table = EvalResult(EvalSpec(), (), summarize(fake), 0.0)  # type: ignore[arg-type]
    ppo = f"ppo:{SHIPPED_MODELS['candidate_sets']}"
    groups = verdict_groups(table, {"candidate_sets": ppo})
    assert {(r["policy"], r["localizer"], int(r["crowd_size"])) for r in judged_rows} == set(groups)
    assert {g[2] for g in groups} == set(ACTIVE_DENSITIES[1:]) and {g[1] for g in groups} == {ACTIVE_LOCALIZERS[0]}
    assert (ppo, "candidate_sets", ACTIVE_DENSITIES[1]) in groups and len(groups) >= 4
    verdict_lines = [line for line in section.splitlines() if line.startswith("| candidate_sets | ")
                     and line.count("|") == 7 and ("PPO " in line or "no significant" in line)]  # fmt: skip
    assert len(verdict_lines) == 3 * (len(ACTIVE_DENSITIES) - 1)


def test_verdict_compares_with_the_best_fixed_policy_of_each_metric() -> None:
    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, verdict, verdict_groups
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
    assert verdict(result, dict.fromkeys(ACTIVE_LOCALIZERS, "ppo:m.zip"), result) == lines
    error_lines = [line for line in lines if "position_error_mean_m" in line]
    fix_lines = [line for line in lines if "first_fix_s" in line]
    assert len(error_lines) == len(fix_lines) == len(ACTIVE_LOCALIZERS) * (len(ACTIVE_DENSITIES) - 1)
    assert all("spin: 0.080" in line and "PPO better" in line for line in error_lines)
    assert all("greedy_info_gain: 1.05 [0.95, 1.15] |" in line and "no significant difference" in line for line in fix_lines)
    available = [line for line in lines if "availability" in line]
    assert len(available) == len(error_lines)
    assert all("greedy_info_gain: 0.900" in line and "PPO worse" in line for line in available)
    only = verdict(result, {"candidate_sets": "ppo:m.zip"})  # a localizer without its own policy is not judged
    assert any("| candidate_sets |" in line for line in only) and not any("| mcl_bearing |" in line for line in only)
    # on fresh seeds: the policies picked on the table, their numbers from the judged result
    judged_rows = [r for r in rows if r.policy == "ppo:m.zip"]
    fewer = {"position_error_mean_m": Stat(0.08, 0.07, 0.09, 7)}  # three episodes without a fix
    judged_rows += [SummaryRow("spin", r.localizer, r.crowd_size, 10, {**r.stats, **fewer}) for r in rows if r.policy == "spin"]
    judged_rows += [row("greedy_info_gain", loc, crowd, (0.9, 0.8, 1.0), (3.0, 2.9, 3.1), (0.1, 0.05, 0.15))
                    for loc in ACTIVE_LOCALIZERS for crowd in ACTIVE_DENSITIES]  # fmt: skip
    judged = EvalResult(EvalSpec(policies=("spin", "greedy_info_gain")), (), tuple(judged_rows), 0.0)
    fresh = verdict(result, {"candidate_sets": "ppo:m.zip"}, judged)
    fix_fresh = [line for line in fresh if "first_fix_s" in line]
    assert fix_fresh and all("greedy_info_gain: 3.00" in line and "PPO better" in line for line in fix_fresh)
    assert all("greedy_info_gain: 0.100" in line and "PPO better" in line for line in fresh if "availability" in line)
    assert all("spin: 0.080 [0.070, 0.090] (7/10) |" in line for line in fresh if "position_error_mean_m" in line)
    assert verdict_groups(result, {"candidate_sets": "ppo:m.zip"}) == [
        (policy, "candidate_sets", crowd)
        for crowd in ACTIVE_DENSITIES[1:]
        for policy in ("ppo:m.zip", "spin", "greedy_info_gain")
    ]


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
        # landmark seeking: significantly later at crowd 6, not at crowd 10 (the intervals overlap)
        for policy, fix, third in (
            ("ppo:m.zip", 1.0, 0.3),
            ("spin", 2.0, 0.9),
            ("landmark_seeking", 1.25 if crowd == 6 else 1.1, 0.5),
        )  # fmt: skip
    ]
    lines = first_fix_split(EvalResult(EvalSpec(), (), tuple(rows), 0.0), {"candidate_sets": "ppo:m.zip"})
    notes = [line for line in lines if line.startswith("- ")]
    assert notes == [
        "- `candidate_sets`, crowd 10, no significant gain on first fix: the trained policy's search took 0.30 s "
        "against 0.50 s for landmark_seeking, the localizer's part after it 0.70 s against 0.60 s; the localizer's "
        "part is 70 % of the trained policy's first fix."
    ]
    body = [line for line in lines[2:] if line.startswith("| ")]
    assert len(body) == 2 * (len(ACTIVE_DENSITIES) - 1)  # the policy and the fastest fixed one per density
    assert all("| candidate_sets |" in line for line in body)
    assert "| candidate_sets | 6 | ppo:m | 1.00 [0.90, 1.10] | 0.30 [0.20, 0.40] | 0.70 [0.60, 0.80] |" in body
    assert "| candidate_sets | 6 | landmark_seeking | 1.25 [1.15, 1.35] | 0.50 [0.40, 0.60] | 0.75 [0.65, 0.85] |" in body
    assert not any("spin" in line for line in body)
    assert "third landmark seen [s]" in lines[0]


def test_caveats_report_identical_first_fixes_and_the_spread_of_episode_errors() -> None:
    from agents.demo import ACTIVE_DENSITIES, ACTIVE_LOCALIZERS, caveats
    from agents.evaluate import EvalResult, EvalSpec, Stat, SummaryRow

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
    from stable_baselines3 import PPO

    from agents.demo import SHIPPED_CONFIG, SHIPPED_MODELS
    from agents.rl.config import load_train_config

    conditions = load_train_config(SHIPPED_CONFIG).env_kwargs
    for localizer, path in SHIPPED_MODELS.items():
        config = load_train_config(f"ppo_{localizer}")
        assert config.localizer == localizer and config.env_kwargs == conditions
        # and the zip is not stale: it observes what an env in those conditions gives (the sonar too)
        env = gym.make(config.env_id, localizer=localizer, **dict(config.env_kwargs))
        assert PPO.load(path, device="cpu").observation_space == env.observation_space, path
        env.close()


@pytest.mark.parametrize(("args", "message"), [(["--active-seeds", "-1"], "--active-seeds must be >= 0, got -1"),
                                               (["--verdict-seeds", "-3"], "--verdict-seeds must be >= 0, got -3"),
                                               (["--task-seeds", "-2"], "--task-seeds must be >= 0, got -2")])  # fmt: skip
def test_demo_refuses_negative_seed_counts(args: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["demo", *args])
    assert exit_info.value.code == 2 and message in capsys.readouterr().err


def test_demo_help_gives_the_verdict_s_default_seed_count(capsys: pytest.CaptureFixture[str]) -> None:
    from agents.cli import main
    from agents.demo import VERDICT_SEEDS

    with pytest.raises(SystemExit):
        main(["demo", "--help"])
    assert f"(default {VERDICT_SEEDS};" in " ".join(capsys.readouterr().out.split())


def test_demo_refuses_a_folder_that_is_not_empty_and_overwrite_clears_only_the_demo_s_files(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import agents.demo as demo
    from agents.cli import main
    from agents.common.output_folder import open_output_folder

    old = [tmp_path / "report.md", tmp_path / "active" / "episode.gif", tmp_path / "active" / "tum" / "x__seed1_estimate.tum",
           tmp_path / "corridor" / "corridor_top.png", tmp_path / "RoboCupStatic-v0.png"]  # fmt: skip
    with open_output_folder(tmp_path, demo.DEMO_OUTPUTS, command="crowdloc demo", overwrite=False):  # an earlier demo
        for path in old:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text("an earlier demo's")
    mine = tmp_path / "active" / "my_notes.md"
    mine.write_text("the user's own")

    class Started(Exception):
        pass

    def first_part(*args: object, **kwargs: object) -> None:
        raise Started

    monkeypatch.setattr(demo, "run_worlds", first_part)
    with pytest.raises(SystemExit) as exit_info:
        main(["demo", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert f"--out {tmp_path} is not empty (RoboCupStatic-v0.png, active, corridor, report.md); give --overwrite" in (
        capsys.readouterr().err
    )
    assert all(path.exists() for path in old)  # refused before any run, nothing touched
    with pytest.raises(Started):
        main(["demo", "--out", str(tmp_path), "--overwrite"])
    assert not any(path.exists() for path in old) and mine.read_text() == "the user's own"
    assert not (tmp_path / "corridor").exists() and not (tmp_path / "active" / "tum").exists()  # emptied folders go too


def test_make_demo_replaces_the_previous_demo() -> None:
    makefile = (Path(__file__).parents[2] / "Makefile").read_text()
    assert "\t$(VENV)/bin/crowdloc demo --overwrite\n" in makefile  # a second make demo is no surprise


def test_the_world_tasks_part_plays_each_task_s_policies_and_its_shipped_policy_where_there_is_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """make demo's last part: each world task's paper policy and random_walk in the task's conditions, and the
    task's PPO policy beside them where models/ holds one (here an untrained one saved for the corridor)."""
    from stable_baselines3 import PPO

    import agents.demo_tasks as demo_tasks
    from agents.rl.config import load_train_config
    from agents.rl.train import make_task_env

    env = make_task_env(load_train_config("ppo_corridor_targets"), 0)
    corridor_model = tmp_path / "ppo_corridor_targets.zip"
    PPO("MultiInputPolicy", env, n_steps=16, batch_size=16, policy_kwargs={"net_arch": [8]}, seed=0, device="cpu").save(
        corridor_model
    )
    env.close()
    monkeypatch.setattr(demo_tasks, "shipped_model", lambda task: tmp_path / f"{task}.zip")
    section = demo_tasks.tasks_section(tmp_path / "tasks", seeds=1, workers=1, episode_steps=15)
    for task, paper_policy in demo_tasks.WORLD_TASKS.items():
        with open(tmp_path / "tasks" / task / "summary.csv") as f:
            policies = [row["policy"] for row in csv.DictReader(f)]
        has_model = task == "ppo_corridor_targets"
        assert policies[:2] == [paper_policy, "random_walk"] and len(policies) == 2 + has_model, task
        assert f"### `{task}`" in section
        assert (f"No trained policy at `models/{task}.zip`" in section) is not has_model
    assert "goal not reached" in section and "time to goal" in section  # the corridor and the campus have a goal
    assert all(f"tasks/{task}/summary.csv" in demo_tasks.TASK_OUTPUTS for task in demo_tasks.WORLD_TASKS)
