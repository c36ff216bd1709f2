"""The window with the lab's records (issue 15 point 8, issue 17 points 3, 4, 7, 9): the Sensors
tab, the certificate dialog filled from the records, the verdict, the reference standard of a
loaded stand file, keyboard and menus, an unknown serial, bad input marked at its field."""

from __future__ import annotations

import os
from datetime import UTC, date, datetime
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDialog, QMessageBox

from app.gui import certificate_dialog, sensor_entry
from app.gui.main_window import MainWindow
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import Run, Stand
from tests.app.records.db.test_run_records import add_sim_reference
from tests.records_db import new_records

ROOT = Path(__file__).resolve().parents[2]
TODAY = date(2026, 11, 24)


def _history_run(lab: Lab, serial: str, run_id: str, day: date, s: float, u: float) -> None:
    """An indexed complete run of `serial` (the records' own rows; no folder needed here)."""
    sensor = lab.sensor(serial)
    with lab.session() as session:
        stand = session.query(Stand).first() or Stand(stand_file_sha256="0" * 64, name="stand")
        session.add(
            Run(
                run_id=run_id,
                manifest_sha256=run_id.ljust(64, "0")[:64],
                folder=f"/runs/{run_id}",
                status="complete",
                started_utc=datetime(day.year, day.month, day.day, 9, tzinfo=UTC),
                dut_id=serial,
                stand=stand,
                sensor_id=sensor.id,
                reference_frequency_hz=160.0,
                sensitivity_mv_per_ms2=s,
                expanded_uncertainty_mv_per_ms2=u,
            )
        )


@pytest.fixture
def lab_url(tmp_path: Path) -> str:
    url = new_records(tmp_path / "lab.sqlite")
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd", "1 Main Street")
    lab.add_customer("Other GmbH")
    lab.add_model(
        "Brüel & Kjær",
        "4533-B",
        nominal_sensitivity=100.0,
        unit="mV/g",
        tolerance_percent=3,
        frequency_min_hz=1,
        frequency_max_hz=10000,
        level_ms2=4.0,
    )
    lab.add_sensor("SN-7", model="4533-B", owner="ACME Ltd")
    lab.add_sensor("SN-8", model="4533-B", owner="Other GmbH", interval_months=12)
    _history_run(lab, "SN-7", "r1", date(2025, 12, 1), 10.20, 0.05)
    _history_run(lab, "SN-7", "r2", date(2026, 3, 1), 10.21, 0.05)
    _history_run(lab, "SN-7", "r3", date(2026, 9, 1), 10.23, 0.06)
    _history_run(lab, "SN-8", "r4", date(2024, 10, 1), 10.0, 0.1)  # due 2025-10-01: overdue
    add_sim_reference(url, date(2099, 1, 1))  # Start needs the stand's reference on record
    return url


@pytest.fixture
def window(qtbot, tmp_path, lab_url):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, db=lab_url)
    qtbot.addWidget(w)
    w.records.wait()
    w.sensors_tab._today = TODAY
    w.sensors_tab.refresh()
    w.wait_for_plans()
    return w


def test_sensors_tab_search_history_and_due_list(window):
    tab = window.sensors_tab
    assert "records: sqlite" in tab.status.text()
    tab.search.setText("SN-7")
    assert tab.sensors.rowCount() == 1 and tab.sensors.item(0, 2).text() == "ACME Ltd"
    assert tab.serial == "SN-7"  # the exact match is selected and its history drawn
    x, y = tab.points.getData()
    assert len(x) == 3 and list(y) == pytest.approx([10.20, 10.21, 10.23])
    assert tab.bars.opts["height"] == pytest.approx([0.10, 0.10, 0.12])
    assert "3 calibration(s)" in tab.history_text.text() and "% per year" in tab.history_text.text()
    tab.search.setText("SN")
    assert tab.sensors.rowCount() == 2
    due = tab.due_identifiers()
    assert "SN-8" in due and "SN-7" not in due  # SN-7 is due 2027-09-01
    row = due.index("SN-8")
    assert "OVERDUE" in tab.due.item(row, 2).text()
    assert tab.chart.getPlotItem().getAxis("left").labelText == "sensitivity"
    assert "mV/(m/s²)" in tab.chart.getPlotItem().getAxis("left").labelUnits


