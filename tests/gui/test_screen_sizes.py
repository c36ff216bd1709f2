"""The technician's screen at the sizes a lab's screens have (issue 36 point 6): a restored
window never comes up smaller than its content needs and nothing on the Setup tab overlaps;
the Results tab's table and chart titles readable at 1366 x 768 and 1920 x 1080; the sensors
tables' columns and the certificate dialog's fields show typical content whole; the history
chart's axis shows dates for one calibration and for several."""

from __future__ import annotations

import os
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

from PySide6.QtCore import QPoint, QRect, QSize
from PySide6.QtGui import QFontMetrics
from PySide6.QtWidgets import QApplication, QGroupBox, QLabel, QLineEdit, QTableWidget, QWidget

from app.gui import main_window
from app.gui.certificate_dialog import CertificateDialog
from app.gui.field_marks import INFO
from app.gui.main_window import MainWindow
from app.gui.sensors_tab import DAY_S
from app.records.db.engine import open_engine
from app.records.db.lab import Lab
from app.records.db.models import Run, Stand
from app.records.run_record import RunRecord
from tests.records_db import new_records

NOTE = "from the records: PCB 352C33, owner ACME Ltd, due 2026-11-03; nominal 100 mV/g, tol. 5 %"
LAPTOP, FULL_HD = QSize(1366, 768), QSize(1920, 1080)
RESULT_ROWS_AT_1366 = 15  # of a 25-line run, in view at 1366 x 768 (all 25 at 1920 x 1080)
# what a line edit draws around its text (px): frame and margins, each side
LINE_EDIT_SLACK_PX = 12
DATE_FORMATS = ("%Y", "%Y-%m", "%Y-%m-%d")


def settle() -> None:
    for _ in range(8):
        QApplication.processEvents()


def place(widget: QWidget, within: QWidget) -> QRect:
    """`widget`'s rectangle in `within`'s coordinates (px)."""
    return QRect(widget.mapTo(within, QPoint(0, 0)), widget.size())


def overlapping(form: QWidget) -> list[tuple[str, str]]:
    """Pairs of visible widgets of `form` that overlap (neither inside the other)."""
    shown = [
        w
        for w in form.findChildren(QWidget)
        if w.isVisible() and not w.isWindow() and w.width() > 0 and w.height() > 0
    ]
    found = []
    for i, a in enumerate(shown):
        for b in shown[i + 1 :]:
            if a.isAncestorOf(b) or b.isAncestorOf(a):
                continue
            if place(a, form).intersects(place(b, form)):
                found.append((_name(a), _name(b)))
    return found


def clipped(form: QWidget) -> list[str]:
    """The fields and labels of `form`'s boxes drawn lower than they need: a wrapped label
    under the height of its lines at its width, any other under its minimum size hint."""
    found = []
    for w in form.findChildren(QWidget):
        if not w.isVisible() or not isinstance(w.parentWidget(), QGroupBox):
            continue
        if isinstance(w, QLabel) and w.wordWrap() and w.text():
            needed = w.heightForWidth(w.width())
        else:
            needed = w.minimumSizeHint().height()
        if w.height() < needed:
            found.append(f"{_name(w)}: {w.height()} < {needed} px")
    return found


def _name(widget: QWidget) -> str:
    text = widget.text() if isinstance(widget, (QLabel, QLineEdit)) else ""
    return f"{type(widget).__name__} {text[:30]!r}"


def a_saved_geometry(tmp_path: Path, qtbot: Any, size: QSize) -> None:
    """The geometry a window of `size` leaves in the settings when it closes."""
    first = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(first)
    first.resize(size)
    first.settings.setValue("geometry", first.saveGeometry())
    first.setup_tab.close_pools()


