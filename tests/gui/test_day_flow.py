"""A technician's whole day at the window (issue 17, point 6): three sensors of two customers,
each typed as a barcode scanner does (characters, then Enter), its model's settings and
template from the records, a run on the simulated stand, the verdict, the certificate prepared
and approved under the two-person rule and entered in the register, Next sensor with nothing
carried over; then the register, and an amendment started from it with its reason.

Every modal dialog is answered by `Modal` as a person would: it fills the fields of the dialog
that is open and presses its button; nothing of the dialogs is replaced."""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import QApplication, QDialogButtonBox, QInputDialog, QMessageBox

from app.gui import certify, teds_entry
from app.gui.certificate_dialog import CertificateDialog
from app.gui.main_window import MainWindow
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from hardware.teds import TedsError
from tests.app.records.db.test_run_records import add_sim_reference
from tests.records_db import add_staff, new_records

MG = 9.80665  # m/s^2 per g
LINES_A = "40,80,160,315,630"
LINES_B = "80,160,315,630,1000"


@pytest.fixture
def lab_url(tmp_path: Path) -> str:
    """Two customers, two models (one in mV/g), three sensors, a template per model; the
    two-person rule on; the simulated stand's reference standard on record, due 2099-01-01
    (issue 24: with records in use, Start refuses a reference standard not on record)."""
    url = new_records(tmp_path / "lab.sqlite")
    lab = Lab(open_engine(url), actor="setup")
    add_sim_reference(url, date(2099, 1, 1))
    lab.add_customer("ACME Ltd", "1 Main Street, Springfield")
    lab.add_customer("Vibration Labs GmbH", "Hauptstraße 2, Bremen")
    lab.add_model(
        "SimCo",
        "PZ-10",
        nominal_sensitivity=10.2,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=10,
        frequency_max_hz=2500,
        level_ms2=4.0,
    )
    lab.add_model(
        "Vibra",
        "V100",
        nominal_sensitivity=100.0,  # 10.197 mV/(m/s^2)
        unit="mV/g",
        tolerance_percent=4,
        frequency_min_hz=10,
        frequency_max_hz=2500,
        level_ms2=5.0,
    )
    lab.add_sensor("PZ-0001", model="PZ-10", owner="ACME Ltd")
    lab.add_sensor("V-0002", model="V100", owner="Vibration Labs GmbH")
    lab.add_sensor("PZ-0003", model="PZ-10", owner="ACME Ltd", teds_identity="43/1/A1/10004")
    lab.add_template(
        "PZ-10",
        "quick A",
        preset="piezo",
        frequencies_hz=[40, 80, 160, 315, 630],
        level_ms2=4.0,
        periods=3,
        estimator="periodic",
    )
    lab.add_template(
        "V100",
        "quick B",
        preset="piezo",
        frequencies_hz=[80, 160, 315, 630, 1000],
        level_ms2=3.0,
        periods=4,
        estimator="h1",
        tolerance_percent=4.5,
    )
    add_staff(url, ("atech", "A. Tech"), ("jsmith", "J. Smith"))  # the rule's persons
    lab.set_setting("two_person_rule", "on")
    return url


class Modal:
    """Answers modal dialogs in order: each step gets the dialog open now (checked for its
    type) and fills it and presses a button, or looks at it. A dialog with no step left is
    closed and kept in `unexpected` (the test then fails, it does not hang)."""

    def __init__(self) -> None:
        self.steps: deque[tuple[type, Callable[[Any], None]]] = deque()
        self.unexpected: list[str] = []
        self.errors: list[str] = []
        self._timer = QTimer(interval=30)
        self._timer.timeout.connect(self._poll)
        self._timer.start()

    def then(self, kind: type, step: Callable[[Any], None]) -> Modal:
        self.steps.append((kind, step))
        return self

    def _poll(self) -> None:
        dialog = QApplication.activeModalWidget()
        if dialog is None or not dialog.isVisible():
            return
        if not self.steps:
            text = getattr(dialog, "text", lambda: "")()
            self.unexpected.append(f"{type(dialog).__name__}: {text}")
            dialog.reject()
            return
        kind, step = self.steps.popleft()
        if not isinstance(dialog, kind):
            self.errors.append(f"expected {kind.__name__}, got {type(dialog).__name__}")
            dialog.reject()
            return
        try:
            step(dialog)
        except Exception as exc:  # an assertion inside a dialog: reported after it closes
            self.errors.append(f"{type(exc).__name__}: {exc}")
            dialog.reject()

    def check(self) -> None:
        self._timer.stop()
        assert not self.errors, self.errors
        assert not self.unexpected, self.unexpected
        assert not self.steps, f"{len(self.steps)} dialog step(s) never reached"


