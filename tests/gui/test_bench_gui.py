"""bench/gui_responsiveness.py runs to its end in its smoke mode (issue 27: bench scripts are
code too): a paced simulated run started as Start does drives the real window, the run ends
aborted through the tab's own path, and the figures are printed against the idle window."""

from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

ROOT = Path(__file__).resolve().parents[2]


def test_the_gui_benchmark_runs_to_its_end_in_smoke_mode(qtbot, capsys, monkeypatch):
    spec = importlib.util.spec_from_file_location(
        "gui_responsiveness", ROOT / "bench" / "gui_responsiveness.py"
    )
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, bench)  # its dataclasses look their module up
    spec.loader.exec_module(bench)
    # the bench sets these for its own process; in the suite's worker they must not outlive it
    # (a data folder left set made later tests in the worker find its stored stand response)
    from app.gui import worker as run_worker

    monkeypatch.setattr(run_worker, "GIL_SWITCH_S", run_worker.GIL_SWITCH_S)
    data_dir, switch = os.environ.get("ACCELCAL_DATA_DIR"), sys.getswitchinterval()
    try:
        assert bench.main(["--smoke"]) == 0
    finally:
        sys.setswitchinterval(switch)
        if data_dir is None:
            os.environ.pop("ACCELCAL_DATA_DIR", None)
        else:
            os.environ["ACCELCAL_DATA_DIR"] = data_dir
    out = capsys.readouterr().out
    assert "(smoke)" in out and "updates per second" in out and "live / idle" in out
    assert "longest main-thread gap" in out and "p99 main-thread gap" in out
    assert "load average (1, 5, 15 min) at start" in out and "Qt platform: offscreen" in out
    assert "targets (>= 30 updates/s, longest stall < 50 ms): " in out
    # the longest stall's phase of the run and the worker's CPU in it (issue 34 point 6)
    assert "longest live stall: " in out and "in the run's phase '" in out
    assert "the run worker's CPU within it" in out and "longest stall per phase: " in out
    assert "GIL switch interval during the run: 0.5 ms" in out
    assert "run ended: aborted (stopped by the operator)" in out
    assert "Run tab: ABORTED" in out
