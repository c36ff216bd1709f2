"""Customers, sensor models and reference standards added and edited in the GUI (issue 24
point 7): each written through the records (found afterwards by a fresh `Lab` on the same
SQLite file), each bad field refused at the field; the Sensors tab current after a run."""

from __future__ import annotations

import html
import json
import os
from datetime import date
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QDate, Qt
from PySide6.QtWidgets import QDialog, QMessageBox

from app.gui.main_window import MainWindow
from app.gui.records_dialogs import ReferenceDialog
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from tests.app.records.db.test_run_records import add_sim_reference
from tests.lab_stand import lab_stand_file
from tests.records_db import new_records


@pytest.fixture
def url(tmp_path: Path) -> str:
    url = new_records(tmp_path / "lab.sqlite")
    Lab(open_engine(url), actor="t").add_customer("Existing Ltd")
    return url


@pytest.fixture
def window(qtbot, tmp_path, url):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, db=url)
    qtbot.addWidget(w)
    w.records.wait()
    w.sensors_tab.refresh()
    return w


def fresh(url: str) -> Lab:
    """The records as another program reads them (nothing cached by the window)."""
    return Lab(open_engine(url), actor="reader")


def accepted(dialog: QDialog) -> bool:
    dialog.accept()
    return dialog.result() == QDialog.DialogCode.Accepted


def marked(dialog, key: str) -> str:
    """The reason shown under field `key` as the technician reads it ("" when none)."""
    return html.unescape(dialog.marks.reason(dialog.fields[key]))


def test_a_customer_is_added_and_edited_and_bad_names_are_refused_at_the_field(window, url):
    listing = window.sensors_tab.records_list("customers")
    assert listing.table.rowCount() == 1
    dialog = listing.open_editor(None)
    dialog.name.setText("   ")
    assert not accepted(dialog)
    assert "customer: must not be blank" in marked(dialog, "name")
    dialog.name.setText("Existing Ltd")
    assert not accepted(dialog)
    assert "already exists" in marked(dialog, "name")
    dialog.name.setText("ACME Ltd")
    dialog.address.setText("1 Main Street, Springfield")
    assert accepted(dialog) and marked(dialog, "name") == ""
    assert [(c.name, c.address) for c in fresh(url).customers()] == [
        ("ACME Ltd", "1 Main Street, Springfield"),
        ("Existing Ltd", ""),
    ]
    listing.refresh()
    assert listing.table.rowCount() == 2 and listing.table.item(0, 1).text().startswith("1 Main")

    editor = listing.open_editor(listing.items[0])
    assert editor.name.text() == "ACME Ltd"
    editor.address.setText("2 High Street")
    assert accepted(editor)
    acme = next(c for c in fresh(url).customers() if c.name == "ACME Ltd")
    assert acme.address == "2 High Street"


def test_a_sensor_model_is_added_and_edited_each_bad_field_marked(window, url):
    listing = window.sensors_tab.records_list("models")
    dialog = listing.open_editor(None)
    assert not accepted(dialog)  # every blank field marked at once, nothing written
    assert {"maker", "model", "nominal", "frequency_min", "frequency_max"} <= {
        key for key in dialog.fields if "must not be blank" in marked(dialog, key)
    }
    assert marked(dialog, "tolerance") == "" and marked(dialog, "phase_tolerance") == ""
    assert fresh(dialog.lab.engine.url.render_as_string(hide_password=False)).models() == []
    dialog.maker.setText("PCB")
    dialog.model.setText("352C33")
    dialog.nominal.setText("abc")
    dialog.unit.setCurrentIndex(dialog.unit.findData("mV/g"))
    assert dialog.unit.currentText() == "mV/g"
    dialog.frequency_min.setText("1")
    dialog.frequency_max.setText("10000")
    assert not accepted(dialog)
    assert "'abc' is not a number" in marked(dialog, "nominal")
    dialog.nominal.setText("-5")  # the records' own check, at the field it names
    assert not accepted(dialog)
    assert "nominal sensitivity: must be in (0, 1e+06]" in marked(dialog, "nominal")
    dialog.nominal.setText("100")
    dialog.frequency_max.setText("0.5")  # below the lowest frequency
    assert not accepted(dialog)
    assert "frequency max" in marked(dialog, "frequency_max") and marked(dialog, "nominal") == ""
    dialog.frequency_max.setText("10000")
    dialog.tolerance.setText("150")
    assert not accepted(dialog)
    assert "tolerance: must be in (0, 100]" in marked(dialog, "tolerance")
    dialog.tolerance.setText("5")
    dialog.phase_tolerance.setText("2.5")
    assert accepted(dialog)
    (model,) = fresh(url).models()
    assert (model.maker, model.model, model.nominal_sensitivity, model.unit) == (
        "PCB",
        "352C33",
        100.0,
        "mV/g",
    )
    assert (model.frequency_min_hz, model.frequency_max_hz, model.phase_tolerance_deg) == (
        1.0,
        10000.0,
        2.5,
    )
    listing.refresh()
    assert listing.table.item(0, 2).text() == "100 mV/g"

    editor = listing.open_editor(listing.items[0])
    assert editor.nominal.text() == "100" and editor.unit.currentData() == "mV/g"
    editor.nominal.setText("98.5")
    editor.unit.setCurrentIndex(editor.unit.findData("mV/(m/s^2)"))
    assert editor.unit.currentText() == "mV/(m/s²)"  # one way of writing it in the GUI
    editor.phase_tolerance.setText("")  # blank: not assessed
    assert accepted(editor)
    (model,) = fresh(url).models()
    assert (model.nominal_sensitivity, model.unit, model.phase_tolerance_deg) == (
        98.5,
        "mV/(m/s^2)",
        None,
    )


