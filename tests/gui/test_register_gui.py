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
    # the Technician field is the run's technician (config.json, results.json; issue 27)
    assert finished.record.technician == "A. Tech"
    assert '"technician": "A. Tech"' in (folder / "config.json").read_text()
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


def test_close_review_asks_confirmed_or_amended_and_a_reason(
    window, qtbot, lab_url, complete_run, tmp_path
):
    """Issue 27: a certificate under review says so in the Register tab; "Close review ..."
    asks how it is decided (amended: by the certificate that replaces it, refused while none
    does) and why, and closes it through the records (who: the window's records actor)."""
    import shutil

    from app.records.db.reviews import impact_subject

    lab = Lab(open_engine(lab_url), actor="qm")
    lab.add_sensor("SN-42", model="PZ-10", owner="ACME Ltd")
    run = tmp_path / "indexed" / complete_run.name
    shutil.copytree(complete_run, run)
    assert lab.import_runs(run).imported
    a = lab.issue_certificate(run_id=run.name, prepared_by="A. Tech", approved_by="J. Smith")
    subject = impact_subject("SIM-0001")
    assert lab.open_review(a.number, subject=subject, reason="impact: to amend or confirm")
    tab = window.register_tab
    tab.refresh()
    assert tab.select(a.number)
    assert tab.cell(tab.table.currentRow(), "Review") == f"under review ({subject})"
    assert tab.review_button.isEnabled()
    told: list[str] = []
    amend = lambda d: (d.setTextValue(register_tab.AMEND), d.accept())  # noqa: E731
    # amended, but nothing replaces it yet: refused by name, nothing written
    modal = Modal().then(QInputDialog, amend)
    modal.then(QMessageBox, lambda box: (told.append(box.text()), box.accept()))
    qtbot.mouseClick(tab.review_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert f"amended by: no certificate replaces {a.number} yet" in told[-1]
    assert lab.reviews(open_only=True)
    b = lab.issue_certificate(
        run_id=run.name,
        prepared_by="A. Tech",
        approved_by="J. Smith",
        replaces=a.number,
        reason="sensitivity corrected",
    )
    tab.refresh()
    assert tab.select(a.number)
    # a blank reason is refused by name; then amended by B with a reason
    modal = Modal().then(QInputDialog, amend)
    modal.then(QInputDialog, lambda d: (d.setTextValue("  "), d.accept()))
    modal.then(QMessageBox, lambda box: (told.append(box.text()), box.accept()))
    qtbot.mouseClick(tab.review_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert told[-1] == "reason: must not be blank" and lab.reviews(open_only=True)
    modal = Modal().then(QInputDialog, amend)
    modal.then(QInputDialog, lambda d: (d.setTextValue("2 % change: amended"), d.accept()))
    qtbot.mouseClick(tab.review_button, Qt.MouseButton.LeftButton)
    modal.check()
    (closed,) = lab.reviews(number=a.number)
    assert (closed.outcome, closed.amended_by, closed.close_reason) == (
        "amended",
        b.number,
        "2 % change: amended",
    )
    assert tab.select(a.number) and not tab.review_button.isEnabled()
    assert tab.cell(tab.table.currentRow(), "Review") == f"amended by {b.number}"
    # the amendment under review in turn: confirmed
    assert lab.open_review(b.number, subject=subject, reason="check the amendment")
    tab.refresh()
    assert tab.select(b.number) and tab.review_button.isEnabled()
    modal = Modal().then(QInputDialog, lambda d: (d.setTextValue(register_tab.CONFIRM), d.accept()))
    modal.then(QInputDialog, lambda d: (d.setTextValue("stands"), d.accept()))
    qtbot.mouseClick(tab.review_button, Qt.MouseButton.LeftButton)
    modal.check()
    assert [r.outcome for r in lab.reviews(number=b.number)] == ["confirmed"]
    assert tab.select(b.number) and tab.cell(tab.table.currentRow(), "Review") == "confirmed"