def test_a_window_restored_at_910_by_515_is_at_least_its_minimum_and_nothing_overlaps(
    qtbot, tmp_path
):
    a_saved_geometry(tmp_path, qtbot, QSize(910, 515))
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    w.wait_for_plans()
    setup = w.setup_tab
    setup.dut_id.setText("SN-1043")
    setup.field_marks.note(setup.dut_id, NOTE, INFO)  # the note over Read TEDS, once
    w.show()
    qtbot.waitExposed(w)
    settle()
    area = w.screen().availableGeometry().size()
    least = w.minimumSizeHint().boundedTo(area)
    assert w.width() >= least.width() and w.height() >= least.height()
    assert w.height() > 515  # grown to what the form asks (or the whole screen)
    assert w.width() <= max(area.width(), w.minimumSizeHint().width())
    assert overlapping(setup.form) == [] and clipped(setup.form) == []
    note = setup.field_marks.notes[setup.dut_id]
    assert note.isVisible() and "from the records" in note.text()
    below = place(setup.teds.button, setup.form).top()
    assert place(note, setup.form).bottom() < below  # the note ends above Read TEDS
    assert note.height() >= note.heightForWidth(note.width())  # and shows all its lines


@pytest.mark.parametrize("screen", [LAPTOP, FULL_HD], ids=["1366x768", "1920x1080"])
def test_a_restored_window_grows_to_the_setup_forms_need_within_the_screen(qtbot, tmp_path, screen):
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    w.wait_for_plans()
    setup = w.setup_tab
    setup.field_marks.note(setup.dut_id, NOTE, INFO)
    w.resize(910, 515)  # as restored from the settings
    w.fit_screen(QRect(QPoint(0, 0), screen))
    need = w.needed_size()
    assert need.height() > 515 and w.size() == need.boundedTo(screen)
    w.show()
    qtbot.waitExposed(w)
    settle()
    if need.height() <= screen.height():  # every row whole without scrolling
        assert setup.form_area.verticalScrollBar().maximum() == 0
    assert overlapping(setup.form) == [] and clipped(setup.form) == []
    # a saved size over the screen comes back within it, placed on it
    w.setGeometry(200, 100, screen.width() + 300, screen.height() + 200)
    w.fit_screen(QRect(QPoint(0, 0), screen))
    assert w.width() <= screen.width() and w.height() <= screen.height()
    assert w.x() + w.width() <= screen.width() and w.y() + w.height() <= screen.height()


def whole_rows(table: QTableWidget) -> int:
    """The rows of `table` wholly in view without scrolling."""
    height = table.viewport().height()
    return sum(
        1
        for row in range(table.rowCount())
        if table.rowViewportPosition(row) + table.rowHeight(row) <= height
    )


@pytest.mark.parametrize("screen", [LAPTOP, FULL_HD], ids=["1366x768", "1920x1080"])
def test_the_results_tab_shows_whole_chart_titles_and_a_readable_table(
    qtbot, tmp_path, complete_run, screen
):
    w = MainWindow(out=tmp_path / "runs", paced=False)
    qtbot.addWidget(w)
    w.resize(screen)
    w.show()
    qtbot.waitExposed(w)
    assert w.open_run(complete_run)
    settle()
    results = w.results_tab
    results.charts.chart.grab()  # laid out and painted as shown
    for plot in (results.result_mag, results.result_phase):
        title = plot.titleLabel
        text = title.item.toPlainText()
        assert text  # the chart has its title
        needed = QFontMetrics(title.item.font()).horizontalAdvance(text)
        assert title.item.boundingRect().width() >= needed
        assert title.geometry().width() >= needed, (text, title.geometry().width(), needed)
    table = results.table
    assert table.rowCount() == 25
    if screen == FULL_HD:
        assert whole_rows(table) == 25 and table.verticalScrollBar().maximum() == 0
    else:
        assert whole_rows(table) >= RESULT_ROWS_AT_1366
    assert table.horizontalScrollBar().maximum() == 0
    for column in range(table.columnCount()):
        header = table.horizontalHeader()
        assert header.sectionSize(column) >= header.sectionSizeHint(column)


