"""The GUI's reference dialog takes a reference standard's DCC in place of a CSV table (issue
35 point 4): the fields filled from the DCC, what was read and its signature shown at the file
field, the table kept with the DCC in force, a malformed DCC refused at the field naming the
element, fields changed away from the DCC's refused at their fields."""

from __future__ import annotations

import html
from datetime import date
from pathlib import Path

import pytest
from PySide6.QtCore import QDate
from PySide6.QtWidgets import QDialog

from app.gui.main_window import MainWindow
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from tests.records_db import new_records

DATA = Path(__file__).parents[1] / "data" / "refdcc"


@pytest.fixture
def url(tmp_path: Path) -> str:
    return new_records(tmp_path / "lab.sqlite")


@pytest.fixture
def window(qtbot, tmp_path, url):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, db=url)
    qtbot.addWidget(w)
    w.records.wait()
    return w


def accepted(dialog: QDialog) -> bool:
    dialog.accept()
    return dialog.result() == QDialog.DialogCode.Accepted


def marked(dialog, key: str) -> str:
    return html.unescape(dialog.marks.reason(dialog.fields[key]))


def test_a_reference_is_added_from_its_dcc_and_a_malformed_one_is_refused_at_the_field(window, url):
    listing = window.sensors_tab.records_list("references")
    dialog = listing.open_editor(None)
    dialog.identifier.setText("REF-DCC")
    dialog.due.setDate(QDate(2027, 3, 4))
    dialog.table_file.setText(str(DATA / "bad_wrong_unit.xml"))
    assert dialog.load_table() is None
    assert "si:unitXMLList: unit '\\metre\\second\\tothe{-2}'" in marked(dialog, "table")
    assert not accepted(dialog)

    dialog.table_file.setText(str(DATA / "signed.xml"))
    rows = dialog.load_table()
    assert rows is not None and len(rows) == 5 and dialog.preview.rowCount() == 5
    assert (dialog.model.text(), dialog.serial.text(), dialog.certificate.text()) == (
        "8305-001",
        "SIM-0001",
        "NMI-VIB-2026-0412",
    )
    assert dialog.calibrated.date() == QDate(2026, 3, 4)
    note = marked(dialog, "table")
    assert "DCC NMI-VIB-2026-0412 of National Vibration Laboratory" in note
    assert "signed by DCC signing, National Vibration Laboratory, verified" in note

    dialog.certificate.setText("TYPED-OVER")  # no longer the DCC's: refused at the field
    assert not accepted(dialog)
    assert "the DCC's uniqueIdentifier is NMI-VIB-2026-0412" in marked(dialog, "certificate")
    dialog.certificate.setText("NMI-VIB-2026-0412")
    assert accepted(dialog)
    lab = Lab(open_engine(url), actor="reader")
    table = lab.reference_table("REF-DCC", "")
    assert table is not None and table.dcc is not None
    assert table.calibration_date == date(2026, 3, 4)
    assert table.dcc.unique_identifier == "NMI-VIB-2026-0412"
    kept = lab.reference_dcc("REF-DCC")
    assert kept is not None and kept.content == (DATA / "signed.xml").read_bytes()
