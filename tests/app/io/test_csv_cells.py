"""app.io.csv_cells: the one helper every CSV the program writes goes through (issue 33)."""

from __future__ import annotations

import csv
import io

import pytest

from app.io.csv_cells import csv_text, neutralised, safe_cell


@pytest.mark.parametrize(
    "text",
    ["=1+1", "+A1", "-2+3", "@SUM(A1)", "\tx", "\rx", '=HYPERLINK("http://x","y")', "-cmd|' /C"],
)
def test_a_formula_like_cell_becomes_text(text: str) -> None:
    assert safe_cell(text) == "'" + text


@pytest.mark.parametrize("value", ["-0.5", "+3", "1e-3", "-1.5E3", "nan", "-inf", "ACME", "", 4.5])
def test_numbers_and_plain_text_are_kept(value: object) -> None:
    assert safe_cell(value) == str(value)


def test_a_whole_table_made_elsewhere_is_made_safe() -> None:
    text = "name,value\n=cmd,-0.25\nok,+1\n"
    rows = list(csv.reader(io.StringIO(neutralised(text))))
    assert rows == [["name", "value"], ["'=cmd", "-0.25"], ["ok", "+1"]]
    assert csv_text([["@x", None]]) == "'@x,\n"
