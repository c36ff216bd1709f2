"""The GUI runs through the run service as the CLI does (issue 31 point 1): a stand file's
[plan] is the plan the Setup tab previews and the run runs (the phases computed for those
lines), the records' quick check gates Start and its chain head is in the seal, and the one
indexing function reports the run's control-chart warnings."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from datetime import UTC, date, datetime
from importlib import resources
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from sqlalchemy import text

from app.gui.main_window import MainWindow
from app.records.db.chain_check import quick_check
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import Run, Stand
from app.records.seal import read_seal
from tests.records_db import new_records

ROOT = Path(__file__).resolve().parents[2]
FIVE_LINES = (40.0, 80.0, 160.0, 315.0, 630.0)  # not the piezo preset's 25 lines


def _stand_with_plan(tmp_path: Path) -> Path:
    """The simulated stand's file with a [plan] of FIVE_LINES."""
    stand = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
    path = tmp_path / "five-lines.toml"
    lines = ", ".join(f"{f:g}" for f in FIVE_LINES)
    path.write_text(f"{stand}\n[plan]\nfrequencies_hz = [{lines}]\n", encoding="utf-8")
    return path


def _lab(tmp_path: Path) -> str:
    """Records with the simulated stand's reference standard on record and in date, a
    customer, a model and a check standard CS-1."""
    url = new_records(tmp_path / "lab.sqlite")
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd")
    lab.add_model(
        "Lab",
        "CS",
        nominal_sensitivity=10.0,
        unit="mV/(m/s^2)",
        tolerance_percent=5,
        frequency_min_hz=1,
        frequency_max_hz=10000,
    )
    lab.add_sensor("CS-1", model="CS", owner="ACME Ltd", check_standard=True)
    lab.add_reference(
        "REF-8305-SIM",
        model="8305",
        serial="SIM-0001",
        certificate_number="SIM-CAL-2026-001",
        calibration_date=date(2025, 6, 1),
        due_date=date(2099, 1, 1),
        table=[(160.0, 1.0, 0.005, None)],
    )
    return url


def _window(qtbot, tmp_path: Path, **kwargs) -> MainWindow:
    w = MainWindow(out=tmp_path / "runs", paced=False, seed=3, **kwargs)
    qtbot.addWidget(w)
    w.records.wait()
    w.wait_for_plans()
    w.setup_tab.periods.setValue(4)
    return w


def test_the_stand_files_plan_is_previewed_and_run_with_its_own_phases(qtbot, tmp_path):
    """The defect: GUI Start was refused ("phases: 25 values for 5 lines") with a stand file
    whose [plan] names 5 lines; the preview checked the preset's 25."""
    w = _window(qtbot, tmp_path, stand_file=_stand_with_plan(tmp_path))
    setup = w.setup_tab
    w.wait_for_plans()
    assert setup.preview is not None and setup.preview.lines_hz == FIVE_LINES
    assert setup.peaks.text().startswith("5 lines, 40 to 630 Hz;")
    assert setup.start_button.isEnabled(), setup.checks.text()
    with qtbot.waitSignal(w.run_finished, timeout=120_000) as blocker:
        w.start_run()
    finished = blocker.args[0]
    assert finished.status == "complete", finished.record.abort_reason
    assert tuple(line.nominal_frequency_hz for line in finished.results.lines) == FIVE_LINES
    # the phases the preview optimised for these lines are the ones played
    played = [line["phase_rad"] for line in finished.record.plan["lines"]]
    assert played == pytest.approx(list(setup.preview.plan.phases_rad), abs=1e-12)


def test_the_headless_gui_runs_the_stand_files_plan(tmp_path):
    out = tmp_path / "runs"
    env = {**os.environ, "QT_QPA_PLATFORM": "offscreen"}
    command = [sys.executable, "-m", "app", "gui", "--unpaced", "--autorun"]
    command += ["--quit-after-run", "--stand", str(_stand_with_plan(tmp_path)), "--out", str(out)]
    done = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    stored = json.loads((folder / "results.json").read_text(encoding="utf-8"))
    assert stored["status"] == "complete"
    assert [line["nominal_frequency_hz"] for line in stored["results"]["lines"]] == list(FIVE_LINES)


def test_a_tampered_records_database_refuses_start_with_the_quick_checks_message(qtbot, tmp_path):
    url = _lab(tmp_path)
    with open_engine(url).begin() as connection:  # an edit behind the records' back
        connection.execute(text("UPDATE sensors SET due_date = '2099-01-01'"))
    w = _window(qtbot, tmp_path, db=url)
    assert w.setup_tab.start_button.isEnabled()
    w.start_run()
    assert w.run_tab.worker is None and not list((tmp_path / "runs").glob("*/results.json"))
    shown = w.run_tab.messages.text()
    assert "Start refused: records: sensors" in shown and "accelcal db verify" in shown
    mark = w.setup_tab.field_marks.reason(w.setup_tab.reference_label)
    assert "Start refused: records: sensors" in mark


def test_a_gui_run_with_records_names_the_chain_head_and_is_indexed_with_its_warnings(
    qtbot, tmp_path
):
    url = _lab(tmp_path)
    lab = Lab(open_engine(url), actor="t")
    sensor = lab.sensor("CS-1")
    # five earlier runs of the check standard on this stand near 20 mV/(m/s^2): the simulated
    # piezo's 10.2 is far outside the control limits, a warning of the import
    with lab.session() as session:
        stand = Stand(stand_file_sha256="0" * 64, name="simulated stand, DUT 'piezo', seed 3")
        session.add(stand)
        for i, s in enumerate((20.00, 20.02, 19.99, 20.01, 20.00)):
            session.add(
                Run(
                    run_id=f"cs{i}",
                    manifest_sha256=f"cs{i}".ljust(64, "0"),
                    folder=f"/runs/cs{i}",
                    status="complete",
                    started_utc=datetime(2026, 1, 1 + i, 9, tzinfo=UTC),
                    dut_id="CS-1",
                    stand=stand,
                    sensor_id=sensor.id,
                    reference_frequency_hz=160.0,
                    sensitivity_mv_per_ms2=s,
                    expanded_uncertainty_mv_per_ms2=0.05,
                )
            )
    head = quick_check(open_engine(url))
    w = _window(qtbot, tmp_path, db=url)
    w.setup_tab.dut_id.setText("CS-1")
    w.setup_tab.dut_id.editingFinished.emit()
    w.setup_tab.periods.setValue(4)
    w.setup_tab.frequencies.setText("80,160,315")
    qtbot.waitUntil(w.setup_tab.start_button.isEnabled, timeout=60_000)
    with qtbot.waitSignal(w.run_finished, timeout=120_000) as blocker:
        w.start_run()
    finished = blocker.args[0]
    assert finished.status == "complete", finished.record.abort_reason
    folder = tmp_path / "runs" / str(finished.record.run_id)
    assert read_seal(folder)[0].records_chain_head == head  # the head the gate checked
    w.records.wait_jobs()
    note = w.last_index_note or ""
    assert "records: run indexed" in note
    assert "WARNING check standard CS-1 on simulated stand" in note
    assert f"run {finished.record.run_id}" in note  # the newest point, outside its limits
    assert "WARNING" in w.run_tab.messages.text()
    assert [r.run_id for r in lab.history("CS-1").points][-1] == finished.record.run_id
