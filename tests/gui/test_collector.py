"""Cyclic garbage is collected on the GUI thread only while the window is open
(app/gui/collector.py): a collection started by a worker's allocations would free Qt objects
off the thread that owns them."""

from __future__ import annotations

import gc
import os
import subprocess
import sys
import threading
from pathlib import Path

from app.gui.collector import collected_on_gui_thread


class _Cycle:
    """Garbage only a collection frees; records the thread that freed it."""

    def __init__(self, freed_in: list[str]) -> None:
        self.me, self.freed_in = self, freed_in

    def __del__(self) -> None:
        self.freed_in.append(threading.current_thread().name)


def _allocate_in_a_worker() -> list[list[object]]:
    """Far more new container objects than the generation-0 threshold (700), kept: with
    automatic collection on, this thread starts collections."""
    kept: list[list[object]] = []

    def churn() -> None:
        kept.extend([] for _ in range(20 * gc.get_threshold()[0]))

    worker = threading.Thread(target=churn, name="run-worker")
    worker.start()
    worker.join()
    return kept


def test_garbage_is_collected_by_the_gui_thread_not_by_the_worker_that_allocates(qtbot):
    freed_in: list[str] = []
    gc.enable()  # as in the application (tests/conftest.py turns it off for Qt tests)
    try:
        with collected_on_gui_thread(interval_s=0.02):
            assert not gc.isenabled()
            _Cycle(freed_in)
            kept = _allocate_in_a_worker()
            assert freed_in == []  # the worker's allocations started no collection
            qtbot.waitUntil(lambda: bool(freed_in), timeout=2000)
            del kept
        assert freed_in == [threading.main_thread().name]
        assert gc.isenabled()  # as it was before the block
    finally:
        gc.disable()


def test_without_it_the_worker_would_collect_the_garbage(qtbot):
    """The control: automatic collection frees the cycle in the allocating worker's thread."""
    freed_in: list[str] = []
    gc.enable()
    try:
        gc.collect()
        _Cycle(freed_in)
        _allocate_in_a_worker()
    finally:
        gc.disable()
    assert freed_in == ["run-worker"]


_WINDOW = """
import gc, sys
from pathlib import Path
from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QApplication
from app.gui import run_gui

app = QApplication(sys.argv[:1])
seen = []
QTimer.singleShot(50, lambda: seen.append(gc.isenabled()))
code = run_gui(stand_file=None, out=Path(sys.argv[1]) / "runs", paced=False, seed=0,
               autorun=False, screenshot=Path(sys.argv[1]) / "shot.png", quit_after_run=True,
               sim=True)
print("code", code, "during", seen, "after", gc.isenabled())
"""


def test_the_window_runs_with_collection_on_the_gui_thread(tmp_path: Path):
    """In a process of its own, as `accelcal gui` runs (an application that has quit would
    leave this test process's later Qt tests without an event loop)."""
    done = subprocess.run(
        [sys.executable, "-c", _WINDOW, str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "QT_QPA_PLATFORM": "offscreen"},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    # automatic collection was off while the window was open, and on again after it closed
    assert "code 0 during [False] after True" in done.stdout
    assert (tmp_path / "shot.png").exists()