def _calibration(lab: Lab, serial: str, run_id: str, day: date, s: float) -> None:
    """An indexed complete run of `serial` (the records' rows; no folder needed here)."""
    sensor = lab.sensor(serial)
    with lab.session() as session:
        stand = session.query(Stand).first() or Stand(stand_file_sha256="0" * 64, name="stand")
        session.add(
            Run(
                run_id=run_id,
                manifest_sha256=run_id.ljust(64, "0")[:64],
                folder=f"/runs/{run_id}",
                status="complete",
                started_utc=datetime(day.year, day.month, day.day, 9, tzinfo=UTC),
                dut_id=serial,
                stand=stand,
                sensor_id=sensor.id,
                reference_frequency_hz=160.0,
                sensitivity_mv_per_ms2=s,
                expanded_uncertainty_mv_per_ms2=0.05,
            )
        )


@pytest.fixture
def lab_url(tmp_path: Path) -> str:
    """A lab's typical records: two customers, two models (one maker with an "&"), three
    sensors; SN-1 calibrated once, SN-3 three times, SN-2 never."""
    url = new_records(tmp_path / "lab.sqlite")
    lab = Lab(open_engine(url), actor="t")
    lab.add_customer("ACME Ltd", "1 Main Street, Springfield")
    lab.add_customer("Vibration Labs GmbH", "Robert-Bosch-Straße 12, 71034 Böblingen, Germany")
    for maker, model in (("Brüel & Kjær", "4533-B"), ("PCB Piezotronics", "352C33")):
        lab.add_model(
            maker,
            model,
            nominal_sensitivity=100.0,
            unit="mV/g",
            tolerance_percent=5,
            frequency_min_hz=1,
            frequency_max_hz=10000,
            level_ms2=5.0,
        )
    lab.add_sensor("SN-1", model="4533-B", owner="Vibration Labs GmbH")
    lab.add_sensor("SN-2", model="352C33", owner="ACME Ltd", interval_months=24)
    lab.add_sensor("SN-3", model="352C33", owner="Vibration Labs GmbH")
    _calibration(lab, "SN-1", "r1", date(2025, 11, 3), 10.20)
    for n, day in enumerate((date(2023, 11, 6), date(2024, 11, 4), date(2025, 11, 3))):
        _calibration(lab, "SN-3", f"r3-{n}", day, 10.2 + 0.01 * n)
    return url


@pytest.fixture
def window(qtbot, tmp_path, lab_url):
    w = MainWindow(out=tmp_path / "runs", paced=False, db=lab_url)
    qtbot.addWidget(w)
    w.records.wait()
    w.sensors_tab._today = date(2026, 11, 24)  # SN-1 and SN-3 overdue
    w.sensors_tab.refresh()
    w.resize(LAPTOP)
    w.tabs.setCurrentIndex(main_window.SENSORS_TAB)
    w.show()
    qtbot.waitExposed(w)
    settle()
    return w


def assert_whole_columns(table: QTableWidget) -> None:
    """Every header and every cell of `table` shows its whole text, unscrolled."""
    header = table.horizontalHeader()
    assert table.rowCount() > 0
    for column in range(table.columnCount()):
        width = header.sectionSize(column)
        label = table.horizontalHeaderItem(column).text()
        assert width >= header.sectionSizeHint(column), label
        assert width >= table.sizeHintForColumn(column), label  # its widest cell, margins too
        for row in range(table.rowCount()):
            text = table.item(row, column).text()
            assert width >= table.fontMetrics().horizontalAdvance(text), text
    assert table.horizontalScrollBar().maximum() == 0


def test_the_sensors_and_due_tables_show_typical_content_whole_at_1366_by_768(window):
    tab = window.sensors_tab
    assert tab.sensors.rowCount() == 3
    texts = {tab.sensors.item(r, c).text() for r in range(3) for c in range(5)}
    assert {"Brüel & Kjær 4533-B", "Vibration Labs GmbH", "never calibrated here"} <= texts
    assert_whole_columns(tab.sensors)
    tab.days.setValue(3650)  # every sensor due within ten years
    settle()
    assert tab.due.rowCount() >= 3
    assert any("OVERDUE" in tab.due.item(r, 2).text() for r in range(tab.due.rowCount()))
    assert_whole_columns(tab.due)


