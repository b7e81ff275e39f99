"""Re-run the outdoor experiment of the far-landmark stereo paper (docs/papers.md section D).

The campus (``crowdloc/StereoCampus-v0``): per seed, run 1 drives the ~100 m route once and
makes the map of scenes (poses from the LIDAR reference, as the paper's came from amcl); run 2,
another crowd on the same route, is driven by ``route_follower`` on the LIDAR reference's
estimate, recorded once and replayed into ``far_landmark_pf`` (far emphasis, the paper's; no
emphasis; nearest first) and into the reference itself (which must reproduce the online
estimates). The paper's Fig. 10 (the distance to the reference over time), Figs 8-9 (the
trajectories near two places) and, beyond the paper, the errors against the truth and a sweep
of crowd sizes.

Modules: :mod:`.paper` (the paper's numbers), :mod:`.experiment` (our set-up and the plan),
:mod:`.world` (what is read from the world and the localizer configs), :mod:`.jobs` (maps, runs
and replays, in workers), :mod:`.analysis` (statistics and verdicts as data), :mod:`.figures`
and :mod:`.report`. ``crowdloc reproduce stereo-far-landmarks`` calls :func:`add_arguments` and :func:`run`.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.common.util import positive_int
from agents.papers import add_worker_arguments

from .experiment import DEFAULT_SEEDS, DENSITIES, QUICK_DENSITIES, QUICK_SEEDS, QUICK_STEPS, crowd_size


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The experiment's own options."""
    parser.add_argument("--seeds", type=positive_int, default=DEFAULT_SEEDS, help=f"seeds (default {DEFAULT_SEEDS})")
    sizes = " ".join(map(str, DENSITIES))
    parser.add_argument("--crowd-sizes", type=crowd_size, nargs="+", default=None, metavar="N",
                        help=f"crowd sizes of run 2 (default {sizes}; the world's own is always run)")  # fmt: skip
    quick = (f"smoke run: {QUICK_SEEDS} seeds, crowd sizes {' '.join(map(str, QUICK_DENSITIES))}, the drives cut after "
             f"{QUICK_STEPS} steps")  # fmt: skip
    parser.add_argument("--quick", action="store_true", help=quick)
    add_worker_arguments(parser, ray=True)


def run(args: argparse.Namespace) -> Path:
    """Make the maps, record and replay every run 2, write figures and report.md into ``args.out``."""
    from . import analysis, world
    from .experiment import make_plan
    from .figures import make_figures
    from .jobs import run_all
    from .report import Context, summary_text, write_report

    start = time.perf_counter()
    plan = make_plan(args)
    maps, episodes = run_all(plan, args.workers, getattr(args, "ray_address", None))
    out = Path(args.out)
    table = analysis.summary_table(episodes)
    pairs = analysis.paired_table(episodes)
    dets = analysis.detections(episodes)
    prof = analysis.profile(episodes, plan.crowd)
    weak = analysis.weak_spot(episodes, plan.crowd)
    verdicts = analysis.claim_verdicts(plan, table, pairs, weak, episodes)
    facts = analysis.facts(maps, episodes)
    figs = make_figures(out, plan, episodes, table, prof, int(world.camera().slots), analysis.sectors_in_view())
    wall = time.perf_counter() - start
    context = Context(plan, maps, episodes, table, pairs, dets, prof, weak, verdicts, facts, figs, wall, args.workers)
    report = write_report(out, context)
    print(summary_text(context))
    print(f"{len(maps)} maps, {len(episodes)} runs 2 in {wall:.1f} s with {args.workers} worker(s)")
    return report


__all__ = ["add_arguments", "run"]
