"""agents.common.util.text_table: the console tables of the commands line up whatever their cells."""

from __future__ import annotations

import pytest

from agents.common.util import text_table
from tests.console import assert_aligned, printed_tables


def test_columns_line_up_left_and_right() -> None:
    text = text_table(["method", "error mm"], [["(1) dead reckoning", "182 ± 146"], ["(5) K=10 [paper]", "31 ± 22"]])
    (table,) = printed_tables(text)
    assert_aligned(table)
    assert table[0] == "| method             |  error mm |"
    assert table[2:] == ["| (1) dead reckoning | 182 ± 146 |", "| (5) K=10 [paper]   |   31 ± 22 |"]  # no markup read
    assert "\x1b" not in text  # no colour codes, even on a terminal


def test_a_table_is_as_wide_as_its_cells_not_the_terminal(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COLUMNS", "20")
    (table,) = printed_tables(text_table(["claim", "text"], [["C1", "a claim much longer than twenty columns"]], align="ll"))
    assert_aligned(table)
    assert table[2] == "| C1    | a claim much longer than twenty columns |"


def test_a_bad_shape_is_an_error_naming_it() -> None:
    with pytest.raises(ValueError, match=r"align must give l or r for each of the 2 columns, got 'lx'"):
        text_table(["a", "b"], [], align="lx")
    with pytest.raises(ValueError, match=r"needs 2 cells \(a, b\), got 1: \['x'\]"):
        text_table(["a", "b"], [["x"]])
