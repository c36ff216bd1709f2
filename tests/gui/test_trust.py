"""The GUI never certifies the wrong run (issue 12, point 11) and keeps a technician's day
readable (issue 17, points 1 and 2)."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QSettings
from PySide6.QtWidgets import QApplication, QDialog, QMessageBox

from app.gui import binding, certificate_dialog, certify, main_window, plots
from app.gui.main_window import MainWindow
from app.gui.worker import copied
from app.procedure import Finished, PeriodBlock, State
from app.records.run_folder import RunFolder
from app.records.run_record import RunRecord
from sim.stand import Fault

SHORT_LINES = "40,80,160,315,630"  # a short plan: quick runs


@pytest.fixture()
def window(qtbot, tmp_path, monkeypatch):
    monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=7)
    qtbot.addWidget(w)
    w.wait_for_plans()
    w.setup_tab.frequencies.setText(SHORT_LINES)
    qtbot.waitUntil(w.setup_tab.start_button.isEnabled, timeout=30_000)
    w.setup_tab.periods.setValue(3)  # the fewest with a stated type A
    w.setup_tab.technician.setText("T. Ester")  # who prepares the certificates
    return w


def run(window, qtbot, dut_id: str, faults: tuple = ()) -> Finished:
    window.options.faults = faults
    window.setup_tab.dut_id.setText(dut_id)
    with qtbot.waitSignal(window.run_finished, timeout=60_000) as blocker:
        window.start_run()
    return blocker.args[0]


class Answers:
    """Stands in for the modal dialogs: fills the certificate dialog, answers questions."""

    def __init__(self, monkeypatch, fields: dict[str, str], temperature: str = "23.0"):
        self.questions: list[str] = []
        self.seen: list[dict[str, str]] = []  # each dialog's fields as it opened
        self.notices: list[str] = []
        answers = self

        def exec_(dialog) -> int:
            answers.seen.append({k: e.text() for k, e in dialog.edits.items()})
            answers.seen[-1]["temperature"] = dialog.temperature.text()
            for key, value in fields.items():
                dialog.edits[key].setText(value)
            dialog.temperature.setText(temperature)
            return QDialog.DialogCode.Accepted

        monkeypatch.setattr(certificate_dialog.CertificateDialog, "exec", exec_)
        monkeypatch.setattr(
            main_window.QMessageBox,
            "question",
            lambda parent, title, text, *a: (
                answers.questions.append(text) or QMessageBox.StandardButton.Yes
            ),
        )
        for kind in ("information", "warning"):
            monkeypatch.setattr(
                main_window.QMessageBox, kind, lambda p, t, text, *a: answers.notices.append(text)
            )


def certificates(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("certificate"))


def test_an_aborted_run_opened_in_the_runs_tab_is_never_certified_nor_another(
    window, qtbot, monkeypatch
):
    good = run(window, qtbot, "SN-GOOD")
    bad = run(window, qtbot, "SN-BAD", (Fault("amplifier-fault", 0.5),))
    assert good.status == "complete" and bad.status == "aborted"
    good_folder = window.options.out / good.record.run_id
    bad_folder = window.options.out / bad.record.run_id
    assert window.runs_tab.state_of(good_folder.name) == "complete"
    assert window.runs_tab.state_of(bad_folder.name) == "aborted"
    answers = Answers(
        monkeypatch,
        {
            "customer": "ACME Ltd",
            "customer_address": "1 Test Street",
            "authorised_by": "J. Smith",
            "mounting": "stud",
        },
    )
    # the complete run was shown last; now the technician opens the aborted one
    row = next(
        r
        for r in range(window.runs_tab.count())
        if bad_folder.name in window.runs_tab.item(r).text()
    )
    item = window.runs_tab.item(row)
    window.runs_tab.runs.itemDoubleClicked.emit(item)
    assert window.tabs.currentIndex() == main_window.RESULTS_TAB
    assert (
        "aborted" in window.results_tab.summary.text()
        and "never certified" in window.results_tab.summary.text()
    )
    assert not window.results_tab.certificate_button.isEnabled()
    assert window.certificate_action() is None
    assert answers.seen == [] and answers.questions == []  # nothing asked for the wrong run
    assert certificates(good_folder) == [] and certificates(bad_folder) == []
    # open the complete one: exactly that run is named once, and certified
    assert window.open_run(good_folder)
    path = window.certificate_action()
    assert path is not None and path.parent == good_folder
    assert len(answers.questions) == 1
    question = answers.questions[0]
    assert good_folder.name in question and "SN-GOOD" in question
    assert good.record.started_utc in question
    assert certificates(bad_folder) == []


def test_the_certificate_dialog_starts_empty_for_every_certificate(window, qtbot, monkeypatch):
    first = run(window, qtbot, "SN-1")
    answers = Answers(
        monkeypatch,
        {
            "customer": "First Customer",
            "customer_address": "1 First Street",
            "authorised_by": "J. Smith",
            "mounting": "stud",
            "dut_model": "Model A",
            "notes": "first sensor's notes",
        },
    )
    assert window.certificate_action() is not None
    second = run(window, qtbot, "SN-2")
    assert window.results_tab.folder.name == second.record.run_id != first.record.run_id
    assert window.certificate_action() is not None
    assert len(answers.seen) == 2
    assert all(value == "" for value in answers.seen[1].values()), answers.seen[1]
    assert "SN-2" in answers.questions[1] and "SN-1" not in answers.questions[1]


def test_modified_and_interrupted_runs_are_listed_so_and_never_certified(
    window, qtbot, monkeypatch
):
    done = run(window, qtbot, "SN-EDIT")
    folder = window.options.out / done.record.run_id
    target = folder / "results.json"
    folder.chmod(0o755)
    target.chmod(0o644)
    target.write_text(target.read_text().replace('"SN-EDIT"', '"SN-FORGED"'))
    dead = RunFolder.create(window.options.out, "died")  # a process that died mid-run
    dead.log("state: acquiring")
    dead.release()
    window.runs_tab.refresh()
    assert window.runs_tab.state_of(folder.name) == "modified"
    assert window.runs_tab.state_of(dead.path.name) == "interrupted"
    answers = Answers(monkeypatch, {"customer": "X", "authorised_by": "Y", "mounting": "Z"})
    for path in (folder, dead.path):
        assert not window.open_run(path)
        assert not window.results_tab.certificate_button.isEnabled()
        assert window.certificate_action() is None
    assert (
        "hash mismatch" in window.results_tab.summary.text()
        or "interrupted" in window.results_tab.summary.text()
    )
    assert answers.questions == [] and certificates(folder) == []


def test_a_run_shown_then_tampered_is_refused_at_the_certificate(window, qtbot, monkeypatch):
    done = run(window, qtbot, "SN-LATE")
    folder = window.options.out / done.record.run_id
    assert window.results_tab.folder == folder
    folder.chmod(0o755)
    (folder / "results.csv").chmod(0o644)
    (folder / "results.csv").write_text("forged\n")
    answers = Answers(monkeypatch, {"customer": "X", "authorised_by": "Y", "mounting": "Z"})
    assert window.certificate_action() is None
    assert answers.questions == [] and "hash mismatch" in answers.notices[-1]
    assert certificates(folder) == []


def test_the_run_tab_is_cleared_when_a_new_run_starts(window, qtbot):
    run(window, qtbot, "SN-A")
    assert window.run_tab.live.wave_ref.getData()[0] is not None  # the first run drew
    assert "coherence" in window.run_tab.coherence.text()
    window.options.paced = True  # the second run is still at its start when we look
    window.setup_tab.periods.setValue(50)
    window.start_run()
    try:
        for curve in window.run_tab.live.curves:
            x, _ = curve.getData()
            assert x is None or len(x) == 0, curve
        assert window.run_tab.coherence.text() == "" and window.run_tab.progress.value() == 0
        assert window.run_tab.meters["reference"].value() == 0
    finally:
        with qtbot.waitSignal(window.run_finished, timeout=60_000):
            window.run_tab.stop()


def test_a_long_abort_message_never_widens_the_window(window, qtbot):
    window.show()
    qtbot.waitExposed(window)
    window.tabs.setCurrentIndex(main_window.RUN_TAB)  # where a run ends
    screen = window.screen().availableGeometry()
    assert window.minimumSizeHint().width() <= screen.width()
    before = window.width()
    reason = (
        " ".join(["the amplifier reported an over-current on output 1"] * 38) + " /" + ("x" * 300)
    )
    assert len(reason) > 2000
    record = RunRecord(run_id=None, status="aborted", abort_reason=reason, final_output_v=0.0)
    window.run_tab.finish(Finished("aborted", reason, None, record))
    for _ in range(5):
        QApplication.processEvents()
    assert window.width() == before <= screen.width()
    assert window.minimumSizeHint().width() <= screen.width()
    assert window.frameGeometry().width() <= screen.width() + 20  # frame: a few pixels
    assert "ABORTED" in window.run_tab.state.text() and reason in window.run_tab.state.toolTip()
    assert reason[:200] in window.run_tab.messages.text()  # the whole message, wrapped below


def test_the_worker_never_draws_and_copies_what_it_queues(window, qtbot, monkeypatch):
    drawn_on: set[str] = set()
    original = plots.LivePlots.show_period  # the tab sets the worker's views through it

    def spy(self, *args):
        drawn_on.add(threading.current_thread().name)
        return original(self, *args)

    monkeypatch.setattr(plots.LivePlots, "show_period", spy)
    assert run(window, qtbot, "SN-T").status == "complete"
    assert drawn_on == {threading.main_thread().name}
    samples = np.ones((2, 8))
    block = PeriodBlock(1, State.ACQUIRING, ("reference", "dut"), samples, np.zeros(8))
    kept = copied(block)
    samples[:] = 5.0  # the procedure reuses its buffer
    assert np.all(kept.samples == 1.0)


def test_a_bad_qt_binding_is_refused_before_the_window_opens(qtbot, monkeypatch, capsys, tmp_path):
    assert binding.known_bad("6.12.0", (3, 11))
    assert not binding.known_bad("6.11.3", (3, 11))
    assert not binding.known_bad("6.12.0", (3, 12))  # None is immortal there
    message = binding.qt_binding_problem("6.12.0", probe=False)
    if binding.known_bad("6.12.0"):  # this interpreter
        assert "none_dealloc" in message and "<6.12" in message
    # the installed binding is a good one (the pin works) and measures clean
    assert binding.qt_binding_problem() is None
    assert not binding.loses_references()
    import PySide6

    from app.gui import run_gui

    monkeypatch.setattr(PySide6, "__version__", "6.12.0")
    monkeypatch.setattr(binding, "IMMORTAL_SINGLETONS", (99, 0))
    code = run_gui(
        stand_file=None,
        out=tmp_path / "runs",
        paced=False,
        seed=0,
        autorun=False,
        screenshot=None,
        quit_after_run=True,
        sim=True,
    )
    assert code == 1 and "none_dealloc" in capsys.readouterr().err


def test_qt_settings_are_isolated_per_test(tmp_path_factory):
    path = QSettings(main_window.ORGANISATION, main_window.APPLICATION).fileName()
    assert str(tmp_path_factory.getbasetemp()) in path or os.environ["XDG_CONFIG_HOME"] in path
    assert not path.startswith(os.path.expanduser("~/.config"))


def test_the_dut_serial_is_not_carried_into_the_next_session(qtbot, tmp_path):
    QSettings(main_window.ORGANISATION, main_window.APPLICATION).setValue("dut_id", "SN-OLD")
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    assert w.setup_tab.dut_id.text() == "" and w.setup_tab.request().dut_id is None
