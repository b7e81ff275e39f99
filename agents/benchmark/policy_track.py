"""The benchmark's policy track: policies ranked on each task's unseen layouts.

A track file (``configs/policy_tracks/v1.yaml``) names tasks on seeded layouts (training
configs with ``layouts``), and per task its crowd sizes, episode length, the fixed policies that
drive it and the shipped models trained on it. :func:`run_policy_track` evaluates them all on the
task's test layouts (:class:`agents.evaluate.EvalSpec` with the config's conditions and its
``layouts.test``: every entrant of a seed meets the same layout and crowd), beside any entrant a
user adds (``ppo:PATH.zip`` trained on the task, or a registered plug-in policy), and ranks them
per task and crowd by the mean episode return (the task's own objective), with the error, the
failure share, the goal reached and the collisions beside it (95 % bootstrap intervals). Each
task's episodes are kept as ``crowdloc eval`` writes them, under ``<out>/<task>/``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import crowdloc_configs
import crowdloc_models
from agents.evaluate.spec import PPO_PREFIX, EvalSpec, task_conditions
from agents.evaluate.stats import EvalResult, SummaryRow, evaluate
from agents.rl.config import load_train_config
from core.schema import ConfigError, check, from_mapping, load_yaml

TRACK_DIR = crowdloc_configs.path("policy_tracks")
#: the shipped track ``crowdloc benchmark --track policies`` runs by default
DEFAULT_TRACK = "v1"
#: the columns of the leaderboard: (metric key, header, format); the first ranks
COLUMNS = (
    ("episode_return", "return", "{:.1f}"),
    ("position_error_mean_m", "error [m]", "{:.3f}"),
    ("failure_rate", "failure share", "{:.3f}"),
    ("goal_missed", "goal missed", "{:.2f}"),
    ("collisions", "collisions", "{:.1f}"),
)


@dataclass(frozen=True)
class TrackTask:
    """One task of the track (its training config's name is the key)."""

    crowd_sizes: tuple[int, ...]
    episode_steps: int
    policies: tuple[str, ...]
    models: tuple[str, ...] = ()


@dataclass(frozen=True)
class TrackSeeds:
    first_seed: int = 0
    count: int = 100


@dataclass(frozen=True)
class TrackQuick:
    seeds: int = 2
    episode_steps: int = 60


@dataclass(frozen=True)
class PolicyTrack:
    """A policy track file (module docstring)."""

    name: str
    description: str
    tasks: dict[str, TrackTask]
    seeds: TrackSeeds = field(default_factory=TrackSeeds)
    quick: TrackQuick = field(default_factory=TrackQuick)


def load_policy_track(name_or_path: str | Path = DEFAULT_TRACK) -> PolicyTrack:
    """A shipped track by name (``v1``, a file of ``configs/policy_tracks/``) or a track YAML path, checked.

    Raises:
        ConfigError: a missing or malformed file (naming the shipped tracks), or a task whose config has no ``layouts``.
    """
    path = Path(name_or_path)
    if not path.suffix:
        path = TRACK_DIR / f"{name_or_path}.yaml"
    if not path.is_file():
        shipped = ", ".join(crowdloc_configs.names("policy_tracks"))
        raise ConfigError(f"policy track {str(name_or_path)!r}: no such file ({path}); shipped: {shipped}")
    track = from_mapping(PolicyTrack, load_yaml(path), str(path))
    for name in track.tasks:
        check(load_train_config(name).layouts is not None,
              f"{path}: task {name!r} has no layouts: the policy track ranks policies on unseen layouts")  # fmt: skip
    return track


def model_path(name: str) -> Path:
    """A shipped model's file (``models/<name>.zip``; it need not exist)."""
    return crowdloc_models.path(f"{name}.zip")


def shipped_model(track: PolicyTrack, task: str, spec: EvalSpec) -> str | None:
    """The policy of ``spec`` that is ``task``'s first shipped model (``ppo:models/<name>.zip``), or None when
    none of its models is shipped."""
    names = [f"{PPO_PREFIX}{model_path(m)}" for m in track.tasks[task].models]
    return next((p for p in spec.policies if p in names), None)


def task_spec(track: PolicyTrack, task: str, entrants: Sequence[str] = (), *, seeds: int | None = None,
              quick: bool = False) -> EvalSpec:  # fmt: skip
    """The evaluation of one task of the track: its fixed policies, its shipped models (those present), then
    ``entrants``, on its test layouts.

    Raises:
        ConfigError: an unknown task, a bad seed count, or an entrant the task cannot run (a model
            trained on other observations, an unknown policy), from :class:`EvalSpec`'s checks.
    """
    if task not in track.tasks:
        raise ConfigError(f"unknown task {task!r} of the policy track {track.name} (tasks: {', '.join(track.tasks)})")
    entry = track.tasks[task]
    config = load_train_config(task)
    assert config.layouts is not None  # load_policy_track checked it
    models = [f"{PPO_PREFIX}{model_path(m)}" for m in entry.models if model_path(m).is_file()]
    policies = list(dict.fromkeys([*entry.policies, *models, *entrants]))
    count = track.quick.seeds if quick else track.seeds.count
    if seeds is not None:
        check(isinstance(seeds, int) and 1 <= seeds <= count, f"--seeds must be from 1 to {count}, got {seeds!r}")
        count = seeds
    return EvalSpec(**task_conditions(config), policies=tuple(policies), crowd_sizes=entry.crowd_sizes, seeds=count,
                    first_seed=track.seeds.first_seed, episode_steps=track.quick.episode_steps if quick else entry.episode_steps,
                    layouts=config.layouts.test)  # fmt: skip


def ranking(result: EvalResult) -> list[tuple[int, list[SummaryRow]]]:
    """Per crowd size, the summary rows by mean return, highest first (ties: the listed order)."""
    by_crowd: dict[int, list[SummaryRow]] = {}
    for row in result.summary:
        by_crowd.setdefault(row.crowd_size, []).append(row)

    def key(row: SummaryRow) -> float:
        mean = row.stats["episode_return"].mean
        return -mean if math.isfinite(mean) else math.inf

    return [(crowd, sorted(rows, key=key)) for crowd, rows in by_crowd.items()]


def _cell(row: SummaryRow, metric: str, fmt: str) -> str:
    stat = row.stats.get(metric)
    if stat is None or not math.isfinite(stat.mean):
        return "-"
    return f"{fmt.format(stat.mean)} [{fmt.format(stat.low)}, {fmt.format(stat.high)}]"


def leaderboard_markdown(track: PolicyTrack, results: dict[str, EvalResult], quick: bool) -> str:
    """The track's tables: one per task and crowd size, ranked by return."""
    lines = [f"# {track.name}" + (" (quick: not comparable with a full run)" if quick else ""), "", track.description, ""]
    for task, result in results.items():
        spec = result.spec
        first, end = spec.layouts or (0, 0)
        lines += [f"## {task}", "",
                  f"{spec.env_id}, localizer {', '.join(spec.localizers)}; {spec.seeds} seeds per crowd, each on a test "
                  f"layout of [{first}, {end}) it draws; {spec.episode_steps} steps at most; ranked by mean return "
                  "(95 % bootstrap intervals).", ""]  # fmt: skip
        for crowd, rows in ranking(result):
            lines += [f"### crowd {crowd}", "", "| rank | policy | " + " | ".join(h for _, h, _ in COLUMNS) + " |",
                      "|---:|---|" + "---|" * len(COLUMNS)]  # fmt: skip
            for rank, row in enumerate(rows, 1):
                label = spec.policy_label(row.policy)
                lines.append(f"| {rank} | {label} | " + " | ".join(_cell(row, m, f) for m, _, f in COLUMNS) + " |")
            lines.append("")
    return "\n".join(lines)


def track_specs(track: PolicyTrack, tasks: Sequence[str] | None = None, entrants: Sequence[str] = (), *,
                seeds: int | None = None, quick: bool = False) -> dict[str, EvalSpec]:  # fmt: skip
    """:func:`task_spec` of each task (all of the track's by default): every entrant checked before any episode."""
    return {name: task_spec(track, name, entrants, seeds=seeds, quick=quick) for name in tasks or track.tasks}


def run_policy_track(
    track: PolicyTrack, specs: dict[str, EvalSpec], out: Path, *, quick: bool = False, workers: int | None = None,
    progress: bool = True, ray_address: str | None = None,
) -> dict[str, Any]:  # fmt: skip
    """Evaluate each task's spec (:func:`track_specs`) and write ``policy_leaderboard.md`` and each task's
    ``crowdloc eval`` outputs under ``out/<task>/``, with the paired verdict on the task's shipped model
    against its best fixed policy (``verdict.md``, ``verdict.csv``; :func:`shipped_model`) where it has one;
    returns the written paths and the results."""
    from agents.evaluate.outputs import write_outputs
    from agents.evaluate.paired import paired_verdict, write_verdict

    results = {}
    written: dict[str, Any] = {}
    for name, spec in specs.items():
        results[name] = evaluate(spec, workers=workers, ray_address=ray_address, progress=progress)
        written[name] = write_outputs(results[name], out / name, gif=False)
        shipped = shipped_model(track, name, spec)
        if shipped is not None:
            written[name].update(write_verdict(paired_verdict(results[name], shipped), spec, out / name))
    board = out / "policy_leaderboard.md"
    board.write_text(leaderboard_markdown(track, results, quick) + "\n")
    return {"leaderboard": board, "tasks": written, "results": results}
