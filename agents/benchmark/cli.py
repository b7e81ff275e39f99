"""``crowdloc benchmark`` from parsed options (the parser lives in :mod:`agents.cli`)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from agents.benchmark.journal import JOURNAL_NAME, ScoreJournal
from agents.benchmark.protocol import DEFAULT_PROTOCOL, load_protocol
from agents.benchmark.results import BENCHMARK_OUTPUTS, write_results
from agents.benchmark.run import BenchmarkPlan, EpisodeScore, load_plugins, plan_benchmark, score_task
from agents.common.output_folder import open_output_folder
from agents.common.sweep import run_tasks
from core.schema import check

#: what the policy track writes under --out
POLICY_TRACK_OUTPUTS = ("policy_leaderboard.md", "*/episodes.csv", "*/summary.csv", "*/summary.md", "*/run.json",
                        "*/verdict.md", "*/verdict.csv", "*/plots/*.png", "*/tum/*.tum")  # fmt: skip


def run_policy_track_cli(args: Any) -> Path:
    """``crowdloc benchmark --track policies``: the track's tasks, their entrants and ``--policies`` on top,
    every spec checked and ``--out`` made ready before any episode runs.

    Raises:
        ConfigError: options of the localizer track (``--worlds``, ``--localizers``, ``--resume``), an unknown
            task, an entrant a task cannot run, or an ``--out`` that is not empty (without ``--overwrite``).
    """
    from agents.benchmark.policy_track import DEFAULT_TRACK, load_policy_track, run_policy_track, track_specs

    for flag in ("worlds", "localizers"):
        check(getattr(args, flag, None) is None, f"--{flag} belongs to the localizer track; the policy track runs --tasks")
    check(not getattr(args, "resume", False), "--track policies does not resume: run it again with --overwrite")
    load_plugins(tuple(args.plugins or ()))
    track = load_policy_track(args.protocol or DEFAULT_TRACK)
    specs = track_specs(track, args.tasks, args.policies or (), seeds=args.seeds, quick=args.quick)
    out = Path(args.out)
    with open_output_folder(
        out, POLICY_TRACK_OUTPUTS, command="crowdloc benchmark --track policies", overwrite=bool(args.overwrite)
    ):
        start = time.perf_counter()
        written = run_policy_track(track, specs, out, quick=args.quick, workers=args.workers, progress=not args.no_progress,
                                   ray_address=getattr(args, "ray_address", None))  # fmt: skip
    print(written["leaderboard"].read_text())
    quick = " (quick: not comparable with a full run)" if args.quick else ""
    print(f"{track.name}{quick}: {time.perf_counter() - start:.0f} s; wrote {out}/ (policy_leaderboard.md, one folder per task)")
    return Path(written["leaderboard"])


def run_cli(args: Any) -> BenchmarkPlan | Path:
    """Import the plug-ins, read the protocol, plan, check ``--out``, run every episode (each into
    the journal as it finishes; with ``--resume`` only those the journal lacks), write.

    Raises:
        ConfigError: an unimportable plug-in, a bad protocol, an unknown world, localizer or
            policy, a bad seed count, an ``--out`` that is not empty (without ``--overwrite`` or
            ``--resume``), or a journal of another run, all before any episode runs.
    """
    if getattr(args, "track", "localizers") == "policies":
        return run_policy_track_cli(args)
    check(getattr(args, "tasks", None) is None, "--tasks belongs to the policy track (--track policies)")
    plugins = tuple(args.plugins or ())
    load_plugins(plugins)
    protocol = load_protocol(args.protocol or DEFAULT_PROTOCOL)
    plan = plan_benchmark(protocol, worlds=args.worlds, localizers=args.localizers, policies=args.policies,
                          seeds=args.seeds, quick=args.quick, plugins=plugins)  # fmt: skip
    resume, overwrite = bool(getattr(args, "resume", False)), bool(args.overwrite)
    check(not (resume and overwrite), "--resume continues a run and --overwrite starts it again: give one")
    out = Path(args.out)
    with open_output_folder(out, BENCHMARK_OUTPUTS, command="crowdloc benchmark", overwrite=overwrite, resume=resume) as folder:
        journal_path = out / JOURNAL_NAME
        journal = ScoreJournal.resume(journal_path, plan) if resume else ScoreJournal.start(journal_path, plan)
        folder.record(journal_path)
        for line in plan.left_out:
            print(line)
        tasks = plan.tasks()
        # seed by seed (the plan's order within a seed), so that a run stopped early holds whole seeds
        order = {seed: i for i, seed in enumerate(plan.seeds)}
        todo = sorted((t for t in tasks if t.key not in journal.done), key=lambda t: order[t.cell.seed])
        if resume:
            print(f"--resume: {len(tasks) - len(todo)} of the {len(tasks)} episodes are in {journal_path}")
        start = time.perf_counter()
        ran = run_tasks(score_task, todo, workers=args.workers, ray_address=getattr(args, "ray_address", None),
                        desc="benchmark", progress=not args.no_progress, on_result=lambda _, score: journal.append(score))  # fmt: skip
        wall_s = time.perf_counter() - start
        by_key: dict[Any, EpisodeScore] = {**journal.done, **{t.key: score for t, score in zip(todo, ran)}}
        scores = [by_key[t.key] for t in tasks]  # the plan's order, however the episodes finished or runs were split
        written = write_results(out, plan, scores, wall_s)
    quick = " (quick: not comparable with a full run)" if plan.quick else ""
    print(f"{protocol.name}{quick}: {len(todo)} episodes in {wall_s:.0f} s ({len(tasks)} in all); wrote {out}/ "
          f"({', '.join(p.name for p in written.values())})")  # fmt: skip
    return plan
