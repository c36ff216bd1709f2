"""The CSV calibration table of a reference standard, as `accelcal refs add --table` and the GUI's
reference dialog read it: one row per line `frequency_hz, sensitivity_mv_per_ms2,
relative_expanded_uncertainty[, phase_deg]` (Hz, mV/(m/s^2), as `Lab.add_reference` takes it,
degrees); a header line and '#' comments are skipped, a bad cell is refused naming its line.
"""

from __future__ import annotations

import csv
from pathlib import Path

from app.records.db.store import RecordsError

TableRow = tuple[float, float, float, float | None]


def read_reference_table(path: Path, field: str = "table") -> list[TableRow]:
    """Rows of the CSV file `path`; RecordsError naming `field` (no file) or the line."""
    path = Path(path)
    if not path.is_file():
        raise RecordsError(f"{field}: no such file {path}")
    rows: list[TableRow] = []
    with path.open(newline="", encoding="utf-8") as handle:
        for number, cells in enumerate(csv.reader(handle), 1):
            if not cells or cells[0].strip().startswith("#") or cells[0].strip().isalpha():
                continue
            if cells[0].strip() == "frequency_hz":
                continue
            if len(cells) not in (3, 4):
                raise RecordsError(f"{path} line {number}: expected 3 or 4 columns")
            try:
                values = [float(c) for c in cells]
            except ValueError:
                raise RecordsError(f"{path} line {number}: not a number") from None
            phase = values[3] if len(values) == 4 else None
            rows.append((values[0], values[1], values[2], phase))
    return rows