def test_records_that_cannot_be_opened_leave_the_window_working(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False, db="sqlite:///" + str(tmp_path / "x.db"))
    qtbot.addWidget(w)
    w.records.wait()
    assert "records not available" in w.sensors_tab.status.text()
    assert "does not exist; `accelcal db upgrade` creates it" in w.sensors_tab.status.text()
    assert not (tmp_path / "x.db").exists()  # the window never creates records
    assert not w.sensors_tab.search.isEnabled()
    w.wait_for_plans()
    assert w.setup_tab.start_button.isEnabled()


def test_a_clean_run_shows_pass_large_and_in_the_runs_list_and_the_certificate_is_prefilled(
    window, qtbot, monkeypatch
):
    window.setup_tab.dut_id.setText("SN-7")
    window.setup_tab.dut_id.editingFinished.emit()
    assert window.setup_tab.nominal.value() == pytest.approx(
        100 / 9.80665, abs=1e-3
    )  # from the records
    assert window.setup_tab.tolerance.value() == 3.0 and window.setup_tab.level.value() == 4.0
    window.setup_tab.periods.setValue(4)
    # the simulated piezo's own nominal value for a clean PASS (the records' model is not it)
    window.setup_tab.nominal.setValue(0.0)
    window.setup_tab.tolerance.setValue(5.0)
    with qtbot.waitSignal(window.run_finished, timeout=60_000) as blocker:
        window.start_run()
    finished = blocker.args[0]
    assert finished.status == "complete" and finished.results.verdict == "PASS"
    assert window.results_tab.verdict.word.text() == "PASS"
    assert window.results_tab.verdict.isVisibleTo(window.results_tab)
    folder = window.results_tab.folder
    assert window.runs_tab.verdict_of(folder.name) == "PASS"
    assert window.runs_tab.runs.horizontalHeaderItem(1).text() == "Verdict"
    # indexed into the records when it ended (off the GUI thread): a fourth point
    window.records.wait_jobs()
    assert len(window.records.lab.history("SN-7").points) == 4
    assert window.sensors_tab.search.text() == "" and window.sensors_tab.sensors.rowCount() == 2

    seen = {}

    def fake_exec(dialog):
        seen.update({k: e.text() for k, e in dialog.edits.items()})
        return QDialog.DialogCode.Rejected

    monkeypatch.setattr(certificate_dialog.CertificateDialog, "exec", fake_exec)
    window.certificate_action()
    assert seen["customer"] == "ACME Ltd" and seen["customer_address"] == "1 Main Street"
    assert seen["dut_model"] == "Brüel & Kjær 4533-B" and seen["dut_serial"] == "SN-7"
    assert seen["authorised_by"] == "" and seen["mounting"] == ""  # asked afresh
    # issue 35: the mounting remembered for the sensor's model is offered, saying from where
    from app.certificate.remembered import RememberedConditions

    RememberedConditions().remember("Brüel & Kjær 4533-B", "stud M3, 1 N m")
    offered = {}

    def offered_exec(dialog):
        offered["mounting"] = dialog.edits["mounting"].text()
        offered["tip"] = dialog.edits["mounting"].toolTip()
        return QDialog.DialogCode.Rejected

    monkeypatch.setattr(certificate_dialog.CertificateDialog, "exec", offered_exec)
    window.certificate_action()
    assert offered == {"mounting": "stud M3, 1 N m", "tip": "from model Brüel & Kjær 4533-B"}


