"""The technician's window through pytest-qt (QT_QPA_PLATFORM=offscreen)."""

from __future__ import annotations

import os

import numpy as np
import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import Qt

from app.gui.main_window import MainWindow
from app.procedure.run import RunRequest, execute
from app.records.run_folder import load_run


@pytest.fixture()
def window(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=4)
    qtbot.addWidget(w)
    w.wait_for_plans()
    return w


def test_a_run_through_the_gui_equals_the_same_run_through_the_cli(window, qtbot, tmp_path):
    window.setup_tab.dut.setCurrentText("piezo")
    window.setup_tab.periods.setValue(4)
    assert window.setup_tab.start_button.isEnabled()
    with qtbot.waitSignal(window.run_finished, timeout=60_000) as blocker:
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    finished = blocker.args[0]
    assert finished.status == "complete"
    assert (
        window.tabs.currentIndex() == 2
        and "Reference sensitivity at 160 Hz" in window.results_tab.summary.text()
    )
    cli = execute(
        RunRequest(
            dut="piezo",
            periods=4,
            seed=4,
            tolerance_percent=5.0,
            preset="piezo",
            out=tmp_path / "cli",
            # the GUI's run stored its response: the CLI's starts from the same (empty) state
            response_store=tmp_path / "cli-responses",
        )
    )
    assert finished.record.stand_response["source"] == "identified"
    assert cli.record.stand_response["source"] == "identified"
    for a, b in zip(finished.results.lines, cli.results.lines, strict=True):
        assert a.sensitivity_mv_per_ms2 == pytest.approx(b.sensitivity_mv_per_ms2, rel=1e-12)
        assert a.phase_deg == pytest.approx(b.phase_deg, abs=1e-9)
    assert window.results_tab.table.rowCount() == 25
    assert window.results_tab.table.item(12, 1).text() in window.results_tab.summary.text()
    assert window.runs_tab.count() == 1 and "complete" in window.runs_tab.item(0).text()


def test_start_is_disabled_for_a_plan_over_the_shakers_limits(window):
    window.setup_tab.preset.setCurrentText("capacitive")
    window.setup_tab.level.setValue(8.0)
    assert not window.setup_tab.start_button.isEnabled()
    assert (
        "displacement" in window.setup_tab.checks.text()
        and "exceeds" in window.setup_tab.checks.text()
    )
    assert "displacement" in window.setup_tab.start_button.toolTip()
    window.setup_tab.level.setValue(5.0)
    assert window.setup_tab.start_button.isEnabled()
    assert "the plan can run" in window.setup_tab.checks.text()
    window.setup_tab.frequencies.setText("10,20")
    assert not window.setup_tab.start_button.isEnabled()
    window.setup_tab.frequencies.setText("")
    assert (
        window.setup_tab.request().target_type_a is None
        and window.setup_tab.request().max_acquisition_s is None
    )
    window.setup_tab.target.setValue(0.2)
    window.setup_tab.max_time.setValue(30)
    assert window.setup_tab.request().target_type_a == pytest.approx(0.002)
    assert window.setup_tab.request().max_acquisition_s == 30.0


def test_closing_the_window_during_a_run_fades_out_to_0_v(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=True, seed=1)
    qtbot.addWidget(w)
    w.wait_for_plans()
    w.start_run()
    qtbot.waitUntil(
        lambda: "acquiring" in w.run_tab.state.text() or "equalising" in w.run_tab.state.text(),
        timeout=30_000,
    )
    stand = w.run_tab.worker.stand
    w.close()
    assert w.run_tab.worker is None
    assert stand.daq.output_v == 0.0 and stand.daq.output.stopped
    folder = next((tmp_path / "runs").iterdir())
    record = load_run(folder)
    assert record.status == "aborted" and record.abort_reason == "window closed"
    assert record.final_output_v == 0.0


def test_emergency_stop_zeroes_at_once(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=True, seed=2)
    qtbot.addWidget(w)
    w.show()
    qtbot.waitExposed(w)
    w.activateWindow()
    w.wait_for_plans()
    w.start_run()
    qtbot.waitUntil(
        lambda: "identifying" in w.run_tab.state.text() or "equalising" in w.run_tab.state.text(),
        timeout=30_000,
    )
    stand = w.run_tab.worker.stand
    with qtbot.waitSignal(w.run_finished, timeout=30_000) as blocker:
        qtbot.keyClick(w, Qt.Key.Key_Escape)
    assert blocker.args[0].abort_reason == "emergency stop"
    assert stand.daq.output_v == 0.0
    assert "ABORTED" in w.run_tab.state.text()


