"""Re-run the MCL experiment of the far-point paper (Fujii et al., docs/papers.md section B).

The room (``crowdloc/CrowdedRoom-v0``) with people queueing along the left and right walls;
our robot drives an open-loop square in the middle of the room for three laps at 0.15 m/s
and localizes every 0.5 m of travel. LIDAR MCL on the raw scan (``mcl_lidar``) is compared
with the same MCL on accumulated, far-point-extracted scans (``far_point_mcl``) while the
sampling parameter (Figs 7/8) and the hit sd (Figs 10/11) are swept; beyond the paper, a
crowd-size sweep and an AMCL-like measurement model. As in the paper, errors are measured
against a reference pose, MCL on a second LIDAR at 1.9 m above the crowd, and, beyond it,
against the simulator's true pose.

Modules: :mod:`.paper` (the paper's numbers), :mod:`.experiment` (our set-up, the
configurations, the plan, the square path), :mod:`.world` (what is read from the world and
the localizer configs), :mod:`.jobs` (the episodes and the replays, in workers),
:mod:`.analysis` (statistics and verdicts as data), :mod:`.figures` and :mod:`.report`.
``crowdloc reproduce lidar-far-point`` calls :func:`add_arguments` and :func:`run`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.common.util import positive_int
from agents.papers import add_worker_arguments

from .experiment import DEFAULT_SEEDS, QUICK_LAPS, QUICK_SAMPLINGS, QUICK_SEEDS


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The experiment's own options."""
    parser.add_argument("--seeds", type=positive_int, default=DEFAULT_SEEDS, help=f"seeds per point (default {DEFAULT_SEEDS})")
    quick = f"smoke run: {QUICK_SEEDS} seeds, {len(QUICK_SAMPLINGS)} values per sweep, {QUICK_LAPS} lap"
    parser.add_argument("--quick", action="store_true", help=quick)
    add_worker_arguments(parser, ray=True)


def run(args: argparse.Namespace) -> Path:
    """Record the episodes, replay every configuration, write figures and report.md into ``args.out``."""
    from .analysis import claim_verdicts, density_rows, reference_stats, run_facts, table_stats
    from .experiment import make_plan
    from .figures import make_figures
    from .jobs import extraction_timing, pass_identity, run_all
    from .report import Context, summary_text, write_report

    start = time.perf_counter()
    plan = make_plan(args)
    episodes, runs = run_all(plan, args.workers, getattr(args, "ray_address", None))
    identity = pass_identity(episodes, runs)
    out = Path(args.out)
    st, st_ref = table_stats(runs, "truth"), table_stats(runs, "reference")
    rows = density_rows(st, episodes, st_ref)
    figs = make_figures(out, plan, st, runs, episodes, rows, st_ref)
    wall = time.perf_counter() - start
    verdicts, verdicts_truth = claim_verdicts(plan, st_ref), claim_verdicts(plan, st)  # the paper's measure first
    report = write_report(out, Context(plan, episodes, runs, st, run_facts(episodes, runs), verdicts, rows, figs, wall,
                                       args.workers, identity, extraction_timing(episodes), st_ref, verdicts_truth,
                                       reference_stats(episodes)))  # fmt: skip
    print(summary_text(plan, st, verdicts, st_ref, verdicts_truth))
    print(f"{len(episodes)} episodes, {len(runs)} MCL runs in {wall:.1f} s with {args.workers} worker(s)")
    return report


__all__ = ["add_arguments", "run"]
