"""Issue 32 point 5 in the GUI: a line outside the reference's calibrated range shows "n/s"
in every value, U and verdict cell of the Results table (its reason in the tooltip) and is
left out of the charts: no number with U."""

from __future__ import annotations

import dataclasses
import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from app.gui.results_tab import ResultsTab
from app.records.run_record import RunRecord
from dsp.calibration import not_stated_line


def test_the_results_table_shows_n_s_for_a_line_not_stated(qtbot, complete_run):
    record = RunRecord.from_json((complete_run / "results.json").read_text())
    results = record.results_object()
    assert results is not None
    why = "outside the reference's calibrated range (20-8000 Hz)"
    last = len(results.lines) - 1
    lines = (*results.lines[:last], not_stated_line(results.lines[last], why))
    tab = ResultsTab()
    qtbot.addWidget(tab)
    tab.show_results(dataclasses.replace(results, lines=lines), record, None)
    cells = [tab.table.item(last, c).text() for c in range(tab.table.columnCount() - 1)]
    assert cells[0] == f"{results.lines[last].nominal_frequency_hz:g}"
    assert set(cells[1:]) == {"n/s"}
    assert tab.table.item(last, 0).toolTip() == f"not stated: {why}"
    stated = [tab.table.item(0, c).text() for c in range(1, 4)]
    assert "n/s" not in stated and all(stated)
