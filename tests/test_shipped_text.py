"""The repository describes what crowdloc is, never how it got there: no working-session labels,
no issue numbers, no commit hashes and no before/after history in the shipped text (README,
docs/, models/, configs/), in the source (docstrings, comments, what the programs print or write)
or in the tests. CHANGELOG.md keeps the history; git keeps the rest."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the file that keeps the history, and this file (it holds the patterns)
EXEMPT = {"CHANGELOG.md", "tests/test_shipped_text.py"}
SUFFIXES = (".py", ".md", ".yaml", ".yml", ".toml", ".txt", ".cfg", ".sh", ".csv", ".json")
NAMES = ("Makefile", "run")

#: what history looks like in prose, each with what to write instead
PATTERNS: dict[str, tuple[re.Pattern[str], str]] = {
    # pytest's fixture scope "session" is not a working session
    "session": (re.compile(r"\bsessions?\b(?![\"'])", re.IGNORECASE), "say what is, not when it was done"),
    "issue number": (
        # a league table's rank "(#2)" is not a ticket
        re.compile(r"\bissues?\s*#?\d+|(?<![\w&/#(])#\d{1,4}\b(?![\w-])", re.IGNORECASE),
        "name the behaviour, not the ticket",
    ),
    "commit hash": (
        # 7-12 hex digits with a digit and a letter, not a float's mantissa (1.5e-3) nor a digest
        re.compile(r"(?<![\w.])(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,12}(?![\w-])(?<!e)"),
        "name the behaviour or the file, not the commit",
    ),
    "before/after": (
        re.compile(
            r"\b(used to be|previously|went from \S+ to|since the fix|before the fix|after the fix|"
            r"was changed|were changed|no longer|the old (?:code|version|behaviou?r)|as before)\b",
            re.IGNORECASE,
        ),
        "state the present fact",
    ),
}


def _tracked_text_files() -> list[str]:
    """The repository's files (tracked and untracked-but-not-ignored) that hold text."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT, capture_output=True, text=True, check=True,
    ).stdout.splitlines()  # fmt: skip
    return sorted(
        name for name in listed if name not in EXEMPT and (name.endswith(SUFFIXES) or Path(name).name in NAMES)
        and (ROOT / name).is_file()
    )  # fmt: skip


def hits(text: str, pattern: re.Pattern[str]) -> list[tuple[int, str]]:
    """``(line number, line)`` of every line of ``text`` the pattern matches."""
    return [(number, line.strip()) for number, line in enumerate(text.splitlines(), 1) if pattern.search(line)]


@pytest.mark.parametrize("kind", sorted(PATTERNS))
def test_no_history_in_the_repository(kind: str) -> None:
    pattern, instead = PATTERNS[kind]
    found = [
        f"{name}:{number}: {line[:160]}"
        for name in _tracked_text_files()
        for number, line in hits((ROOT / name).read_text(errors="replace"), pattern)
    ]
    assert not found, f"{len(found)} lines with a {kind} ({instead}):\n" + "\n".join(found[:60])


@pytest.mark.parametrize(
    ("kind", "text", "found"),
    [
        ("session", "measured in session 38", True),
        ("session", "the study's storage", False),
        ("session", '@pytest.fixture(scope="session")', False),
        ("issue number", "the kidnap of issue 27", True),
        ("issue number", "see #12 for the reason", True),
        ("issue number", "colour #1f77b4 is not an issue", False),
        ("issue number", "| 0.31 [0.27, 0.35] (#6) |", False),
        ("commit hash", "re-run at 598c42d", True),
        ("commit hash", "a float 3.3329491539e-05 and a digest 6518ed5956c8a223", False),
        ("before/after", "its error went from 1.9 to 1.7 m", True),
        ("before/after", "the robot is pushed before the scan", False),
    ],
)
def test_the_patterns_find_history_and_leave_prose(kind: str, text: str, found: bool) -> None:
    assert bool(hits(text, PATTERNS[kind][0])) is found
