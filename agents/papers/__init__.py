"""Paper reproductions: ``crowdloc reproduce NAME`` runs one and writes ``results/NAME/report.md``.

Each experiment module exposes ``add_arguments(parser)`` (its own options) and
``run(args) -> pathlib.Path`` (the report it wrote).

May import: ``envs``, ``localizers``, :mod:`agents.common`, :mod:`agents.policies`,
:mod:`agents.experiments`, :mod:`agents.rl`, :mod:`agents.evaluate`; never :mod:`agents.tune`,
:mod:`agents.cli`, :mod:`agents.demo`.
"""

from __future__ import annotations

import argparse
import os

from agents.common.util import positive_int

#: worker processes a reproduction runs by default: min(DEFAULT_WORKERS, cpu count)
DEFAULT_WORKERS = 2

#: experiment name -> (module implementing it, one-line summary for --help)
EXPERIMENTS: dict[str, tuple[str, str]] = {
    "bearing-candidates": (
        "agents.papers.bearing_candidates",
        "two-landmark candidate sets (Motomura et al.): Exp 1-3, Tables 1-3, beside the paper's numbers",
    ),
    "ceiling-target": (
        "agents.papers.ceiling_target",
        "ceiling colour targets (Fukaya et al.): Tables 2-6 beside the paper's numbers, and drives among crowds",
    ),
    "lidar-far-point": (
        "agents.papers.lidar_far_point",
        "LIDAR scan accumulation + far points (Fujii et al.): MCL with and without them vs sampling and hit (Figs 5, 7-11)",
    ),
    "stereo-far-landmarks": (
        "agents.papers.stereo_far_landmarks",
        "far landmarks first, stereo edges + particle filter (paper D): Figs 8-10 against the LIDAR reference, and crowds",
    ),
}


def add_worker_arguments(parser: argparse.ArgumentParser, what: str = "worker processes", ray: bool = False) -> None:
    """``--workers`` (default min(:data:`DEFAULT_WORKERS`, cpu count)), and with ``ray`` ``--ray-address``."""
    parser.add_argument("--workers", type=positive_int, default=min(DEFAULT_WORKERS, os.cpu_count() or 1),
                        help=f"{what} (default min({DEFAULT_WORKERS}, cpu count))")  # fmt: skip
    if ray:
        parser.add_argument("--ray-address", help="run the tasks on this Ray cluster instead (e.g. auto)")
