"""Cyclic garbage is collected on the GUI thread only while the window is open
(app/gui/collector.py): a collection started by a worker's allocations would free Qt objects
off the thread that owns them."""

from __future__ import annotations

import gc
import threading
from pathlib import Path

from PySide6.QtCore import QTimer

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


def test_the_window_runs_with_collection_on_the_gui_thread(qtbot, tmp_path: Path):
    from app.gui import run_gui

    seen: list[bool] = []
    QTimer.singleShot(50, lambda: seen.append(gc.isenabled()))
    gc.enable()
    try:
        code = run_gui(
            stand_file=None,
            out=tmp_path / "runs",
            paced=False,
            seed=0,
            autorun=False,
            screenshot=tmp_path / "shot.png",
            quit_after_run=True,
            sim=True,
        )
        assert gc.isenabled()  # restored when the window closed
    finally:
        gc.disable()
    assert code == 0 and (tmp_path / "shot.png").exists()
    assert seen == [False]  # automatic collection was off while the window was open