def press(dialog: Any, which: QDialogButtonBox.StandardButton) -> None:
    box = dialog.findChild(QDialogButtonBox)
    box.button(which).click()


def yes(box: QMessageBox) -> None:
    box.button(QMessageBox.StandardButton.Yes).click()


@pytest.fixture
def window(qtbot, tmp_path, lab_url, monkeypatch):
    monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4, db=lab_url)
    qtbot.addWidget(w)
    w.records.wait()
    w.wait_for_plans()
    w.setup_tab.technician.setText("A. Tech")
    return w


def type_serial(qtbot, window: MainWindow, serial: str) -> None:
    """As a barcode scanner: the characters, then Enter."""
    window.setup_tab.dut_id.setFocus()
    qtbot.keyClicks(window.setup_tab.dut_id, serial)
    qtbot.keyClick(window.setup_tab.dut_id, Qt.Key.Key_Return)


def run_now(qtbot, window: MainWindow):
    qtbot.waitUntil(window.setup_tab.start_button.isEnabled, timeout=30_000)
    with qtbot.waitSignal(window.run_finished, timeout=90_000) as blocker:
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    window.records.wait_jobs()  # indexed into the records (records thread)
    return blocker.args[0]


def certificate_steps(
    modal: Modal, seen: list[dict[str, str]], approver: str, same_person: str
) -> None:
    """The certificate dialog: first the preparer also as approver (refused at the field,
    the dialog stays open), then another approver; then the confirmation."""

    def first(dialog: CertificateDialog) -> None:
        seen.append({k: e.text() for k, e in dialog.edits.items()})
        seen[-1]["prepared_by"] = dialog.prepared_by()
        seen[-1]["temperature"] = dialog.temperature.text()
        seen[-1]["mounting_from"] = dialog.edits["mounting"].toolTip()
        dialog.edits["authorised_by"].setText(same_person)
        dialog.edits["mounting"].setText("stud, 2 N m")
        dialog.temperature.setText("23.1")
        press(dialog, QDialogButtonBox.StandardButton.Ok)

    def second(dialog: CertificateDialog) -> None:
        assert dialog.isVisible()  # refused: still open
        reason = dialog.marks.reason(dialog.edits["authorised_by"])
        assert "approved by: the lab&#x27;s two-person rule" in reason, reason
        seen[-1]["refusal"] = reason
        dialog.edits["authorised_by"].setText(approver)
        press(dialog, QDialogButtonBox.StandardButton.Ok)

    modal.then(CertificateDialog, first).then(CertificateDialog, second)


