"""The reference dialog's DCC (issue 35 point 4): a reference standard's DCC chosen in place
of a CSV table is read by the same reader as `accelcal refs add --dcc`
(app.io.reference_dcc), its model, serial, certificate number (its uniqueIdentifier) and
calibration date filled in, what was read and its signature shown at the file field, a refusal
marked there naming the element; on save the fields must still be the DCC's."""

from __future__ import annotations

from datetime import date
from pathlib import Path
from typing import Any

from PySide6.QtCore import QDate

from app.gui.field_marks import ERROR, INFO
from app.io.reference_dcc import ReferenceDcc, ReferenceDccError, read_reference_dcc
from app.io.reference_table import TableRow

DCC_SUFFIXES = (".xml",)
FILE_FILTER = "CSV table or DCC (*.csv *.xml)"


def is_dcc(path: Path) -> bool:
    """Whether the chosen file is taken as a DCC (by its suffix) rather than a CSV table."""
    return path.suffix.lower() in DCC_SUFFIXES


def summary(dcc: ReferenceDcc) -> str:
    """One note for the file field: identity, laboratory, table, signature, SHA-256."""
    first, last = dcc.points[0].frequency_hz, dcc.points[-1].frequency_hz
    return (
        f"DCC {dcc.unique_identifier} of {dcc.laboratory}: {len(dcc.points)} frequencies, "
        f"{first:g} Hz to {last:g} Hz; {dcc.signature.line()}; SHA-256 {dcc.sha256}"
    )


def load_dcc(dialog: Any, path: Path, *, fill: bool = True) -> list[TableRow] | None:
    """Read the DCC at `path` into the reference dialog `dialog` (app.gui.records_dialogs.
    ReferenceDialog): `dialog.dcc` set, the note at the file field, the fields filled unless
    `fill` is False (on save: the fields as typed are checked against it); None and the
    refusal marked at the file field when it is refused."""
    dialog.dcc = None
    try:
        dcc = read_reference_dcc(path, "table")
    except ReferenceDccError as exc:
        dialog.marks.note(dialog.table_file, str(exc), ERROR)
        return None
    dialog.dcc = dcc
    dialog.marks.note(dialog.table_file, summary(dcc), INFO)
    if not fill:
        return dcc.table()
    if dcc.model and not dialog.model.text().strip():
        dialog.model.setText(dcc.model)
    if dcc.serial:
        dialog.serial.setText(dcc.serial)
    dialog.certificate.setText(dcc.unique_identifier)
    day = dcc.calibration_date
    dialog.calibrated.setDate(QDate(day.year, day.month, day.day))
    return dcc.table()


def mismatches(
    dcc: ReferenceDcc, *, serial: str, certificate: str, calibrated: date
) -> list[tuple[str, str]]:
    """The fields (key, reason) no longer the DCC's: its serial, uniqueIdentifier, date."""
    found = []
    if dcc.serial and serial.strip() != dcc.serial:
        found.append(("serial", f"the DCC's serial is {dcc.serial}"))
    if certificate.strip() != dcc.unique_identifier:
        found.append(("certificate", f"the DCC's uniqueIdentifier is {dcc.unique_identifier}"))
    if calibrated != dcc.calibration_date:
        found.append(("calibrated", f"the DCC's endPerformanceDate is {dcc.calibration_date}"))
    return found