def _csv(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def _fill_reference(dialog: ReferenceDialog, table: Path) -> None:
    dialog.identifier.setText("REF-8305")
    dialog.model.setText("B&K 8305")
    dialog.serial.setText("2571833")
    dialog.certificate.setText("DKD-2026-117")
    dialog.calibrated.setDate(QDate(2026, 3, 2))
    dialog.due.setDate(QDate(2027, 3, 2))
    dialog.table_file.setText(str(table))


def test_a_reference_standard_is_added_from_a_csv_table_and_recalibrated(window, url, tmp_path):
    listing = window.sensors_tab.records_list("references")
    dialog = listing.open_editor(None)
    bad = _csv(
        tmp_path / "bad.csv",
        "frequency_hz,sensitivity_mv_per_ms2,relative_expanded_uncertainty_percent\n"
        "160,1.0,0.5\n1000,1.01\n",
    )
    _fill_reference(dialog, bad)
    assert not accepted(dialog)
    assert "line 3: expected 3 or 4 columns" in marked(dialog, "table")
    fraction_over_one = _csv(tmp_path / "big.csv", "160,1.0,150\n")  # percent: 150 % is refused
    dialog.table_file.setText(str(fraction_over_one))
    assert not accepted(dialog)
    # refused by the one table reader (app.io.reference_table), naming the line and the rule
    assert "line 1: relative expanded uncertainty 150 % is not in [0, 100) %" in marked(
        dialog, "table"
    )
    good = _csv(
        tmp_path / "ref.csv",
        "# B&K 8305 certificate DKD-2026-117\nfrequency_hz,sensitivity_mv_per_ms2,"
        "relative_expanded_uncertainty_percent,phase_deg\n160,0.1257,0.5,0.1\n1000,0.1262,0.7,-0.4\n",
    )
    dialog.table_file.setText(str(good))
    dialog.due.setDate(QDate(2026, 3, 1))  # before the calibration
    assert not accepted(dialog)
    assert "due date: 2026-03-01 is not after" in marked(dialog, "due")
    # the table as read, its relative uncertainties shown in %
    assert [dialog.preview.item(r, 2).text() for r in range(2)] == ["0.5", "0.7"]
    assert dialog.preview.horizontalHeaderItem(2).text() == "U rel. %"
    dialog.due.setDate(QDate(2027, 3, 2))
    assert accepted(dialog)
    (ref,) = fresh(url).references()
    assert (ref.identifier, ref.serial, ref.certificate_number) == (
        "REF-8305",
        "2571833",
        "DKD-2026-117",
    )
    assert (ref.calibration_date, ref.due_date) == (date(2026, 3, 2), date(2027, 3, 2))
    assert [
        (p.frequency_hz, p.sensitivity_mv_per_ms2, p.relative_expanded_uncertainty, p.phase_deg)
        for p in ref.points
    ] == [(160.0, 0.1257, 0.005, 0.1), (1000.0, 0.1262, 0.007, -0.4)]

    # a second one with the same identifier is refused at the identifier
    again = listing.open_editor(None)
    _fill_reference(again, good)
    assert not accepted(again)
    assert "already exists" in marked(again, "identifier")
    # without a table file a new reference is refused at the table field
    again.identifier.setText("REF-2")
    again.table_file.setText("")
    assert not accepted(again)
    assert "choose the CSV file" in marked(again, "table")

    # the recalibration: a new certificate, dates and table; the identifier is fixed
    listing.refresh()
    editor = listing.open_editor(listing.items[0])
    assert editor.identifier.isReadOnly() and editor.preview.rowCount() == 2
    editor.certificate.setText("DKD-2027-004")
    editor.calibrated.setDate(QDate(2027, 2, 20))
    editor.due.setDate(QDate(2028, 2, 20))
    editor.table_file.setText(str(_csv(tmp_path / "new.csv", "160,0.1259,0.004\n")))
    assert accepted(editor)
    (ref,) = fresh(url).references()
    assert ref.certificate_number == "DKD-2027-004" and ref.due_date == date(2028, 2, 20)
    assert [(p.frequency_hz, p.sensitivity_mv_per_ms2, p.phase_deg) for p in ref.points] == [
        (160.0, 0.1259, None)
    ]
    # an edit without a new file keeps the table on record
    listing.refresh()
    editor = listing.open_editor(listing.items[0])
    editor.model.setText("Brüel & Kjær 8305")
    assert accepted(editor)
    (ref,) = fresh(url).references()
    assert ref.model == "Brüel & Kjær 8305" and len(ref.points) == 1


def test_a_customer_model_and_reference_added_in_the_gui_are_in_the_records(
    window, url, tmp_path, monkeypatch
):
    """The whole path through the Sensors tab's buttons: each list opens, Add runs its editor
    (filled here instead of by hand), the records hold all three afterwards and the views
    read them again."""
    fills = {
        "CustomerDialog": lambda d: d.name.setText("New Customer AG"),
        "ModelDialog": lambda d: (
            d.maker.setText("Kistler"),
            d.model.setText("8702B"),
            d.nominal.setText("5"),
            d.frequency_min.setText("1"),
            d.frequency_max.setText("8000"),
        ),
        "ReferenceDialog": lambda d: _fill_reference(
            d, _csv(tmp_path / "t.csv", "160,0.125,0.005\n")
        ),
    }

    def exec_filled(dialog):
        fills[type(dialog).__name__](dialog)
        dialog.accept()
        return dialog.result()

    from app.gui import records_dialogs

    monkeypatch.setattr(records_dialogs.RecordDialog, "exec", exec_filled)
    opened = []

    def list_exec(listing):
        opened.append(listing.windowTitle())
        assert listing.add()
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(records_dialogs.RecordsList, "exec", list_exec)
    changed = []
    window.records.changed.connect(lambda: changed.append(1))
    tab = window.sensors_tab
    for key in ("customers", "models", "references"):
        assert tab.edit_buttons[key].isEnabled()
        tab.edit_buttons[key].click()
    assert opened == ["Customers", "Sensor models", "Reference standards"]
    assert len(changed) == 3
    lab = fresh(url)
    assert "New Customer AG" in [c.name for c in lab.customers()]
    assert [f"{m.maker} {m.model}" for m in lab.models()] == ["Kistler 8702B"]
    assert [r.identifier for r in lab.references()] == ["REF-8305"]
    assert "REF-8305" in tab.due_identifiers() or lab.references()[0].due_date > date.today()


def test_the_sensors_tab_shows_a_run_of_the_selected_sensor_when_it_ends(qtbot, tmp_path, url):
    lab = Lab(open_engine(url), actor="t")
    lab.add_model(
        "PCB",
        "352C33",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=1,
        frequency_max_hz=10000,
    )
    lab.add_sensor("SN-9", model="352C33", owner="Existing Ltd")
    add_sim_reference(url, date(2099, 1, 1))  # Start needs the stand's reference on record
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, db=url)
    qtbot.addWidget(w)
    w.records.wait()
    w.wait_for_plans()
    tab = w.sensors_tab
    tab.search.setText("SN-9")
    assert tab.serial == "SN-9" and "no complete calibration" in tab.history_text.text()
    assert tab.sensors.item(0, 4).text() == "never calibrated here"
    w.setup_tab.dut_id.setText("SN-9")
    w.setup_tab.dut_id.editingFinished.emit()
    w.setup_tab.frequencies.setText("80,160,315")
    w.setup_tab.periods.setValue(3)
    w.wait_for_plans()
    with qtbot.waitSignal(w.run_finished, timeout=60_000):
        w.start_run()
    w.records.wait_jobs()
    # without touching the tab: the new calibration is in its table and chart
    assert tab.serial == "SN-9"
    x, _y = tab.points.getData()
    assert len(x) == 1 and "1 calibration(s)" in tab.history_text.text()
    assert tab.sensors.item(0, 4).text() != "never calibrated here"


