"""The CSV calibration table of a reference standard as the records take it (`accelcal refs add
--table`, the GUI's reference dialog): read by the one reader every command uses
(app.io.reference_table: the uncertainty column in percent), its refusal a RecordsError.
"""

from __future__ import annotations

from pathlib import Path

from app.io import reference_table
from app.io.reference_table import TABLE_COLUMNS, TableRow
from app.records.db.store import RecordsError


def read_reference_table(path: Path, option: str = "--table") -> list[TableRow]:
    """The rows of the table at `path` (app.io.reference_table.read_reference_table), the
    uncertainty as a fraction; RecordsError naming the option, file and line."""
    try:
        return reference_table.read_reference_table(path, option)
    except reference_table.ReferenceTableError as exc:
        raise RecordsError(str(exc)) from None


__all__ = ["TABLE_COLUMNS", "TableRow", "read_reference_table"]
