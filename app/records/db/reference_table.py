"""The CSV calibration table of a reference standard, as `accelcal refs add --table` and the
GUI's reference dialog read it: one row per line `frequency_hz, sensitivity_mv_per_ms2,
relative_expanded_uncertainty_percent[, phase_deg]` (Hz, mV/(m/s^2), percent: 0.5 means
0.5 %, degrees); returned with the uncertainty as the fraction `Lab.add_reference` stores.
A bad cell is refused naming its line; a header whose uncertainty column does not say percent
is refused by name.
"""

from __future__ import annotations

import csv
from decimal import Decimal
from pathlib import Path

from app.records.db.store import RecordsError

TableRow = tuple[float, float, float, float | None]  # Hz, mV/(m/s^2), fraction, deg or None
TABLE_COLUMNS = (
    "frequency_hz",
    "sensitivity_mv_per_ms2",
    "relative_expanded_uncertainty_percent",
    "phase_deg",
)
MAX_TABLE_BYTES = 1_000_000


def read_reference_table(path: Path, option: str = "--table") -> list[TableRow]:
    """The rows of a reference calibration table CSV (what `refs add --table` and the GUI
    read): frequency_hz, sensitivity_mv_per_ms2, relative expanded uncertainty IN PERCENT
    (0.5 means 0.5 %), optional phase_deg; returned with the uncertainty as a fraction. A
    header is optional; a header whose uncertainty column does not say percent (such as
    relative_expanded_uncertainty, a fraction) is refused by name, as is a bad cell by line."""
    if not path.is_file():
        raise RecordsError(f"{option}: no such file {path}")
    if path.stat().st_size > MAX_TABLE_BYTES:
        raise RecordsError(f"{option}: {path} is larger than {MAX_TABLE_BYTES} bytes")
    rows: list[TableRow] = []
    try:
        with path.open(newline="", encoding="utf-8") as handle:
            lines = list(csv.reader(handle))
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordsError(f"{option}: {path} cannot be read ({exc})") from None
    for number, cells in enumerate(lines, 1):
        cells = [c.strip() for c in cells]
        if not cells or not any(cells) or cells[0].startswith("#"):
            continue
        where = f"{option}: {path} line {number}"
        if len(cells) not in (3, 4):
            raise RecordsError(f"{where}: expected 3 or 4 columns")
        if not rows and _is_header(cells):
            _check_header(cells, where)
            continue
        try:
            values = [float(c) for c in cells]
        except ValueError:
            raise RecordsError(f"{where}: not a number") from None
        phase = values[3] if len(values) == 4 else None
        # percent to fraction on the decimal as typed: '0.7' -> 0.007 exactly, not 0.7 / 100
        fraction = float(Decimal(cells[2]) / 100)
        rows.append((values[0], values[1], fraction, phase))
    return rows


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
                raise RecordsError(
                    f"{where}: column {name!r} does not say its unit; the relative expanded "
                    f"uncertainty is given in percent (0.5 means 0.5 %): name the column "
                    f"{expected!r} and give percent"
                )
        elif plain != expected:
            raise RecordsError(f"{where}: column {index + 1} is {name!r}, expected {expected!r}")