def test_from_an_empty_window_to_a_certificate(window, qtbot, monkeypatch):
    from app.certificate import CertificateInfo
    from app.gui import certify, main_window

    monkeypatch.setattr(certify.QDesktopServices, "openUrl", lambda url: True)
    window.setup_tab.dut_id.setText("SN-GUI-1")
    window.setup_tab.technician.setText("A. Tech")  # who prepares it (the service's rule)
    window.setup_tab.periods.setValue(3)
    with qtbot.waitSignal(window.run_finished, timeout=60_000):
        window.start_run()
    folder = window.results_tab.folder
    assert folder is not None and folder.parent == window.options.out
    path = window.issue_certificate(
        folder,
        CertificateInfo(
            customer="ACME Ltd",
            authorised_by="J. Smith",
            temperature_c=23.0,
            mounting="stud",
            customer_address="1 Test Street, 00-001 Testtown",
        ),
    )
    assert path is not None and path.exists() and path.name == "certificate.pdf"
    assert "Certificate:" in window.results_tab.summary.text()
    refused = []
    monkeypatch.setattr(main_window.QMessageBox, "warning", lambda *a: refused.append(a[2]))
    assert window.issue_certificate(folder, CertificateInfo(customer="ACME Ltd")) is None
    assert "never overwritten" in refused[0] or "missing" in refused[0]


def test_a_fault_shows_its_message_and_the_window_stays_usable(qtbot, tmp_path):
    from sim.stand import Fault

    w = MainWindow(
        out=tmp_path / "runs", paced=False, seed=3, faults=(Fault("amplifier-fault", 10.0),)
    )
    qtbot.addWidget(w)
    w.wait_for_plans()
    with qtbot.waitSignal(w.run_finished, timeout=60_000) as blocker:
        w.start_run()
    assert blocker.args[0].status == "aborted"
    assert (
        "AmplifierFaultError" in w.run_tab.messages.text()
        and "Check the power amplifier" in w.run_tab.messages.text()
    )
    assert "ABORTED" in w.run_tab.state.text() and w.setup_tab.start_button.isEnabled()
    w.options.faults = ()
    with qtbot.waitSignal(w.run_finished, timeout=60_000) as blocker:
        w.start_run()
    assert blocker.args[0].status == "complete"


def test_custom_lines_are_checked_as_typed_and_run(window, qtbot):
    window.setup_tab.frequencies.setText("10,abc")
    assert (
        not window.setup_tab.start_button.isEnabled()
        and "is not a number" in window.setup_tab.checks.text()
    )
    window.setup_tab.frequencies.setText("20,40,80")
    assert "reference frequency 160 Hz: not among the lines" in window.setup_tab.checks.text()
    window.setup_tab.frequencies.setText("20,25,...,315")
    qtbot.waitUntil(window.setup_tab.start_button.isEnabled, timeout=20_000)
    window.setup_tab.periods.setValue(3)
    with qtbot.waitSignal(window.run_finished, timeout=60_000) as blocker:
        window.start_run()
    results = blocker.args[0].results
    ran = [ln.nominal_frequency_hz for ln in results.lines]
    assert ran == [
        20.0,
        25.0,
        31.5,
        40.0,
        50.0,
        63.0,
        80.0,
        100.0,
        125.0,
        160.0,
        200.0,
        250.0,
        315.0,
    ]
    assert window.results_tab.budget.rowCount() >= 4  # type A, the budget, combined, expanded
    assert window.results_tab.result_mag.listDataItems()  # the band and the curve are drawn


