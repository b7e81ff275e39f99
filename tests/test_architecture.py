"""The house's rules, held by tests: no import circle among the source modules (a package's
``__init__`` importing its own submodules is how a package presents them and is no circle), no
source file past 700 lines, ``localizers`` never importing ``envs`` (docs/architecture.md, "Layers"),
and no file left with the marks of an unresolved merge."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.import_graph import ROOT, circles, import_graph, source_files

#: the longest a source file may be: past it, a file mixes two ideas (issue 28)
MAX_LINES = 700


def test_the_source_modules_import_no_circle() -> None:
    graph = import_graph()
    found = circles(graph)
    described = [" ; ".join(f"{a} -> {b}" for a in c for b in sorted(graph[a]) if b in c) for c in found]
    assert not found, "import circles:\n" + "\n".join(described)


def test_the_circle_finder_finds_a_circle() -> None:
    graph = {"a.x": {"a.y"}, "a.y": {"b"}, "b": {"a.x"}, "c": {"c.d"}, "c.d": {"c"}, "e": set()}
    assert circles(graph) == [["a.x", "a.y", "b"]]  # a package with its submodule is no circle


@pytest.mark.parametrize("module", sorted(source_files()))
def test_no_source_file_passes_700_lines(module: str) -> None:
    lines = source_files()[module].read_text().count("\n")
    assert lines <= MAX_LINES, f"{module} has {lines} lines: split it along its seam (docs/architecture.md)"


def test_localizers_never_import_envs() -> None:
    graph = import_graph()
    crossing = sorted(f"{m} -> {t}" for m, targets in graph.items() if m.startswith("localizers") for t in targets
                      if t == "envs" or t.startswith("envs."))  # fmt: skip
    assert not crossing, crossing


def test_no_file_holds_the_marks_of_an_unresolved_merge() -> None:
    suffixes = (".py", ".md", ".yaml", ".toml", ".txt", ".cfg")
    skipped = {".venv", ".git", "results", "build", "dist", "__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache"}
    marked = []
    for folder, subfolders, names in os.walk(ROOT):
        subfolders[:] = [d for d in subfolders if d not in skipped and not d.endswith(".egg-info")]
        for name in names:
            if not name.endswith(suffixes):
                continue
            path = Path(folder, name)
            for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
                if line.startswith(("<<<<<<< ", ">>>>>>> ")):
                    marked.append(f"{path.relative_to(ROOT)}:{number}")
    assert not marked, f"merge conflict marks left in: {marked}"
