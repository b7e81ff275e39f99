"""Paper reproductions: ``crowdloc reproduce NAME`` runs one and writes ``results/NAME/report.md``.

Each experiment module exposes ``add_arguments(parser)`` (its own options) and
``run(args) -> pathlib.Path`` (the report it wrote).
"""

from __future__ import annotations

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
