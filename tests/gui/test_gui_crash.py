"""A GUI that dies mid-run costs no record: the folder stays readable, listed "interrupted"."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.main_window import MainWindow
from app.io.hdf5 import read_recording
from app.records.run_folder import inspect_run

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.long
def test_a_killed_gui_leaves_a_readable_run_listed_as_interrupted(qtbot, tmp_path):
    out = tmp_path / "runs"
    env = dict(os.environ, QT_QPA_PLATFORM="offscreen", PYTHONPATH=str(ROOT))
    gui = subprocess.Popen(
        [sys.executable, "-m", "app", "gui", "--sim", "--autorun", "--out", str(out)],
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 90
        folder = None
        while time.monotonic() < deadline:  # paced: wait for acquired periods on disk
            folders = list(out.iterdir()) if out.is_dir() else []
            if folders and "state: acquiring" in _log(folders[0]):
                folder = folders[0]
                break
            assert gui.poll() is None, f"the GUI ended early: exit {gui.returncode}"
            time.sleep(0.2)
        assert folder is not None, "no run reached acquisition"
        assert inspect_run(folder).state == "running"  # killed in acquisition: no fixed wait
    finally:
        gui.send_signal(signal.SIGKILL)  # as a crash would: no handler, no clean-up
        gui.wait(10)
    check = inspect_run(folder)
    assert check.state == "interrupted" and not check.certifiable
    recording = read_recording(folder / "recording.h5")
    assert recording.periods >= 1 and recording.status == "incomplete"
    window = MainWindow(out=out, paced=False)
    qtbot.addWidget(window)
    assert window.runs_tab.state_of(folder.name) == "interrupted"
    assert not window.open_run(folder)
    assert not window.results_tab.certificate_button.isEnabled()


def _log(folder: Path) -> str:
    try:
        return (folder / "run.log").read_text(encoding="utf-8")
    except OSError:
        return ""


def test_without_xvfb_the_soak_test_skips_but_fails_under_ci(monkeypatch):
    from tests.gui import test_soak

    monkeypatch.setattr(test_soak.shutil, "which", lambda name: None)
    monkeypatch.setenv("CI", "true")
    with pytest.raises(pytest.fail.Exception, match="make xvfb"):
        next(test_soak.xvfb_server())
    monkeypatch.delenv("CI")
    with pytest.raises(pytest.skip.Exception, match="make xvfb"):
        next(test_soak.xvfb_server())
