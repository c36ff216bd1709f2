"""The window at the sizes a lab's screens have (issue 27): the default size gives every tab
what its layout asks for, the Results table of a 25-line run needs no horizontal scrolling at
1366 x 768, the run state is not cut there, and no tab shows empty charts."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QSize
from PySide6.QtWidgets import QApplication

from app.gui import main_window
from app.gui.main_window import MainWindow


def settle() -> None:
    for _ in range(5):
        QApplication.processEvents()


def test_the_default_size_gives_the_setup_tab_all_it_asks_for(qtbot, tmp_path):
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    w.wait_for_plans()
    size = w.default_size()
    assert size.width() >= main_window.DEFAULT_SIZE.width()
    w.resize(size)
    w.show()
    qtbot.waitExposed(w)
    settle()
    setup = w.setup_tab
    hint = setup.sizeHint()
    assert setup.width() >= hint.width() and setup.height() >= hint.height()
    # and at 1366 x 768 (a laptop): still nothing under what the Setup tab's layout asks
    w.resize(1366, 768)
    settle()
    assert setup.width() >= hint.width() and setup.height() >= hint.height()


def test_at_1366_by_768_results_fit_unscrolled_and_the_state_is_whole(
    qtbot, tmp_path, complete_run
):
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    w.resize(QSize(1366, 768))
    w.show()
    qtbot.waitExposed(w)
    results = w.results_tab
    assert not results.charts.showing_chart and "No results yet" in results.charts.message.text()
    assert not w.run_tab.live.widget.showing_chart
    assert w.open_run(complete_run)
    settle()
    assert results.charts.showing_chart
    table = results.table
    assert table.rowCount() == 25
    assert table.horizontalScrollBar().maximum() == 0  # every column in view
    assert all(not table.isColumnHidden(c) for c in range(table.columnCount()))
    header = table.horizontalHeaderItem(1).text()
    assert header == "S\nmV/(m/s²)"
    w.tabs.setCurrentIndex(main_window.RUN_TAB)
    settle()
    state = w.run_tab.state
    text = "equalising: closed loop, tolerance 1 %"
    state.setText(text)
    settle()
    assert super(type(state), state).text() == text and state.toolTip() == ""


def test_the_technician_starts_empty_and_is_remembered_never_the_login_name(qtbot, tmp_path):
    first = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(first)
    assert first.setup_tab.technician.text() == ""
    assert "remembered" in first.setup_tab.technician.placeholderText()
    first.setup_tab.technician.setText("B. Tech")
    first.setup_tab.technician.editingFinished.emit()
    second = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(second)
    assert second.setup_tab.technician.text() == "B. Tech"


def test_optimising_phases_is_progress_not_an_error_and_holds_start(qtbot, tmp_path):
    from concurrent.futures import Future

    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    setup = w.setup_tab
    pending: Future = Future()  # a plan still being optimised
    original = setup.plans.ask
    setup.plans.ask = lambda *_a: pending  # type: ignore[method-assign]
    blocking = setup.validate()
    checks = setup.checks.text()
    assert "optimising the multisine phases" in checks
    assert "✖" not in checks and "#c0392b" not in checks  # not shown as an error
    assert not setup.start_button.isEnabled() and blocking  # but Start waits for it
    assert setup.field_marks.marked() == {}  # and no field is marked for it
    setup.plans.ask = original  # type: ignore[method-assign]
    w.wait_for_plans()
    assert setup.start_button.isEnabled() and "the plan can run" in setup.checks.text()
