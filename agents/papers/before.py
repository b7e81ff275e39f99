"""The previous release's figures, kept beside the new ones for one release.

When a change of the worlds moves a reproduction's numbers (issue 15 made the worlds as hard as
the papers' real ones), its report shows the figures of the release before the change next to
the new ones, so the effect of each change can be read. The figures live as data in
``agents/papers/<package>/before.json``, extracted from that release's ``results.json`` by::

    python -m agents.papers.before bearing-candidates OLD/results.json --release "c5b3ecc (before issue 15)"

Only the headline numbers are kept (each paper says which: :data:`EXTRACTORS`); the rest of the
old run is not needed to read the change.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable, Mapping
from importlib import import_module
from pathlib import Path
from typing import Any

from agents.common.util import text_table
from agents.papers import EXPERIMENTS

Extractor = Callable[[Mapping[str, Any]], dict[str, Any]]
FILE_NAME = "before.json"


def _bearing(results: Mapping[str, Any]) -> dict[str, Any]:
    """Tables 1-3: position and heading mean and sd per method row."""
    return {
        table: {r["key"]: {"label": r["label"], "pos_mm": r["pos_mm"], "head_deg": r["head_deg"]} for r in results[table]}
        for table in ("exp1", "exp2", "exp3")
    }


def _lidar(results: Mapping[str, Any]) -> dict[str, Any]:
    """Every configuration's mean error and failures per run against the truth, and the claims' verdicts."""
    stats = {key: {"mean_m": s["mean_m"], "failures": s["failures"]} for key, s in results["stats"].items()}
    return {"stats": stats, "verdicts": {v["id"]: v["verdict"] for v in results["verdicts"]}}


#: experiment name -> the extractor of its headline numbers
EXTRACTORS: dict[str, Extractor] = {"bearing-candidates": _bearing, "lidar-far-point": _lidar}


def path(experiment: str) -> Path:
    """Where an experiment's previous-release figures live (beside its package's modules)."""
    module = import_module(EXPERIMENTS[experiment][0])
    assert module.__file__ is not None
    return Path(module.__file__).parent / FILE_NAME


def load(experiment: str) -> dict[str, Any] | None:
    """The previous release's figures of ``experiment``, or None when none are kept."""
    p = path(experiment)
    return json.loads(p.read_text()) if p.is_file() else None


def write(experiment: str, results_path: Path, release: str) -> Path:
    """Extract ``results_path``'s headline numbers into the package's ``before.json``."""
    if experiment not in EXTRACTORS:
        raise SystemExit(f"no extractor for {experiment!r}; known: {', '.join(EXTRACTORS)}")
    results = json.loads(Path(results_path).read_text())
    if results.get("plan", {}).get("quick"):
        raise SystemExit(f"{results_path} is a --quick run; keep the figures of a full run")
    out = path(experiment)
    out.write_text(json.dumps({"release": release, **EXTRACTORS[experiment](results)}, indent=1) + "\n")
    return out


def change_table(first: str, columns: list[str], rows: list[tuple[str, list[str], list[str]]]) -> list[str]:
    """A markdown table: per row its label, then each column's previous-release value beside the new one."""
    header = [first] + [f"{c} {when}" for c in columns for when in ("before", "now")]
    body = [[label, *(cell for pair in zip(old, new) for cell in pair)] for label, old, new in rows]
    return text_table(header, body).splitlines()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m agents.papers.before", description=__doc__.split("\n")[0])
    parser.add_argument("experiment", choices=sorted(EXTRACTORS))
    parser.add_argument("results", type=Path, help="results.json of a full run of the previous release")
    parser.add_argument("--release", required=True, help="how the report names that release")
    args = parser.parse_args(argv)
    print(f"wrote {write(args.experiment, args.results, args.release)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