def test_start_refuses_a_reference_standard_not_on_record_unless_a_reason_is_given(
    qtbot, url, tmp_path, monkeypatch, caplog
):
    """Issue 24 point 2, as the CLI: with records open, a stand's reference standard that is a
    lab's (REF-8305-SIM with its table in the stand file, not in these records) refuses Start
    naming it; cancelled or blank, nothing starts; with a reason the run goes on under a
    recorded override. (The built-in stand's own reference is exempt: test_first_use.)"""
    from app.gui import reference_view

    window = MainWindow(
        stand_file=lab_stand_file(tmp_path), out=tmp_path / "runs", paced=False, seed=4, db=url
    )
    qtbot.addWidget(window)
    window.records.wait()

    asked: list[str] = []
    answers = iter([("", False), ("   ", True), ("new certificate in transit", True)])

    def get_text(parent, title, label, *args, **kwargs):
        asked.append(label)
        return next(answers)

    monkeypatch.setattr(reference_view.QInputDialog, "getText", get_text)
    monkeypatch.setattr(QMessageBox, "warning", lambda *a, **k: pytest.fail(f"warning: {a[2]}"))
    window.setup_tab.frequencies.setText("160")
    window.setup_tab.periods.setValue(3)
    qtbot.waitUntil(window.setup_tab.start_button.isEnabled, timeout=30_000)
    for _ in range(2):  # cancelled, then blank: refused
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
        assert window.run_tab.worker is None
        mark = window.setup_tab.field_marks.reason(window.setup_tab.reference_label)
        assert "Start refused" in mark and "REF-8305-SIM" in mark and "not in the records" in mark
    assert len(asked) == 2 and "REF-8305-SIM" in asked[0]
    with qtbot.waitSignal(window.run_finished, timeout=90_000) as blocker:
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    finished = blocker.args[0]
    assert finished.status == "complete"
    (override,) = finished.record.overrides  # a typed field of the run record, as the CLI's
    assert override.kind == "unrecorded reference" and override.why == "new certificate in transit"
    assert "REF-8305-SIM" in override.what
    stored = json.loads((window.options.out / finished.record.run_id / "results.json").read_text())
    assert stored["overrides"][0]["why"] == "new certificate in transit"
    from sqlalchemy import select

    from app.records.db.models import AuditEntry

    window.records.wait_jobs()  # the run indexed
    with fresh(url).session() as s:
        trail = s.scalars(
            select(AuditEntry).where(AuditEntry.action == "override").order_by(AuditEntry.id)
        ).all()
        # granted (keyed by the reference standard), then with the run when it was indexed
        assert [(e.table_name, e.row_key) for e in trail] == [
            ("reference_standards", "REF-8305-SIM"),
            ("runs", finished.record.run_id),
        ]
        assert all(json.loads(e.changes)["why"] == "new certificate in transit" for e in trail)
    assert window.setup_tab.field_marks.reason(window.setup_tab.reference_label) == ""
    assert any(
        "used under the override: new certificate in transit" in r.getMessage()
        for r in caplog.records
    )


def test_the_model_dialog_reads_tolerance_and_level_as_the_cli_does(window, url):
    """Issue 31 point 3: `5%` is 5 %, `0.5g` is 4.903325 m/s^2; a wrong unit is refused at its
    field naming it, nothing written."""
    listing = window.sensors_tab.records_list("models")
    dialog = listing.open_editor(None)
    dialog.maker.setText("PCB")
    dialog.model.setText("352C33")
    dialog.nominal.setText("100")
    dialog.unit.setCurrentIndex(dialog.unit.findData("mV/g"))
    dialog.frequency_min.setText("1")
    dialog.frequency_max.setText("10000")
    dialog.tolerance.setText("5 s")
    dialog.level.setText("0.5gg")
    assert not accepted(dialog)
    assert "tolerance: '5 s' is not a percentage" in marked(dialog, "tolerance")
    assert "level: '0.5gg' is not an acceleration (m/s² or g)" in marked(dialog, "level")
    assert fresh(url).models() == []
    dialog.tolerance.setText("5%")
    dialog.level.setText("0.5g")
    assert accepted(dialog)
    (model,) = fresh(url).models()
    assert model.tolerance_percent == 5.0
    assert model.level_ms2 == pytest.approx(4.903325, rel=1e-12)
