"""What the commands print: the aligned tables of agents.common.util.text_table, found in printed text."""

from __future__ import annotations


def printed_tables(printed: str) -> list[list[str]]:
    """The tables in ``printed``: each a run of consecutive lines that start with ``|``."""
    tables: list[list[str]] = []
    previous_was_row = False
    for line in printed.splitlines():
        row = line.startswith("|")
        if row and not previous_was_row:
            tables.append([])
        if row:
            tables[-1].append(line)
        previous_was_row = row
    return tables


def assert_aligned(table: list[str]) -> None:
    """Every line of ``table`` is as wide as the first and has its column separators at the same offsets."""
    offsets = [[i for i, ch in enumerate(line) if ch == "|"] for line in table]
    assert len(table) >= 3, f"a header, its rule and at least one row: {table}"
    assert all(len(line) == len(table[0]) for line in table), "\n".join(table)
    assert all(o == offsets[0] for o in offsets), "\n".join(table)
