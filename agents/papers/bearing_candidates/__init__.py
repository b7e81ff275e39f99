"""Re-run Exp 1-3 of the candidate-set paper (Motomura et al.) and write report.md with plots.

Exp 1: RoboCupStatic-v0, an open-loop closed polygon a-b-...-h-a; the proposed method uses
L6 and L7 only, the baselines all three landmarks. Exp 2: RoboCupCrowded-v0 with the
goalkeeper and a ball, our field robot chasing, dribbling and shooting, half of the visible
landmarks dropped at random per frame. Exp 3: Exp 2's recordings replayed into the proposed
method with K = 1, 5, 10 candidate sets. Beside the paper's rows of Tables 1-3, "(ours)" rows
run method (5) with an exponential forgetting of its accumulated Error (``jobs.OURS_PARAMS``,
not in the paper). Beyond the paper: error and availability against
crowd density and false-detection rate, and recovery after a shove. Every run is recorded
once and replayed into every localizer (agents.experiments.replay), one process per seed.

Modules: :mod:`.jobs` (the plan, the jobs, running them), :mod:`.analysis` (statistics as
data), :mod:`.conditions` (the set-up as the configs hold it), :mod:`.report` and
:mod:`.discussion` (report.md, results.json), :mod:`.figures`, :mod:`.paper` (the paper's
numbers). ``crowdloc reproduce bearing-candidates`` calls :func:`add_arguments` and :func:`run`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.common.util import positive_int
from agents.papers import add_worker_arguments
from agents.papers.bearing_candidates.jobs import (
    DEFAULT_PUSH_SEEDS,
    DEFAULT_SEEDS,
    DEFAULT_SWEEP_SEEDS,
    QUICK_DENSITIES,
    QUICK_SEEDS,
    make_jobs,
    make_plan,
    run_jobs,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The experiment's own options."""
    parser.add_argument("--seeds", type=positive_int, default=DEFAULT_SEEDS,
                        help=f"seeds of Exp 1 and Exp 2/3 (default {DEFAULT_SEEDS})")  # fmt: skip
    parser.add_argument("--sweep-seeds", type=positive_int, default=DEFAULT_SWEEP_SEEDS,
                        help=f"seeds per point of the density and false-detection sweeps (default {DEFAULT_SWEEP_SEEDS})")  # fmt: skip
    parser.add_argument("--push-seeds", type=positive_int, default=DEFAULT_PUSH_SEEDS,
                        help=f"seeds of the shove-recovery study (default {DEFAULT_PUSH_SEEDS})")  # fmt: skip
    parser.add_argument("--quick", action="store_true",
                        help=f"tiny smoke run: {QUICK_SEEDS} seeds, short episodes, {len(QUICK_DENSITIES)} sweep points")  # fmt: skip
    add_worker_arguments(parser, "worker processes over seeds")


def run(args: argparse.Namespace) -> Path:
    """Run every study, write the figures and report.md into ``args.out``; return the report path."""
    from agents.papers.bearing_candidates.analysis import analyze
    from agents.papers.bearing_candidates.conditions import conditions
    from agents.papers.bearing_candidates.figures import make_figures
    from agents.papers.bearing_candidates.report import summary_table, write_report

    start = time.perf_counter()
    plan = make_plan(args)
    jobs = make_jobs(plan)
    results = run_jobs(jobs, args.workers)
    analysis = analyze(results)
    out = Path(args.out)
    figures = make_figures(out, results, analysis)
    wall = time.perf_counter() - start
    report = write_report(out, analysis, conditions(jobs), plan, figures, wall, args.workers)
    print(summary_table(analysis))
    print(f"{len(jobs)} runs in {wall:.1f} s with {args.workers} worker(s)")
    return report


__all__ = ["add_arguments", "run"]
