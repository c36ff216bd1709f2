"""The window's faces of a run of several DUTs (issue 36 point 4): the Setup tab lists the
fixture's positions (a serial field and a Read TEDS button each), the run goes through the run
service's `start_batch` on the worker and waits for its view as a single run does, the Run tab
draws each DUT's deviation, the Results tab lists a verdict per DUT and shows the one chosen,
and the certificates of every DUT are issued in one confirmation, each through the certificate
service. Simulated stand sim/stand-fixture4.toml (four positions A-D)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QDialogButtonBox, QMessageBox

from app.gui import certify
from app.gui.certificate_dialog import CertificateDialog
from app.gui.main_window import MainWindow
from app.gui.worker import RunWorker
from app.records.run_folder import load_run
from tests.gui.test_day_flow import Modal, press, yes

ROOT = Path(__file__).resolve().parents[2]
FIXTURE4 = ROOT / "sim" / "stand-fixture4.toml"
LINES = "80,160,315,630"


def _window(qtbot, tmp_path: Path, stand: Path | None = FIXTURE4) -> MainWindow:
    w = MainWindow(stand_file=stand, out=tmp_path / "runs", paced=False, seed=5)
    qtbot.addWidget(w)
    w.records.wait()
    w.wait_for_plans()
    w.setup_tab.periods.setValue(4)
    w.setup_tab.frequencies.setText(LINES)
    w.setup_tab.technician.setText("A. Tech")
    return w


def _serials(w: MainWindow, **serials: str) -> None:
    rows = {row.position.name: row for row in w.setup_tab.fixture.rows}
    for position, serial in serials.items():
        rows[position].serial.setText(serial)
        rows[position].serial.editingFinished.emit()
    w.setup_tab.validate()


def _run(qtbot, w: MainWindow, count: int) -> list:
    """Start and wait for every member's `run_finished` (one per DUT); the worker checked to
    wait for its view right after Start, as a single run's does."""
    qtbot.waitUntil(w.setup_tab.start_button.isEnabled, timeout=60_000)
    finished: list = []
    w.run_finished.connect(finished.append)
    w.start_run()
    worker = w.run_tab.worker
    assert isinstance(worker, RunWorker)
    assert not worker.view_ready.is_set()  # the run waits until its plots are painted
    qtbot.waitUntil(lambda: len(finished) == count, timeout=240_000)
    return finished


def test_the_setup_tab_lists_the_fixtures_positions_in_place_of_the_single_serial(qtbot, tmp_path):
    w = _window(qtbot, tmp_path)
    setup = w.setup_tab
    fixture = setup.fixture
    assert [row.position.name for row in fixture.rows] == ["A", "B", "C", "D"]
    assert fixture.widget.isVisibleTo(setup)
    assert not setup.dut_id.isVisibleTo(setup) and not setup.teds.button.isVisibleTo(setup)
    assert setup.form_area.widget() is setup.form  # the scrolling form holds the boxes
    assert fixture.box is not None
    form = fixture.box.layout()
    labels = [form.labelForField(row.serial).text() for row in fixture.rows]
    assert labels[0] == "A: 15 mm, up to 0.1 kg"
    buttons = [row.teds.button.text() for row in fixture.rows if row.teds is not None]
    assert buttons == [f"Read TEDS at {p}" for p in "ABCD"]
    # no serial: nothing to run, Start refused with the reason
    assert not setup.start_button.isEnabled()
    assert "at least one position" in setup.checks.text()
    _serials(w, B="SN-2")
    qtbot.waitUntil(setup.start_button.isEnabled, timeout=60_000)
    assert [(m.position, m.serial) for m in fixture.members()] == [("B", "SN-2")]
    assert setup.run_options().dut_id is None  # the single serial is not the run's
    _serials(w, D="SN-2")
    assert "serial SN-2 at two positions" in setup.checks.text()
    assert not setup.start_button.isEnabled()
    _serials(w, D="SN-4")
    setup.mode.setCurrentText("stepped-sine")
    assert "multisine only" in setup.checks.text()
    setup.mode.setCurrentText("multisine")
    # the simulated stand without a fixture: the single serial and TEDS rows as always
    assert setup.load_stand(None)
    assert not fixture.widget.isVisibleTo(setup) and fixture.rows == []
    assert setup.dut_id.isVisibleTo(setup) and setup.teds.button.isVisibleTo(setup)
    assert setup.fixture.members() == []