def test_esc_aborts_a_run_through_the_menu_action_to_0_v(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=True, seed=2)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.activateWindow()
    w.wait_for_plans()
    assert not w.window_actions.abort.isEnabled()  # idle: Esc is left to dialogs
    w.start_run()
    qtbot.waitUntil(w.window_actions.abort.isEnabled, timeout=5_000)
    assert w.window_actions.abort.shortcut().toString() == "Esc"
    qtbot.waitUntil(
        lambda: "identifying" in w.run_tab.state.text() or "equalising" in w.run_tab.state.text(),
        timeout=30_000,
    )
    stand = w.run_tab.worker.stand
    with qtbot.waitSignal(w.run_finished, timeout=30_000) as blocker:
        qtbot.keyClick(w.focusWidget() or w, Qt.Key.Key_Escape)
    assert blocker.args[0].abort_reason == "emergency stop"
    assert stand.daq.output_v == 0.0 and blocker.args[0].record.final_output_v == 0.0


def test_shortcuts_are_in_the_menus_and_tooltips_and_every_field_is_reached_by_tab(window):
    actions = window.window_actions
    shortcuts = {
        actions.start: "Ctrl+R",
        actions.abort: "Esc",
        actions.next_sensor: "Ctrl+N",
        actions.certificate: "Ctrl+Shift+C",
    }
    menu_actions = [a for m in window.menuBar().actions() for a in m.menu().actions()]
    for action, key in shortcuts.items():
        assert action in menu_actions and action.shortcut().toString() == key
        assert key in action.toolTip()
    assert (
        "Ctrl+R" in window.setup_tab.start_button.toolTip()
        and "Ctrl+R" in window.setup_tab.start_button.text()
    )
    assert "Ctrl+Shift+C" in window.results_tab.certificate_button.toolTip()
    assert "Ctrl+." in window.run_tab.stop_button.toolTip()
    fields = [
        window.setup_tab.dut,
        window.setup_tab.dut_id,
        window.setup_tab.nominal,
        window.setup_tab.tolerance,
        window.setup_tab.preset,
        window.setup_tab.frequencies,
        window.setup_tab.level,
        window.setup_tab.periods,
        window.setup_tab.target,
        window.setup_tab.max_time,
        window.setup_tab.estimator,
        window.setup_tab.mode,
        window.setup_tab.start_button,
    ]
    reached, widget = set(), window.setup_tab.dut
    for _ in range(60):
        reached.add(widget)
        widget = widget.nextInFocusChain()
    assert all(f in reached for f in fields)
    assert all(f.focusPolicy() & Qt.FocusPolicy.TabFocus for f in fields)
    for spin in (window.setup_tab.nominal, window.setup_tab.tolerance, window.setup_tab.level):
        assert spin.suffix().strip()  # units in the field
    # next sensor: nothing of the last one carried over
    window.setup_tab.dut_id.setText("SN-7")
    window.setup_tab.dut_id.editingFinished.emit()
    actions.next_sensor.trigger()
    assert window.setup_tab.dut_id.text() == "" and window.setup_tab.nominal.value() == 0.0
    assert (
        window.tabs.currentIndex() == 0
        and window.setup_tab.field_marks.reason(window.setup_tab.dut_id) == ""
    )