@pytest.mark.long
def test_stop_fades_out_to_0_v_and_keeps_an_aborted_run(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=True, seed=5)
    qtbot.addWidget(w)
    w.wait_for_plans()
    w.setup_tab.periods.setValue(100)  # a long acquisition: Stop comes first
    w.start_run()
    qtbot.waitUntil(lambda: "acquiring" in w.run_tab.state.text(), timeout=40_000)
    # the first live estimate comes once MIN_PERIODS periods are in (maybe a few periods on)
    qtbot.waitUntil(lambda: "coherence" in w.run_tab.coherence.text(), timeout=40_000)
    stand = w.run_tab.worker.stand
    with qtbot.waitSignal(w.run_finished, timeout=30_000) as blocker:
        qtbot.mouseClick(w.run_tab.stop_button, Qt.MouseButton.LeftButton)
    finished = blocker.args[0]
    assert finished.status == "aborted" and finished.abort_reason == "stopped by the operator"
    assert stand.daq.output_v == 0.0 and finished.record.final_output_v == 0.0
    assert stand.daq.output.periods[-1].last_v == 0.0  # the fade-out's last sample
    assert "coherence" in w.run_tab.coherence.text()


def test_a_real_stand_file_loads_and_start_says_what_is_missing(
    window, qtbot, monkeypatch, tmp_path
):
    from pathlib import Path

    from app.gui import main_window

    example = Path(__file__).resolve().parents[2] / "examples" / "stand-pxi6251.toml"
    shown = []
    monkeypatch.setattr(main_window.QMessageBox, "warning", lambda *a: shown.append(a[2]))
    assert window.setup_tab.load_stand(example)
    assert "nidaqmx" in window.setup_tab.stand_label.text()
    window.start_run()  # the stand opens on the run worker's thread: refused there
    assert window.run_tab.procedure is None  # nothing started, nothing moved
    qtbot.waitUntil(lambda: bool(shown) and window.run_tab.worker is None, timeout=20_000)
    assert "NI-DAQmx is not installed" in shown[-1]
    assert "NI-DAQmx is not installed" in window.run_tab.messages.text()
    assert window.setup_tab.start_button.isEnabled()  # Start again, once the driver is in
    bad = tmp_path / "bad.toml"
    bad.write_text(example.read_text().replace('backend = "nidaqmx"', 'backend = "x"'))
    assert not window.setup_tab.load_stand(bad)
    assert "daq.backend" in shown[-1]
    assert window.setup_tab.load_stand(None) and "simulated" in window.setup_tab.stand_label.text()


def test_percent_and_degree_axes_show_their_own_unit_not_a_scale_factor(window, qtbot):
    """A deviation of +-0.5 % is labelled "%" with ticks 0.5, never "% (x0.001)" with 500."""
    plots = (  # (tab index, plot): a label is scaled only while it is visible
        (2, window.results_tab.result_mag),
        (2, window.results_tab.result_phase),
        (1, window.run_tab.live.sens_plot),
        (1, window.run_tab.live.phase_plot),
    )
    window.show()
    for tab, plot in plots:
        window.tabs.setCurrentIndex(tab)
        plot.plot([1.0, 2.0, 3.0], [0.7, -0.7, 0.2])
        plot.enableAutoRange()
        qtbot.wait(50)
        assert plot.getAxis("left").label.isVisible()
        axis = plot.getAxis("left")
        assert axis.autoSIPrefixScale == 1.0
        assert "x0.001" not in axis.labelString() and "0.001" not in axis.labelString()


def test_the_run_tab_ends_on_the_last_steady_period_not_the_fade_out(window, qtbot):
    """The fade-out lasts 4 cycles of the lowest line (0.1 s at 40 Hz) and then plays zeros:
    the Last period plot keeps the last acquired period, which moves over its whole length."""
    window.setup_tab.frequencies.setText("40,80,160,315,630")
    window.setup_tab.periods.setValue(3)
    window.wait_for_plans()
    qtbot.waitUntil(window.setup_tab.start_button.isEnabled, timeout=10_000)
    with qtbot.waitSignal(window.run_finished, timeout=60_000) as blocker:
        qtbot.mouseClick(window.setup_tab.start_button, Qt.MouseButton.LeftButton)
    assert blocker.args[0].status == "complete"
    qtbot.wait(200)  # the 25 Hz drawing timer
    _, y = window.run_tab.live.wave_ref.getData()
    assert y is not None and y.size > 0
    half = y.size // 2
    assert np.max(np.abs(y[half:])) > 0.5 * np.max(np.abs(y[:half]))
