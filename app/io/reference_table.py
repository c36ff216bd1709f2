"""The CSV calibration table of a reference standard, read one way for every command that takes
one (`refs add --table`, the GUI's reference dialog, `impact --table`): one row per line
`frequency_hz, sensitivity_mv_per_ms2, relative_expanded_uncertainty_percent[, phase_deg]` (Hz,
mV/(m/s^2), percent: 0.5 means 0.5 %, degrees), returned with the uncertainty as a fraction.
A header is optional; a header whose uncertainty column does not say percent is refused by
name, as is a bad cell by its line (issue 33 point 6: `impact` read the column as a fraction).
"""

from __future__ import annotations

import csv
import io
import math
from decimal import Decimal, InvalidOperation
from pathlib import Path

from app.errors import Refusal

TableRow = tuple[float, float, float, float | None]  # Hz, mV/(m/s^2), fraction, deg or None
TABLE_COLUMNS = (
    "frequency_hz",
    "sensitivity_mv_per_ms2",
    "relative_expanded_uncertainty_percent",
    "phase_deg",
)
MAX_TABLE_BYTES = 1_000_000
MAX_TABLE_ROWS = 1000


class ReferenceTableError(Refusal):
    """A calibration table that cannot be read; the message names the option, file and line."""


def read_reference_table(path: Path, option: str = "--table") -> list[TableRow]:
    """The rows of the table at `path` (module docstring), checked: numbers finite, frequency
    and sensitivity > 0, uncertainty in [0, 100) %, frequencies increasing. ReferenceTableError
    naming `option`, the file and the line."""
    if not path.is_file():
        raise ReferenceTableError(f"{option}: no such file {path}")
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise ReferenceTableError(f"{option}: {path} cannot be read ({exc})") from None
    if len(raw) > MAX_TABLE_BYTES:
        raise ReferenceTableError(f"{option}: {path} is larger than {MAX_TABLE_BYTES} bytes")
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise ReferenceTableError(f"{option}: {path} is not UTF-8 text") from None
    rows: list[TableRow] = []
    for number, cells in enumerate(csv.reader(io.StringIO(text)), 1):
        cells = [c.strip() for c in cells]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        where = f"{option}: {path} line {number}"
        if len(cells) not in (3, 4):
            raise ReferenceTableError(f"{where}: expected 3 or 4 columns")
        if not rows and _is_header(cells):
            _check_header(cells, where)
            continue
        rows.append(_row(cells, where, rows))
        if len(rows) > MAX_TABLE_ROWS:
            raise ReferenceTableError(f"{option}: {path}: more than {MAX_TABLE_ROWS} rows")
    if not rows:
        raise ReferenceTableError(f"{option}: {path} holds no table rows")
    return rows


def _row(cells: list[str], where: str, rows: list[TableRow]) -> TableRow:
    try:
        values = [float(c) for c in cells]
        percent = Decimal(cells[2])
    except (ValueError, InvalidOperation):
        raise ReferenceTableError(f"{where}: not a number") from None
    if not all(math.isfinite(v) for v in values):
        raise ReferenceTableError(f"{where}: not a finite number")
    if values[0] <= 0 or values[1] <= 0:
        raise ReferenceTableError(f"{where}: frequency and sensitivity must be > 0")
    if not 0 <= values[2] < 100:
        raise ReferenceTableError(
            f"{where}: relative expanded uncertainty {cells[2]} % is not in [0, 100) % (the "
            "column is in percent: 0.5 means 0.5 %)"
        )
    if rows and values[0] <= rows[-1][0]:
        raise ReferenceTableError(f"{where}: frequencies must increase")
    phase = values[3] if len(values) == 4 else None  # a certificate may state it at some only
    # percent to fraction on the decimal as typed: '0.7' -> 0.007 exactly, not 0.7 / 100
    return (values[0], values[1], float(percent / 100), phase)


def _is_header(cells: list[str]) -> bool:
    try:
        float(cells[0])
    except ValueError:
        return True
    return False


def _check_header(cells: list[str], where: str) -> None:
    """Refuse a header row whose columns are not the table's, naming the column; the
    uncertainty column must say it is in percent."""
    for index, (name, expected) in enumerate(zip(cells, TABLE_COLUMNS, strict=False)):
        plain = name.lower().replace(" ", "_")
        if index == 2:
            if "percent" not in plain and "%" not in plain:
                raise ReferenceTableError(
                    f"{where}: column {name!r} does not say its unit; the relative expanded "
                    f"uncertainty is given in percent (0.5 means 0.5 %): name the column "
                    f"{expected!r} and give percent"
                )
        elif plain != expected:
            raise ReferenceTableError(
                f"{where}: column {index + 1} is {name!r}, expected {expected!r}"
            )