def test_read_teds_at_a_position_fills_that_positions_serial_only(qtbot, tmp_path, monkeypatch):
    from app.gui import teds_entry

    seen = []

    def read(stand_file, dut, seed, position=None):
        seen.append(position.name if position is not None else None)
        return teds_entry.TedsRead("43/1/A1/10077", 10.0)

    monkeypatch.setattr(teds_entry, "read_teds", read)
    w = _window(qtbot, tmp_path)
    rows = {row.position.name: row for row in w.setup_tab.fixture.rows}
    rows["C"].teds.read()
    rows["C"].teds.wait()
    assert seen == ["C"]
    # no records open: the identity is said at C's serial field, the others untouched
    assert "TEDS identity 43/1/A1/10077" in w.setup_tab.field_marks.reason(rows["C"].serial)
    assert w.setup_tab.field_marks.reason(rows["A"].serial) == ""


def test_the_simulated_teds_of_each_position_is_its_own_sensor(tmp_path):
    from app.gui.teds_entry import read_teds
    from app.stand import config as stand_config

    fixture = stand_config.load(FIXTURE4).fixture
    assert fixture is not None
    a, b = (read_teds(FIXTURE4, "piezo", 5, fixture.position(p)) for p in "AB")
    assert a.identity != b.identity and a.sensitivity_mv_per_ms2 == b.sensitivity_mv_per_ms2


def test_a_batch_of_three_runs_shows_each_duts_curve_verdict_and_results(
    qtbot, tmp_path, monkeypatch
):
    monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)
    w = _window(qtbot, tmp_path)
    _serials(w, A="SN-1", B="SN-2", D="SN-4")
    finished = _run(qtbot, w, 3)
    assert [f.status for f in finished] == ["complete"] * 3, [
        f.record.abort_reason for f in finished
    ]
    assert [f.record.dut.id for f in finished] == ["SN-1", "SN-2", "SN-4"]
    # Run tab: a curve per DUT, named by position and serial, each with every line
    curves = w.run_tab.live.member_curves
    assert list(curves) == ["A", "B", "D"]
    legend = w.run_tab.live.sens_plot.legend
    assert [label.text for _, label in legend.items] == ["A · SN-1", "B · SN-2", "D · SN-4"]
    for position, curve in curves.items():
        x, y = curve.getData()
        assert x is not None and len(x) == 4, position
    by_position = {f.record.dut.id: f for f in finished}
    x, y = curves["B"].getData()
    expected = [ln.deviation_percent for ln in by_position["SN-2"].results.lines]
    assert list(y) == pytest.approx(expected)
    assert not w.run_tab.live.sens_curve.isVisible()  # the single run's curve: not drawn
    # Results tab: a row per DUT, the first one's results shown
    table = w.results_tab.members
    assert table.isVisibleTo(w.results_tab) and table.rowCount() == 3
    cells = [[table.item(r, c).text() for c in range(3)] for r in range(3)]
    assert [c[:2] for c in cells] == [["A", "SN-1"], ["B", "SN-2"], ["D", "SN-4"]]
    verdicts = [f.results.verdict for f in finished]
    assert [c[2] for c in cells] == verdicts
    assert table.item(1, 3).text().endswith(" Hz") and "%" in table.item(1, 3).text()
    assert w.results_tab.record.dut.id == "SN-1"
    table.choose(2)
    assert w.results_tab.record.dut.id == "SN-4"
    assert w.results_tab.folder == tmp_path / "runs" / str(by_position["SN-4"].record.run_id)
    assert w.results_tab.table.rowCount() == 4
    # each member's folder is a batch member's run (config.json's batch link)
    batch = w.run_tab.batch
    config = json.loads((w.results_tab.folder / "config.json").read_text(encoding="utf-8"))
    assert config["batch"]["batch_id"] == batch.batch_id and config["batch"]["position"] == "D"
    # a run opened from the Runs tab is shown alone
    w.open_stored(tmp_path / "runs" / str(finished[0].record.run_id))
    assert not table.isVisibleTo(w.results_tab)
    assert not w.results_tab.batch_certificate_button.isVisibleTo(w.results_tab)


def test_a_single_dut_run_draws_no_member_curves(qtbot, tmp_path):
    w = _window(qtbot, tmp_path, stand=None)
    _ = _run(qtbot, w, 1)
    assert w.run_tab.live.member_curves == {} and w.run_tab.batch is None
    assert w.run_tab.live.sens_curve.isVisible()
    assert w.run_tab.live.sens_err.isVisible()  # its U drawn, as before several DUTs
    assert w.run_tab.live.phase_plot.titleLabel.text == "Phase"
    assert list(w.run_tab.meters) == ["reference", "dut"]
    x, _y = w.run_tab.live.sens_curve.getData()
    assert x is not None and len(x) == 4
    assert not w.results_tab.members.isVisibleTo(w.results_tab)