def test_an_unknown_serial_offers_registration_and_fills_nothing(window, monkeypatch):
    asked = []
    monkeypatch.setattr(
        sensor_entry.QMessageBox,
        "question",
        lambda *a, **k: asked.append(a[2]) or QMessageBox.StandardButton.No,
    )
    before = (
        window.setup_tab.nominal.value(),
        window.setup_tab.tolerance.value(),
        window.setup_tab.level.value(),
    )
    window.setup_tab.dut_id.setText("SN-77")  # near SN-7: never guessed
    window.setup_tab.dut_id.editingFinished.emit()
    assert asked and "SN-77 is not in the records" in asked[0]
    assert (
        window.setup_tab.nominal.value(),
        window.setup_tab.tolerance.value(),
        window.setup_tab.level.value(),
    ) == before
    assert "not in the records" in window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
    assert "border" in window.setup_tab.dut_id.styleSheet()

    # accepted this time: the dialog registers it with the model and owner chosen
    monkeypatch.setattr(
        sensor_entry.QMessageBox,
        "question",
        lambda *a, **k: QMessageBox.StandardButton.Yes,
    )
    shown = []

    def fake_exec(dialog):
        shown.append(dialog.serial.text())
        dialog.owner.setCurrentText("Other GmbH")
        return QDialog.DialogCode.Accepted

    monkeypatch.setattr(sensor_entry.RegisterSensorDialog, "exec", fake_exec)
    window.setup_tab.dut_id.setText("SN-99")
    window.setup_tab.dut_id.textEdited.emit("SN-99")
    window.setup_tab.dut_id.editingFinished.emit()
    assert shown == ["SN-99"]
    sensor = window.records.lab.sensor("SN-99")
    assert sensor.owner.name == "Other GmbH"
    assert "from the records" in window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
    assert window.setup_tab.tolerance.value() == 3.0


def test_a_bad_field_is_marked_with_its_reason_and_blocks_start(window):
    assert window.setup_tab.start_button.isEnabled() and window.setup_tab.field_marks.marked() == {}
    window.setup_tab.frequencies.setText("10, 20 kHz")
    assert not window.setup_tab.start_button.isEnabled()
    reason = window.setup_tab.field_marks.reason(window.setup_tab.frequencies)
    assert "'20 kHz' is not a number of Hz" in reason.replace("&#x27;", "'")
    assert "border" in window.setup_tab.frequencies.styleSheet()
    window.setup_tab.frequencies.setText("")
    window.setup_tab.preset.setCurrentText("capacitive")
    window.setup_tab.level.setValue(8.0)
    assert not window.setup_tab.start_button.isEnabled()
    assert "displacement" in window.setup_tab.field_marks.reason(window.setup_tab.level)
    assert window.setup_tab.field_marks.reason(window.setup_tab.frequencies) == ""
    window.setup_tab.level.setValue(5.0)
    assert window.setup_tab.start_button.isEnabled() and window.setup_tab.field_marks.marked() == {}


def test_the_reference_standard_shown_is_the_stand_files_with_its_record(window, lab_url):
    assert "REF-8305-SIM" in window.setup_tab.reference_label.text()
    assert "records: certificate SIM-CAL-2026-001 of 2025-06-01, due on 2099-01-01" in (
        window.setup_tab.reference_label.text()
    )
    example = ROOT / "examples" / "stand-pxi6251.toml"
    from app.stand import config as stand_config

    ref = stand_config.load(example).reference
    Lab(open_engine(lab_url), actor="t").add_reference(
        ref.id,
        model=ref.model,
        serial=ref.serial,
        certificate_number="PTB-1",
        calibration_date=date(2024, 1, 10),
        due_date=date(2025, 1, 10),
        table=[(160.0, 1.0, 0.005, None)],
    )
    assert window.setup_tab.load_stand(example)
    text = window.setup_tab.reference_label.text()
    assert ref.id in text and ref.serial in text and "stand-pxi6251.toml" in text
    assert "EXPIRED, due on 2025-01-10" in text
    assert "simulated" not in text


def test_the_verdict_view_shows_fail_and_indeterminate_with_reasons(qtbot):
    from app.gui.verdict_view import VerdictView, verdict_of

    view = VerdictView()
    qtbot.addWidget(view)
    view.show_verdict("FAIL", ["sensitivity at 160 Hz: fail (-7.1 % from the nominal)"])
    assert view.word.text() == "FAIL" and "#c0392b" in view.word.styleSheet()
    assert "sensitivity at 160 Hz: fail" in view.reasons.text()
    record = {"verdict": "INDETERMINATE", "verdict_reasons": ["no tolerance given"]}
    assert verdict_of(None, record) == ("INDETERMINATE", ["no tolerance given"])
    assert verdict_of(None, {"status": "aborted"})[0] == "not assessed"
    view.show_verdict(None)
    assert not view.isVisibleTo(view.parentWidget() or view) or view.word.text() == ""


