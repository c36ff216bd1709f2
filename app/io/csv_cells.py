"""Every CSV the program writes goes through here (issue 33 point 6): a cell that a spreadsheet
would run as a formula (text starting with =, +, -, @, a tab or a carriage return: a customer
or DUT name typed as `=HYPERLINK(...)`) is written with a leading apostrophe, which makes it
text; numbers (-0.5, +3, 1e-3) stay numbers.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable, Sequence

FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def _is_number(text: str) -> bool:
    try:
        value = float(text)
    except ValueError:
        return False
    return math.isfinite(value) or text.strip().lower() in ("nan", "inf", "-inf", "+inf")


def safe_cell(value: object) -> str:
    """The cell's text, with an apostrophe before it when a spreadsheet would take it for a
    formula (a number is never one)."""
    text = "" if value is None else str(value)
    if text.startswith(FORMULA_START) and not _is_number(text):
        return "'" + text
    return text


def csv_text(rows: Iterable[Sequence[object]]) -> str:
    """The rows as CSV text (\\n line ends), every cell through `safe_cell`."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    for row in rows:
        writer.writerow([safe_cell(cell) for cell in row])
    return out.getvalue()


def neutralised(text: str) -> str:
    """CSV text made by another writer (dsp's results table) with its cells made safe."""
    return csv_text(csv.reader(io.StringIO(text)))
