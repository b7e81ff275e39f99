"""The house's rules, held by tests: no import circle among the source modules (a package's
``__init__`` importing its own submodules is how a package presents them and is no circle), layers
that go one way (``core`` below ``localizers`` below ``envs`` below ``agents``: no import and no
string reference to a module runs up a layer; docs/architecture.md, "Layers"), no source file past
700 lines, and no file left with the marks of an unresolved merge."""

from __future__ import annotations

import ast
import os
import re
from pathlib import Path

import pytest

from tests.import_graph import ROOT, circles, import_graph, source_files

#: the longest a source file may be: past it, a file mixes two ideas
MAX_LINES = 700
#: the layers, lowest first: a module may import (or name in a string) its own layer and those below
LAYERS = ("core", "localizers", "envs", "agents")
#: a string that is a whole reference to a module of crowdloc, ``pkg.module`` or ``pkg.module:name``
_REFERENCE = re.compile(r"(core|localizers|envs|agents)(\.\w+)*(:\w+)?")


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


def _layer(module: str) -> int:
    return LAYERS.index(module.split(".")[0])


def test_no_import_runs_up_a_layer() -> None:
    graph = import_graph()
    up = sorted(f"{m} -> {t}" for m, targets in graph.items() for t in targets if _layer(t) > _layer(m))
    assert not up, "imports that run up a layer (core < localizers < envs < agents):\n" + "\n".join(up)


def test_the_worlds_meet_the_localizers_only_in_the_wrapper() -> None:
    """A world simulates and senses on the foundation alone; only the wrapper that runs a
    localizer inside the env loop (envs.wrappers) imports localizers."""
    graph = import_graph()
    crossing = sorted(f"{m} -> {t}" for m, targets in graph.items() if m.startswith("envs") and m != "envs.wrappers"
                      for t in targets if t.split(".")[0] == "localizers")  # fmt: skip
    assert not crossing, crossing


def string_references(path: Path) -> list[tuple[int, str]]:
    """``(line, text)`` of every string constant in ``path`` that is wholly a module reference
    (an entry point, a hook, a registry's module): :data:`_REFERENCE`."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and _REFERENCE.fullmatch(node.value):
            found.append((node.lineno, node.value))
    return found


def test_no_string_reference_runs_up_a_layer() -> None:
    up = []
    for module, path in source_files().items():
        for line, text in string_references(path):
            if "." in text or ":" in text:  # a bare package name ("envs") is a word, not a reference
                if _layer(text) > _layer(module):
                    up.append(f"{path.relative_to(ROOT)}:{line}: {text!r}")
    assert not up, "string references that run up a layer:\n" + "\n".join(up)


def test_the_reference_finder_finds_hooks_and_entry_points(tmp_path: Path) -> None:
    path = tmp_path / "m.py"
    path.write_text('"""Docs naming agents.rl.tasks in a sentence."""\nA = "agents.rl.tasks:make_task"\nB = {"m": "envs.world"}\n'
                    'C = "see agents.cli"\n')  # fmt: skip
    assert string_references(path) == [(2, "agents.rl.tasks:make_task"), (3, "envs.world")]


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
