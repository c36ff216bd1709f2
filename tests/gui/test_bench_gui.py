"""bench/gui_responsiveness.py runs to its end in its smoke mode (issue 27: bench scripts are
code too): the stand-in stream drives the real Run tab, the run ends aborted through the tab's
own path with a RunRecord, and the figures are printed."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

ROOT = Path(__file__).resolve().parents[2]


def test_the_gui_benchmark_runs_to_its_end_in_smoke_mode(qtbot, capsys):
    spec = importlib.util.spec_from_file_location(
        "gui_responsiveness", ROOT / "bench" / "gui_responsiveness.py"
    )
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert bench.main(["--smoke"]) == 0
    out = capsys.readouterr().out
    assert "(smoke)" in out and "plot updates per second" in out
    assert "run ended: aborted (stopped by the operator)" in out
    assert "Run tab: ABORTED" in out
