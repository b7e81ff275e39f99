"""Small helpers shared by the command-line tools: argparse types, dotted overrides, JSON conversion,
console tables."""

from __future__ import annotations

import argparse
import importlib.metadata
import json
import math
import os
import platform
import subprocess
import sys
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from core.schema import ConfigError


def _argument_type(convert: Callable[[str], Any], accept: Callable[[Any], bool], what: str) -> Callable[[str], Any]:
    """An argparse type: ``convert`` the text and keep it when ``accept`` holds, else a one-line
    error ``expected WHAT, got TEXT`` naming the bad text (or the converted value)."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not accept(value):
            raise argparse.ArgumentTypeError(f"expected {what}, got {value}")
        return value

    return parse


#: argparse type: an integer >= 1
positive_int: Callable[[str], int] = _argument_type(int, lambda v: v > 0, "a positive integer")
#: argparse type: a seed, an integer >= 0 (what numpy and Gymnasium accept)
seed_int: Callable[[str], int] = _argument_type(int, lambda v: v >= 0, "a seed (an integer >= 0)")
#: argparse type: a finite number > 0
positive_float: Callable[[str], float] = _argument_type(float, lambda v: math.isfinite(v) and v > 0, "a finite number > 0")


def at_least(minimum: int) -> Callable[[str], int]:
    """argparse type: an integer >= ``minimum``, with a one-line error naming the bad text."""
    parse: Callable[[str], int] = _argument_type(int, lambda v: v >= minimum, f"an integer >= {minimum}")
    return parse


def nest(dotted: Mapping[str, Any]) -> dict[str, Any]:
    """``{"ppo.learning_rate": 1e-3, "n": 1}`` -> ``{"ppo": {"learning_rate": 1e-3}, "n": 1}``.

    Raises:
        ConfigError: when one key is both a value and a section (``a=1`` and ``a.b=2``).
    """
    out: dict[str, Any] = {}
    for key, value in dotted.items():
        *parents, leaf = key.split(".")
        node = out
        for part in parents:
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ConfigError(f"override {key!r} conflicts with another override")
        if isinstance(node.get(leaf), dict):
            raise ConfigError(f"override {key!r} conflicts with another override")
        node[leaf] = value
    return out


def flatten(nested: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """The inverse of :func:`nest`: ``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out: dict[str, Any] = {}
    for key, value in nested.items():
        if isinstance(value, Mapping):
            out.update(flatten(value, f"{prefix}{key}."))
        else:
            out[f"{prefix}{key}"] = value
    return out


def jsonable(o: Any) -> Any:
    """Plain JSON values: mappings and sequences recursively, arrays to lists, numpy scalars
    to Python ones, non-finite floats to None, anything else to its ``str``."""
    if isinstance(o, Mapping):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, np.ndarray):
        return jsonable(o.tolist())
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, (np.integer, np.bool_)):
        return o.item()
    if isinstance(o, (int, bool, str)) or o is None:
        return o
    return str(o)


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """``rows`` under ``header`` as the lines of a markdown table (the first column left-aligned, the others right)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join([":---"] + ["---:"] * (len(header) - 1)) + "|"]
    for row in rows:
        if len(row) != len(header):
            raise ValueError(f"markdown_table: a row has {len(row)} cells for {len(header)} columns: {list(row)!r}")
        lines.append("| " + " | ".join(row) + " |")
    return lines


def refuse_to_overwrite(report: Path, overwrite: bool) -> None:
    """Raise :class:`ConfigError` when ``report`` exists and the user did not ask to replace it
    (``--overwrite``): a command never overwrites a user's results unasked."""
    if report.exists() and not overwrite:
        raise ConfigError(f"{report} exists; give --overwrite to replace it (or another --out)")


def check_output_file(path: Path, overwrite: bool, flag: str = "--out") -> Path:
    """Make ready to write the file ``path``, before any work: refused when a folder is in its
    place, or when it exists and the user did not ask to replace it (``overwrite``); its folder is
    created and must be writable (:func:`make_out_dir`).

    Raises:
        ConfigError: naming ``flag`` and ``path``.
    """
    if path.is_dir():
        raise ConfigError(f"{flag} {path} is a folder; give the path of the file to write")
    if path.exists() and not overwrite:
        raise ConfigError(f"{flag} {path} exists; give --overwrite to replace it (or another {flag})")
    make_out_dir(path.parent, flag=f"{flag} {path}: its folder")
    return path


def make_out_dir(out: Path, flag: str = "--out") -> Path:
    """Create the output folder ``out`` (and its parents) and check that it is writable, before any
    work: a run that cannot save its results must fail at its start, not after its last episode.

    Raises:
        ConfigError: naming ``flag`` and ``out`` when it is a file, or cannot be created or written.
    """
    if out.exists() and not out.is_dir():
        raise ConfigError(f"{flag} {out} is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"{flag} {out}: cannot create the output folder ({exc.strerror or exc})") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ConfigError(f"{flag} {out}: the output folder is not writable")
    return out


def text_table(header: Sequence[str], rows: Iterable[Sequence[str]], align: str | None = None) -> str:
    """``rows`` under ``header`` as an aligned plain-text table for the console: rich's markdown
    form, without colour or markup, each column as wide as its widest cell, whatever the terminal's
    width. ``align``: one letter per column, ``l`` (left) or ``r`` (right); by default the first
    column left and the others right (a label, then numbers)."""
    import io

    from rich import box
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    align = align if align is not None else "l" + "r" * (len(header) - 1)
    if len(align) != len(header) or set(align) - {"l", "r"}:
        raise ValueError(f"align must give l or r for each of the {len(header)} columns, got {align!r}")
    table = Table(box=box.MARKDOWN, header_style="", show_edge=True)
    for name, side in zip(header, align):
        table.add_column(Text(name), justify="left" if side == "l" else "right", no_wrap=True)
    for row in rows:
        if len(row) != len(header):
            raise ValueError(f"a table row needs {len(header)} cells ({', '.join(header)}), got {len(row)}: {list(row)}")
        table.add_row(*(Text(cell) for cell in row))
    buffer = io.StringIO()
    Console(file=buffer, width=100_000, color_system=None, no_color=True, highlight=False).print(table)
    return "\n".join(line.rstrip() for line in buffer.getvalue().splitlines() if line.strip())


_RECORDED_PACKAGES = ("crowdloc", "gymnasium", "numpy", "pymunk", "stable-baselines3", "torch")


def write_run_record(path: Path, **fields: Any) -> Path:
    """Write ``run.json``: ``fields`` (a config, seeds, conditions) plus the command line, the
    package versions and the git commit of the code (None outside a git checkout)."""
    record = {
        **{key: jsonable(value) for key, value in fields.items()},
        "command": list(sys.argv),
        "versions": {"python": platform.python_version(), **{n.replace("-", "_"): _version(n) for n in _RECORDED_PACKAGES}},
        "git_commit": _git_commit(),
    }
    path.write_text(json.dumps(record, indent=2) + "\n")
    return path


def _version(package: str) -> str | None:
    try:
        return importlib.metadata.version(package)
    except importlib.metadata.PackageNotFoundError:
        return None


def _git_commit() -> str | None:
    """The commit of the checkout this code runs from, or None (an installed wheel, no git)."""
    try:
        done = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parent, capture_output=True, text=True, timeout=5
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None