def test_gui_takes_the_records_url():
    from app.cli import build_parser

    args = build_parser().parse_args(["gui", "--sim", "--db", "sqlite:///x.sqlite"])
    assert args.db == "sqlite:///x.sqlite"
    assert build_parser().parse_args(["gui"]).db is None


def test_the_window_builds_its_request_as_the_cli_from_the_sensors_record(window, lab_url):
    """The GUI resolves a sensor on record into its DutSpec through `build_request`, as the
    CLI does: the record's phase tolerance over the model's range reaches the verdict, and
    the nominal in mV/g is converted by the records (100 mV/g = 100/9.80665 mV/(m/s^2))."""
    from app.stand.dut import Band

    Lab(open_engine(lab_url), actor="t").add_model(
        "PCB",
        "352C33",
        nominal_sensitivity=10.2,
        unit="mV/(m/s^2)",
        tolerance_percent=4,
        frequency_min_hz=5,
        frequency_max_hz=4000,
        level_ms2=6.0,
        phase_tolerance_deg=3.0,
    )
    Lab(open_engine(lab_url), actor="t").add_sensor("SN-PH", model="352C33", owner="ACME Ltd")
    setup = window.setup_tab
    setup.dut_id.setText("SN-PH")
    setup.dut_id.editingFinished.emit()
    assert setup.nominal.value() == pytest.approx(10.2)
    assert setup.tolerance.value() == 4.0 and setup.level.value() == 6.0
    request = setup.request()
    spec = request.dut_spec
    assert spec is not None and spec.serial == "SN-PH" and "PCB 352C33" in spec.source
    assert spec.phase == (Band(5.0, 4000.0, 3.0),)
    tolerances = request.tolerances("sim", 160.0)
    assert tolerances.phase == (Band(5.0, 4000.0, 3.0),)
    assert tolerances.nominal_sensitivity_mv_per_ms2 == pytest.approx(10.2)
    assert tolerances.sensitivity_percent == 4.0
    # the operator's tolerance wins over the record's, over every line
    setup.tolerance.setValue(2.5)
    assert setup.request().tolerances("sim", 160.0).characteristic[0].tolerance == 2.5
    # a serial typed but not on record: no spec of the records, the catalogue DUT's instead
    setup.dut_id.setText("SN-7")
    setup.dut_id.textEdited.emit("SN-7")  # typing forgets the look-up
    request = setup.request()
    assert request.dut_id == "SN-7" and request.dut_spec is not None
    assert request.dut_spec.phase != (Band(5.0, 4000.0, 3.0),)
    assert request.dut_spec.catalogue == "piezo"
    # the B&K model in mV/g: 100 mV/g is 10.197 mV/(m/s^2)
    setup.dut_id.setText("SN-8")
    setup.dut_id.editingFinished.emit()
    assert setup.nominal.value() == pytest.approx(100 / 9.80665, abs=1e-3)
    assert setup.request().dut_spec.nominal_mv_per_ms2 == pytest.approx(100 / 9.80665)


def test_a_template_of_fields_that_do_not_parse_is_refused_by_name(window, monkeypatch):
    shown: list[str] = []
    monkeypatch.setattr(QMessageBox, "warning", lambda parent, title, text, *a: shown.append(text))
    setup = window.setup_tab
    setup.dut_id.setText("SN-7")
    setup.dut_id.editingFinished.emit()
    setup.frequencies.setText("10,abc")
    assert setup.templates.save() is None
    assert len(shown) == 1 and "is not a number" in shown[0]
    assert Lab(open_engine(window.records.url)).templates("4533-B") == []
