"""The demo's active localization in the other worlds: each world task, briefly (``make demo``).

For each world task (:data:`WORLD_TASKS`: the training configs ``configs/experiments/NAME.yaml`` of
the room, the corridor and the campus) its fixed policy to beat (the world's paper policy; in the room,
where the paper's start was known, ``look_then_route``) and ``random_walk`` play a few test
seeds at the world's default crowd in the task's conditions, with the task's reward, as
``crowdloc eval --conditions NAME`` evaluates them; the task's shipped PPO policy
(``models/NAME.zip``) plays beside them where the checkout has one. The section gives, per task,
the return, the mean error, the failure share, the first fix (where the start is unknown), the
share that missed the goal and the time to it (where the world has a goal) and the collisions.

A few seeds show how each policy drives; they do not say which is better. The verdict is
``crowdloc eval --conditions NAME --verdict ppo:models/NAME.zip`` on 100 fresh seeds at the
world's default and largest crowd (docs/tasks.md, "The verdict on a trained policy").
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import crowdloc_models
from agents.evaluate.outputs import EVAL_OUTPUTS

if TYPE_CHECKING:
    from agents.evaluate import EvalResult

#: the world tasks and the fixed policy each is measured against
WORLD_TASKS = {
    "ppo_room_lidar": "look_then_route",  # turns twice (the start is unknown), then drives the task's square on the estimate
    "ppo_corridor_targets": "corridor_follower",  # the ceiling paper's stop-and-correct drive
    "ppo_campus_stereo": "route_follower",  # the stereo paper's route, pure pursuit on the estimate
}
#: the test seeds per task (2**31 + 0 ..): enough to show each policy drive, too few for a verdict
TASK_SEEDS = 2
#: what the section writes under the demo's folder (``crowdloc demo --overwrite`` deletes these only)
TASK_OUTPUTS = tuple(f"tasks/{name}/{pattern}" for name in WORLD_TASKS for pattern in EVAL_OUTPUTS)
#: the metrics of the section's tables, in order (a metric the task does not have is left out)
SHOWN = ("episode_return", "position_error_mean_m", "failure_rate", "first_fix_s", "goal_missed", "time_to_goal_s",
         "collisions")  # fmt: skip


def shipped_model(task: str) -> Path:
    """The shipped PPO policy of ``task`` (``models/<task>.zip``; it need not exist)."""
    return crowdloc_models.path(f"{task}.zip")


def tasks_section(out_dir: Path, seeds: int = TASK_SEEDS, workers: int | None = None, episode_steps: int | None = None) -> str:
    """Evaluate each world task's policies (module docstring) under ``out_dir/<task>/``; return the section.

    ``episode_steps``: the episodes' length (default: each task's training episode, ``ppo.n_steps``).
    """
    from agents.evaluate import evaluate, write_tables
    from agents.evaluate.spec import EvalSpec, task_conditions, world_of
    from agents.rl.config import load_train_config

    lines = [
        "## Active localization in the other worlds",
        "",
        f"Each world task in its training conditions and with its reward (`crowdloc eval --conditions NAME`), at its "
        f"world's default crowd on {seeds} test seed(s): the task's fixed policy to beat, `random_walk` and the task's shipped "
        "PPO policy where this checkout has one. Mean [95 % bootstrap CI] over the episodes; a few seeds show how a "
        "policy drives, not which is better: the verdict is `crowdloc eval --conditions NAME --verdict "
        "ppo:models/NAME.zip` on 100 seeds at the default and the largest crowd (docs/tasks.md).",
        "",
    ]
    for task, paper_policy in WORLD_TASKS.items():
        config = load_train_config(task)
        model = shipped_model(task)
        policies = (paper_policy, "random_walk", *((f"ppo:{model}",) if model.is_file() else ()))
        world = world_of(config.env_id, config.env_kwargs)
        crowd = world.crowd.count if world.crowd is not None else 0
        spec = EvalSpec(policies=policies, crowd_sizes=(crowd,), seeds=seeds,
                        episode_steps=episode_steps or config.ppo.n_steps, **task_conditions(config))  # fmt: skip
        result = evaluate(spec, workers=workers, progress=False)
        write_tables(result, out_dir / task)
        lines += [f"### `{task}` ({config.env_id}, {config.localizer})", "", *_table(result), ""]
        if not model.is_file():
            lines += [f"No trained policy at `models/{task}.zip`: the fixed policies alone.", ""]
    return "\n".join(lines) + "\n"


def _table(result: EvalResult) -> list[str]:
    from agents.evaluate.outputs import format_stat

    infos = {m.key: m for m in result.metrics}
    shown = [infos[key] for key in SHOWN if key in infos]
    head = ["policy", *[m.label for m in shown]]
    rows = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for row in result.summary:
        values = [format_stat(m, row.stats[m.key], row.episodes) for m in shown]
        rows.append("| " + " | ".join([result.spec.policy_label(row.policy), *values]) + " |")
    return rows