def test_a_whole_day_three_sensors_two_customers_register_and_an_amendment(window, qtbot, lab_url):
    lab = Lab(open_engine(lab_url))
    sensors = [
        # serial, customer, nominal mV/(m/s^2) by hand, model tolerance %, template, its lines
        ("PZ-0001", "ACME Ltd", 10.2, 5.0, "quick A", LINES_A, 3, 5.0),
        ("V-0002", "Vibration Labs GmbH", 100 / MG, 4.0, "quick B", LINES_B, 4, 4.5),
        ("PZ-0003", "ACME Ltd", 10.2, 5.0, "quick A", LINES_A, 3, 5.0),
    ]
    runs: dict[str, str] = {}
    folders: dict[str, Path] = {}
    seen: list[dict[str, str]] = []
    for n, (serial, customer, nominal, tol, template, lines, periods, run_tol) in enumerate(
        sensors
    ):
        type_serial(qtbot, window, serial)
        # from the records: the model's nominal (converted from mV/g) and tolerance
        assert window.setup_tab.nominal.value() == pytest.approx(nominal, abs=1e-3)
        assert window.setup_tab.tolerance.value() == tol
        assert customer in window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
        listed = ["after run 1", "quick A"] if n == 2 else [template]  # by name
        assert window.setup_tab.templates.names() == listed  # its model's templates only
        assert window.setup_tab.templates.choose(template)
        assert (
            window.setup_tab.frequencies.text() == lines
            and window.setup_tab.periods.value() == periods
        )
        assert window.setup_tab.tolerance.value() == run_tol
        finished = run_now(qtbot, window)
        assert finished.status == "complete"
        assert finished.record.dut.id == serial
        runs[serial] = str(finished.record.run_id)
        folders[serial] = window.options.out / runs[serial]
        assert window.results_tab.folder == folders[serial]
        assert finished.results.verdict == "PASS"
        assert window.results_tab.verdict.word.text() == "PASS"
        assert window.results_tab.table.rowCount() == 5

        if n == 0:  # a template saved from the settings of the run just made
            modal = Modal().then(
                QInputDialog, lambda d: (d.setTextValue("after run 1"), d.accept())
            )
            assert window.setup_tab.templates.save() == "after run 1"
            modal.check()
            saved = {t.name: t for t in lab.templates("SimCo PZ-10")}
            assert set(saved) == {"quick A", "after run 1"}
            assert saved["after run 1"].lines_hz() == (40.0, 80.0, 160.0, 315.0, 630.0)
            assert (saved["after run 1"].periods, saved["after run 1"].level_ms2) == (3, 4.0)

        modal = Modal()
        certificate_steps(modal, seen, approver="J. Smith", same_person="a. tech")
        modal.then(QMessageBox, yes)
        qtbot.mouseClick(window.results_tab.certificate_button, Qt.MouseButton.LeftButton)
        modal.check()
        # the dialog asked afresh: only the records' customer and sensor, the technician
        assert seen[n]["customer"] == customer and seen[n]["dut_serial"] == serial
        assert seen[n]["prepared_by"] == "A. Tech"
        assert seen[n]["authorised_by"] == seen[n]["temperature"] == ""
        # issue 35: the mounting typed for the first sensor of a model is offered to the next
        # of it (PZ-0003 after PZ-0001, not V-0002 of another model), saying from where (the
        # model: PZ-0001's certificate followed the save of template "after run 1", so its
        # template "quick A" holds none of its own)
        offered = serial == "PZ-0003"
        assert seen[n]["mounting"] == ("stud, 2 N m" if offered else "")
        assert seen[n]["mounting_from"] == ("from model SimCo PZ-10" if offered else "")
        assert seen[n]["notes"] == ""
        assert window.last_certificate is not None
        assert (folders[serial] / "certificate.pdf").is_file()
        assert window.last_certificate in window.results_tab.summary.text()

        # Ctrl+N: the next sensor, nothing of this one left
        window.show()
        qtbot.waitExposed(window)
        window.activateWindow()
        qtbot.waitUntil(window.isActiveWindow, timeout=5_000)
        focus = window.focusWidget() or window
        qtbot.keyClick(focus, Qt.Key.Key_N, Qt.KeyboardModifier.ControlModifier)
        assert window.setup_tab.dut_id.text() == ""
        assert window.setup_tab.nominal.value() == 0.0 and window.setup_tab.tolerance.value() == 5.0
        # the tab as it opened: the default estimator, the lpm, and its one period (issue 34;
        # periodic and 8 before)
        assert window.setup_tab.frequencies.text() == "" and window.setup_tab.periods.value() == 1
        assert (
            window.setup_tab.level.value() == 5.0
            and window.setup_tab.estimator.currentText() == "lpm"
        )
        assert window.setup_tab.field_marks.reason(window.setup_tab.dut_id) == ""
        assert (
            window.setup_tab.templates.names() == []
            and not window.setup_tab.templates.combo.isEnabled()
        )
        assert window.results_tab.folder is None and window.results_tab.results is None
        assert window.results_tab.table.rowCount() == 0
        assert window.results_tab.budget.rowCount() == 0
        assert window.results_tab.verdict.word.text() == ""
        assert not window.results_tab.certificate_button.isEnabled()
        assert (
            serial not in window.results_tab.summary.text()
            and runs[serial] not in window.results_tab.summary.text()
        )
        assert window.last_certificate is None and window.setup_tab.last_request is None
        assert window.run_tab.progress.value() == 0 and window.run_tab.coherence.text() == ""
        assert window.run_tab.messages.text() == "" and window.run_tab.state.text() == "idle"
        for curve in window.run_tab.live.curves:
            x, _ = curve.getData()
            assert x is None or len(x) == 0
        assert window.tabs.currentIndex() == 0

    # the register: three certificates, consecutive numbers, each its sensor's run
    year = datetime.now(UTC).year
    expected = [f"ACC-{year}-{k:04d}" for k in (1, 2, 3)]
    register = lab.register()
    assert [c.number for c in register] == expected
    assert [c.run.run_id for c in register] == [runs[s[0]] for s in sensors]
    assert [c.sensor.serial for c in register] == ["PZ-0001", "V-0002", "PZ-0003"]
    assert [c.sensor.owner.name for c in register] == [
        "ACME Ltd",
        "Vibration Labs GmbH",
        "ACME Ltd",
    ]
    assert {(c.prepared_by, c.approved_by, c.state) for c in register} == {
        ("A. Tech", "J. Smith", "issued")
    }
    assert len({c.run.run_id for c in register}) == 3  # three distinct runs
    tab = window.register_tab
    tab.refresh()
    assert tab.numbers() == expected
    assert [tab.cell(r, "Customer") for r in range(3)] == [
        "ACME Ltd",
        "Vibration Labs GmbH",
        "ACME Ltd",
    ]

    # an amendment of the second, started from the register with its reason
    window.tabs.setCurrentIndex(5)
    assert tab.select(expected[1])
    amended: list[dict[str, str]] = []

    def reason(dialog: QInputDialog) -> None:
        assert expected[1] in dialog.labelText()
        dialog.setTextValue("customer address corrected")
        dialog.accept()

    def fields(dialog: CertificateDialog) -> None:
        amended.append({k: e.text() for k, e in dialog.edits.items()})
        amended[-1]["title"] = dialog.title.text()
        dialog.edits["authorised_by"].setText("J. Smith")
        dialog.edits["mounting"].setText("stud, 2 N m")
        dialog.temperature.setText("23.0")
        press(dialog, QDialogButtonBox.StandardButton.Ok)

    modal = Modal().then(QInputDialog, reason).then(CertificateDialog, fields)
    modal.then(QMessageBox, yes)
    qtbot.mouseClick(tab.amend_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert f"Amendment of {expected[1]} (customer address corrected)" in amended[0]["title"]
    assert runs["V-0002"] in amended[0]["title"]
    # the approver is typed anew; the mounting is offered from the model (issue 35), not blank
    assert amended[0]["authorised_by"] == "" and amended[0]["mounting"] == "stud, 2 N m"
    assert amended[0]["customer"] == "Vibration Labs GmbH" and amended[0]["dut_serial"] == "V-0002"
    register = lab.register()
    assert [c.number for c in register] == [*expected, f"ACC-{year}-0004"]
    old, new = register[1], register[3]
    assert (old.state, old.reason) == ("replaced", "customer address corrected")
    assert (new.state, new.replaces, new.reason) == (
        "issued",
        expected[1],
        "customer address corrected",
    )
    assert new.run.run_id == runs["V-0002"] and new.sensor.serial == "V-0002"
    assert (folders["V-0002"] / "certificate.pdf").is_file()  # the old one stays
    assert (folders["V-0002"] / "certificate-2.pdf").is_file()
    assert tab.cell(1, "State") == "replaced" and tab.cell(3, "Replaces") == expected[1]


def test_read_teds_finds_the_sensor_by_its_teds_identity_or_says_why_not(
    window, qtbot, monkeypatch
):
    # the simulated piezo of seed 4 carries TEDS identity 43/1/A1/10004 (sim/teds.py): PZ-0003
    qtbot.mouseClick(window.setup_tab.teds.button, Qt.MouseButton.LeftButton)
    window.setup_tab.teds.wait()
    assert window.setup_tab.dut_id.text() == "PZ-0003"
    assert window.setup_tab.nominal.value() == pytest.approx(10.2, abs=1e-9)
    reason = window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
    assert "TEDS identity 43/1/A1/10004" in reason and "ACME Ltd" in reason
    assert window.setup_tab.templates.names() == ["quick A"]

    window.next_sensor()
    window.setup_tab.dut.setCurrentText("capacitive")  # identity 43/2/A1/10004: not on record
    qtbot.mouseClick(window.setup_tab.teds.button, Qt.MouseButton.LeftButton)
    window.setup_tab.teds.wait()
    assert window.setup_tab.dut_id.text() == "" and window.setup_tab.nominal.value() == 0.0
    reason = window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
    assert "no sensor with TEDS identity &#x27;43/2/A1/10004&#x27;" in reason
    assert "nothing filled in" in reason

    def broken(*_args):
        raise TedsError("TEDS: the basic TEDS checksum does not match")

    monkeypatch.setattr(teds_entry, "read_teds", broken)
    qtbot.mouseClick(window.setup_tab.teds.button, Qt.MouseButton.LeftButton)
    window.setup_tab.teds.wait()
    reason = window.setup_tab.field_marks.reason(window.setup_tab.dut_id)
    assert "TEDS not read: TEDS: the basic TEDS checksum does not match" in reason
    assert "type or scan the serial instead" in reason
    assert window.setup_tab.dut_id.text() == "" and window.setup_tab.teds.button.isEnabled()
    assert (
        window.setup_tab.dut_id.isEnabled() and not window.setup_tab.dut_id.isReadOnly()
    )  # entry by hand


def test_start_refuses_a_reference_standard_past_its_due_date_unless_a_reason_is_given(
    window, qtbot, lab_url, caplog
):
    # the simulated stand's reference is on record (fixture), due 2099-01-01
    assert window.setup_tab.config.reference.id == "REF-8305-SIM"
    window.today = date(2100, 11, 24)
    window.setup_tab.frequencies.setText(LINES_A)
    window.setup_tab.periods.setValue(3)
    qtbot.waitUntil(window.setup_tab.start_button.isEnabled, timeout=30_000)
    asked: list[str] = []

    def cancel(dialog: QInputDialog) -> None:
        asked.append(dialog.labelText())
        dialog.reject()

    modal = Modal().then(QInputDialog, cancel)
    qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert "was due for calibration on 2099-01-01" in asked[0]
    assert window.run_tab.worker is None  # nothing started
    mark = window.setup_tab.field_marks.reason(window.setup_tab.reference_label)
    assert "Start refused" in mark and "2099-01-01" in mark

    def override(dialog: QInputDialog) -> None:
        dialog.setTextValue("  ")  # blank: refused like a cancel
        dialog.accept()

    modal = Modal().then(QInputDialog, override)
    qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert window.run_tab.worker is None

    def reason(dialog: QInputDialog) -> None:
        dialog.setTextValue("recalibration booked for 2026-12-01")
        dialog.accept()

    modal = Modal().then(QInputDialog, reason)
    with qtbot.waitSignal(window.run_finished, timeout=90_000) as blocker:
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
        modal.check()
    assert blocker.args[0].status == "complete"
    assert window.setup_tab.field_marks.reason(window.setup_tab.reference_label) == ""
    assert any(
        "used under the override: recalibration booked for 2026-12-01" in r.getMessage()
        for r in caplog.records
    )
    # within its due date no question is asked (Modal fails on any dialog)
    window.today = date(2024, 6, 1)
    modal = Modal()
    with qtbot.waitSignal(window.run_finished, timeout=90_000):
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    modal.check()


def test_withdraw_from_the_register_needs_a_reason(window, qtbot, lab_url):
    window.setup_tab.frequencies.setText(LINES_A)
    window.setup_tab.periods.setValue(3)
    type_serial(qtbot, window, "PZ-0001")
    window.setup_tab.nominal.setValue(0.0)
    finished = run_now(qtbot, window)
    lab = Lab(open_engine(lab_url))
    number = lab.issue_certificate(
        run_id=str(finished.record.run_id), prepared_by="A. Tech", approved_by="J. Smith"
    ).number
    tab = window.register_tab
    tab.refresh()
    assert tab.select(number) and tab.withdraw_button.isEnabled()
    assert tab.amend_button.isEnabled()
    tab.table.clearSelection()
    window.run_tab.worker = object()  # a run going (no event loop turns before it is undone)
    try:
        assert tab.select(number) and not tab.amend_button.isEnabled()  # no amendment now
    finally:
        window.run_tab.worker = None
    notices: list[str] = []

    def blank(dialog: QInputDialog) -> None:
        dialog.setTextValue("")
        dialog.accept()

    def notice(box: QMessageBox) -> None:
        notices.append(box.text())
        box.accept()

    modal = Modal().then(QInputDialog, blank).then(QMessageBox, notice)
    qtbot.mouseClick(tab.withdraw_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert notices == ["reason: must not be blank"]
    assert lab.register()[0].state == "issued"
    modal = Modal().then(
        QInputDialog, lambda d: (d.setTextValue("wrong sensor mounted"), d.accept())
    )
    qtbot.mouseClick(tab.withdraw_button, Qt.MouseButton.LeftButton)
    modal.check()
    row = lab.register()[0]
    assert (row.state, row.reason) == ("withdrawn", "wrong sensor mounted")
    assert tab.cell(0, "State") == "withdrawn" and tab.cell(0, "Reason") == "wrong sensor mounted"
    assert tab.select(number)
    assert not tab.amend_button.isEnabled() and not tab.withdraw_button.isEnabled()


def test_a_disabled_stop_button_looks_disabled(window, qtbot):
    button = window.run_tab.stop_button
    window.show()
    qtbot.waitExposed(window)
    window.tabs.setCurrentIndex(1)

    def colour() -> tuple[int, int, int]:
        image = button.grab().toImage()
        pixel = image.pixelColor(6, image.height() // 2)
        return pixel.red(), pixel.green(), pixel.blue()

    assert not button.isEnabled()
    r, g, b = colour()
    assert (r, g, b) == (0xE5, 0xE7, 0xE9)  # flat light grey: not the red of a live button
    button.setEnabled(True)
    r, g, b = colour()
    assert (r, g, b) == (0xC0, 0x39, 0x2B)  # red
    button.setEnabled(False)


def test_a_reissue_from_the_register_may_certify_a_later_run_of_the_same_sensor(
    window, qtbot, lab_url
):
    window.setup_tab.frequencies.setText(LINES_A)
    window.setup_tab.periods.setValue(3)
    type_serial(qtbot, window, "PZ-0001")
    first = run_now(qtbot, window)
    second = run_now(qtbot, window)  # e.g. after the sensor was remounted
    lab = Lab(open_engine(lab_url))
    number = lab.issue_certificate(
        run_id=str(first.record.run_id), prepared_by="A. Tech", approved_by="J. Smith"
    ).number
    tab = window.register_tab
    tab.refresh()
    assert tab.select(number)
    offered: list[list[str]] = []

    def choose_run(dialog: QInputDialog) -> None:
        offered.append(list(dialog.comboBoxItems()))
        dialog.setTextValue(str(second.record.run_id))
        dialog.accept()

    def fields(dialog: CertificateDialog) -> None:
        assert str(second.record.run_id) in dialog.title.text()
        dialog.edits["authorised_by"].setText("J. Smith")
        dialog.edits["mounting"].setText("stud, 2 N m, remounted")
        dialog.temperature.setText("22.8")
        press(dialog, QDialogButtonBox.StandardButton.Ok)

    modal = Modal().then(
        QInputDialog, lambda d: (d.setTextValue("reissued on the remounted run"), d.accept())
    )
    modal.then(QInputDialog, choose_run).then(CertificateDialog, fields).then(QMessageBox, yes)
    qtbot.mouseClick(tab.amend_button, Qt.MouseButton.LeftButton)
    modal.check()
    # the certificate's own run offered first, then the sensor's other complete run
    assert offered == [[str(first.record.run_id), str(second.record.run_id)]]
    old, new = lab.register()
    assert (old.number, old.state) == (number, "replaced")
    assert new.replaces == number and new.run.run_id == str(second.record.run_id)
    assert (window.options.out / str(second.record.run_id) / "certificate.pdf").is_file()