def test_the_certificate_dialogs_fields_show_typical_content_whole(qtbot):
    record = RunRecord(
        run_id="20261128T031420Z-SN-1043-782840",
        status="complete",
        abort_reason=None,
        final_output_v=0.0,
    )
    typical = {
        "customer": "Vibration Labs GmbH, Kalibrierlaboratorium",
        "customer_address": "Robert-Bosch-Straße 12, 71034 Böblingen, Germany",
        "dut_model": "Brüel & Kjær 4533-B",
        "dut_serial": "BK-2210-0042",
        "mounting": "stud M5, 2 N m, thin film of silicone grease",
    }
    dialog = CertificateDialog(
        None, record, typical, prepared_by="A. Tech", offered_from="model Brüel & Kjær 4533-B"
    )
    qtbot.addWidget(dialog)
    dialog.show()
    qtbot.waitExposed(dialog)
    settle()
    typed = {
        "spec_id": "ACME QA-17 rev. C, accelerometers, 2026-03",
        "authorised_function": "head of laboratory, vibration and shock",
        "address_not_stated": "the customer asked it not to be stated",
    }
    for key, text in typed.items():
        dialog.edits[key].setText(text)
    for key, text in {**typical, **typed}.items():
        edit = dialog.edits[key]
        assert edit.text() == text
        needed = QFontMetrics(edit.font()).horizontalAdvance(text) + LINE_EDIT_SLACK_PX
        assert edit.width() >= needed, (key, edit.width(), needed)
    labels = [label for label in dialog.findChildren(QLabel) if label.isVisible()]
    mounting = [label.text() for label in labels if label.text().startswith("Mounting")]
    assert mounting == ["Mounting (from model Brüel && Kjær 4533-B)"]  # "&" shown, not a key
    for label in labels:
        if label is not dialog.title and not label.wordWrap():
            assert label.width() >= label.sizeHint().width(), label.text()


def tick_texts(window: MainWindow) -> tuple[tuple[float, float], list[str]]:
    """The history chart's date range (s since the epoch) and its bottom axis's tick texts
    as drawn at the axis's width."""
    chart = window.sensors_tab.chart
    chart.grab()  # painted: the axis has its fonts
    axis = chart.getPlotItem().getAxis("bottom")
    low, high = chart.getPlotItem().getViewBox().viewRange()[0]
    texts = []
    for spacing, values in axis.tickValues(low, high, axis.width()):
        texts += axis.tickStrings(values, axis.scale, spacing)
    return (low, high), [t for t in texts if t]


def is_date(text: str) -> bool:
    for pattern in DATE_FORMATS:
        try:
            datetime.strptime(text, pattern)
        except ValueError:
            continue
        return True
    return False


def test_the_history_chart_has_a_date_axis_with_one_calibration_and_with_three(window):
    tab = window.sensors_tab
    tab.search.setText("SN-1")  # one calibration: 2025-11-03
    settle()
    assert tab.serial == "SN-1" and len(tab.points.getData()[0]) == 1
    (low, high), texts = tick_texts(window)
    day = datetime(2025, 11, 3, 9, tzinfo=UTC).timestamp()
    assert low <= day - 29 * DAY_S and high >= day + 29 * DAY_S  # about a month each side
    assert high - low <= 90 * DAY_S
    assert len(texts) >= 2 and all(is_date(t) for t in texts), texts
    assert any(t.startswith("2025-11") for t in texts)
    tab.search.setText("SN-3")  # three calibrations, 2023 to 2025
    settle()
    assert len(tab.points.getData()[0]) == 3
    (low, high), texts = tick_texts(window)
    assert low <= datetime(2023, 11, 6, tzinfo=UTC).timestamp() - 29 * DAY_S
    assert high >= datetime(2025, 11, 3, tzinfo=UTC).timestamp() + 29 * DAY_S
    assert len(texts) >= 2 and all(is_date(t) for t in texts), texts
    assert {"2024", "2025"} <= set(texts)
    # zoomed in as far as the chart goes: still dates, never times of day
    tab.chart.getPlotItem().getViewBox().setXRange(day - 3600, day + 3600, padding=0)
    settle()
    (low, high), texts = tick_texts(window)
    assert high - low >= 13 * DAY_S
    assert texts and all(is_date(t) for t in texts), texts
