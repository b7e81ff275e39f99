"""Re-run the ceiling-target paper's experiments (Fukaya et al., docs/papers.md section C).

- Tables 2-4 (:mod:`.static`): the robot placed under a target at set rotations and offsets,
  measured from rendered images, in two camera/calibration conditions;
- Tables 5-6 (:mod:`.drive`): the 20.8 m drive by the corridor_follower, without and with
  correction at the targets;
- beyond the paper: the drive among crowds, illumination (HSV against RGB thresholds, under a
  colourless light's gains and under the light's colour and glare, the camera's options),
  measuring without stopping, and how far apart targets may be.

``crowdloc reproduce ceiling-target`` calls :func:`add_arguments` and :func:`run`; the
thresholds it uses are the shipped ones (``crowdloc fit ceiling_target`` re-learns them).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from agents.common.util import positive_int
from agents.papers import add_worker_arguments

DEFAULT_SEEDS = 10
QUICK_SEEDS = 2
#: training images of the thresholds fitted under each light of the illumination study in a --quick run (a full
#: run: crowdloc fit's default, 160); few enough for a smoke run, so the rarer colours' boxes come out narrow
QUICK_FIT_IMAGES = 40
DENSITIES = (0, 10, 20)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The experiment's own options."""
    parser.add_argument(
        "--seeds", type=positive_int, default=DEFAULT_SEEDS, help=f"seeds per setting and drive (default {DEFAULT_SEEDS})"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"smoke run: {QUICK_SEEDS} seeds, crowd 0 and {DENSITIES[1]} only, {QUICK_FIT_IMAGES} images per light's fit",
    )
    add_worker_arguments(parser, "worker processes for the drives")


def run(args: argparse.Namespace) -> Path:
    """Run every part and write report.md, results.json and the figures into ``args.out``."""
    from .report import run_and_report

    start = time.perf_counter()
    seeds = QUICK_SEEDS if args.quick else args.seeds
    densities = DENSITIES[:2] if args.quick else DENSITIES
    fit_images = {"fit_images": QUICK_FIT_IMAGES} if args.quick else {}
    return run_and_report(Path(args.out), seeds, densities, args.workers, bool(args.overwrite), start, **fit_images)