def test_certificates_for_all_duts_in_one_confirmation(qtbot, tmp_path, monkeypatch):
    monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)
    w = _window(qtbot, tmp_path)
    _serials(w, A="SN-1", C="SN-3")
    finished = _run(qtbot, w, 2)
    assert [f.status for f in finished] == ["complete"] * 2
    button = w.results_tab.batch_certificate_button
    assert button.isEnabled() and button.text() == "Certificates for all 2 DUTs ..."
    seen: dict[str, str] = {}
    asked: list[str] = []

    def fill(dialog: CertificateDialog) -> None:
        seen["title"] = dialog.title.text()
        seen["serial_enabled"] = str(dialog.edits["dut_serial"].isEnabled())
        dialog.edits["customer"].setText("ACME Ltd")
        dialog.edits["customer_address"].setText("1 Main Street, Springfield")
        dialog.edits["authorised_by"].setText("J. Smith")
        dialog.edits["mounting"].setText("stud, 2 N m")
        dialog.edits["dut_serial"].setText("TYPED")  # never any member's serial
        dialog.temperature.setText("23.0")
        press(dialog, QDialogButtonBox.StandardButton.Ok)

    def confirm(box: QMessageBox) -> None:
        asked.append(box.text())
        yes(box)

    modal = Modal().then(CertificateDialog, fill).then(QMessageBox, confirm)
    qtbot.mouseClick(button, Qt.MouseButton.LeftButton)
    modal.check()
    assert "Certificates of the 2 DUTs of batch" in seen["title"]
    assert seen["serial_enabled"] == "False"
    assert asked == ["Issue 2 certificates, one per DUT (A SN-1, C SN-3)?"]
    pdfs = sorted((tmp_path / "runs").glob("*/certificate*.pdf"))
    assert len(pdfs) == 2
    folders = {pdf.parent.name for pdf in pdfs}
    assert folders == {str(f.record.run_id) for f in finished}
    messages = w.run_tab.messages.text()
    assert "position A: certificate " in messages and "position C: certificate " in messages
    numbers = [
        line.split("certificate ")[1].split(":")[0]
        for line in messages.split("<br/>")
        if line.startswith("position ")
    ]
    assert len(set(numbers)) == 2  # each its own number
    for f in finished:  # each member's run still verifies (the certificate beside it)
        assert load_run(tmp_path / "runs" / str(f.record.run_id)).complete


class _Stand:
    def __init__(self) -> None:
        self.closed = False

    def close(self) -> None:
        self.closed = True


class _Procedure:
    """A run that ends at once, complete."""

    plan = None
    listener = None

    def run(self):
        from app.io.vocabulary import RunStatus
        from app.procedure import Finished
        from app.records.run_record import RunRecord

        record = RunRecord(run_id="lead", status=RunStatus.COMPLETE)
        return Finished(RunStatus.COMPLETE, None, None, record)


def test_the_worker_ends_a_batch_after_the_stand_is_closed_and_queues_its_events():
    from app.procedure import WarningRaised

    stand = _Stand()
    seen: list = []

    def ending(finished, listener):
        seen.append((finished.record.run_id, stand.closed))
        listener(WarningRaised("member B analysed"))
        return "the batch"

    worker = RunWorker.opening(lambda: (_Procedure(), stand), ending)
    worker.start()
    assert worker.join(10)
    assert seen == [("lead", True)]  # after the stand was closed, with the run's Finished
    assert worker.ended == "the batch" and worker.done
    assert any(isinstance(e, WarningRaised) and "member B" in e.text for e in worker.drain())


def test_a_failing_batch_end_keeps_the_runs_own_end(caplog):
    def ending(finished, listener):
        raise RuntimeError("disk gone")

    worker = RunWorker.opening(lambda: (_Procedure(), _Stand()), ending)
    worker.start()
    assert worker.join(10)
    assert worker.finished is not None and worker.finished.record.run_id == "lead"
    assert worker.ended is None and "the other DUTs of the batch" in caplog.text


def test_the_live_views_read_the_first_dut_channel_of_a_batch_block():
    import numpy as np

    from app.gui.live_view import block_view, own_dut
    from app.gui.run_tab import shown_dut
    from dsp.multisine import preset_plan

    channels = ("reference", "dut.A", "dut.B", "drive")
    assert own_dut(channels) == "dut.A" and own_dut(("reference", "dut", "drive")) == "dut"
    assert shown_dut("dut", channels) == "dut.A" and shown_dut("reference", channels) == "reference"
    plan = preset_plan("piezo")
    n = plan.period_samples
    samples = np.vstack([np.full(n, 0.1), np.full(n, 0.3), np.full(n, 0.7), np.zeros(n)])
    view = block_view(samples, channels, plan, 300)
    assert view.peaks_v["dut"] == pytest.approx(0.3)  # dut.A, never dut.B
