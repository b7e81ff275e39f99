"""Paper reproductions: ``crowdloc reproduce NAME`` runs one and writes ``results/NAME/report.md``.

Each experiment module exposes ``add_arguments(parser)`` (its own options) and
``run(args) -> pathlib.Path`` (the report it wrote).
"""

from __future__ import annotations

#: experiment name -> module implementing it
EXPERIMENTS: dict[str, str] = {
    "bearing-candidates": "agents.reproduce.bearing_candidates",
}
