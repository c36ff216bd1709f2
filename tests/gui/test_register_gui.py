"""The window's register (issue 24 points 1 and 7): a run gets one certificate; the certificate
dialog says so and offers the amendment; the Register tab opens each entry's PDF (checked by
its SHA-256). Modal dialogs answered as a person would (tests.gui.test_day_flow.Modal)."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QInputDialog, QMessageBox

from app.gui import register_tab
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from tests.gui import test_day_flow as day
from tests.gui.test_day_flow import LINES_A, Modal, certificate_steps, run_now, type_serial, yes

lab_url = day.lab_url  # the day's records and window (fixtures)
window = day.window


def no(box: QMessageBox) -> None:
    box.button(QMessageBox.StandardButton.No).click()


def test_a_second_certificate_of_a_run_is_offered_as_an_amendment_and_pdfs_open(
    window, qtbot, lab_url, monkeypatch
):
    opened: list[str] = []
    monkeypatch.setattr(
        register_tab.QDesktopServices, "openUrl", lambda url: opened.append(url.toLocalFile())
    )
    window.setup_tab.frequencies.setText(LINES_A)
    window.setup_tab.periods.setValue(3)
    type_serial(qtbot, window, "PZ-0001")
    finished = run_now(qtbot, window)
    folder = window.options.out / str(finished.record.run_id)
    seen: list[dict[str, str]] = []
    modal = Modal()
    certificate_steps(modal, seen, approver="J. Smith", same_person="a. tech")
    modal.then(QMessageBox, yes)
    qtbot.mouseClick(window.results_tab.certificate_button, Qt.MouseButton.LeftButton)
    modal.check()
    lab = Lab(open_engine(lab_url))
    (first,) = lab.register()
    told: list[str] = []
    # again: the window says the run has a certificate; declined, nothing is issued
    modal = Modal().then(QMessageBox, lambda box: (told.append(box.text()), no(box)))
    qtbot.mouseClick(window.results_tab.certificate_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert f"already has certificate {first.number}" in told[0]
    assert len(lab.register()) == 1
    # accepted: the reason, the dialog, the confirmation; the amendment replaces it
    modal = Modal().then(QMessageBox, yes)
    modal.then(QInputDialog, lambda d: (d.setTextValue("address corrected"), d.accept()))
    certificate_steps(modal, seen, approver="J. Smith", same_person="a. tech")
    modal.then(QMessageBox, yes)
    qtbot.mouseClick(window.results_tab.certificate_button, Qt.MouseButton.LeftButton)
    modal.check()
    rows = [(c.number, c.state, c.replaces, c.reason) for c in lab.register()]
    assert rows[0][:2] == (first.number, "replaced") and rows[0][3] == "address corrected"
    assert rows[1][1:3] == ("issued", first.number)
    assert (folder / "certificate-2.pdf").is_file()
    tab = window.register_tab
    tab.refresh()
    assert tab.select(rows[1][0]) and tab.open_button.isEnabled()
    del opened[:]  # (issuing opened each new PDF too)
    qtbot.mouseClick(tab.open_button, Qt.MouseButton.LeftButton)
    assert opened == [str((folder / "certificate-2.pdf").resolve())]
    # a file that is not the register's is not opened
    tab.files[rows[1][0]] = (tab.files[rows[1][0]][0], "0" * 64)
    modal = Modal().then(QMessageBox, lambda box: (told.append(box.text()), box.accept()))
    assert tab.open_pdf() is None
    modal.check()
    assert "not the register's file" in told[-1] and len(opened) == 1
