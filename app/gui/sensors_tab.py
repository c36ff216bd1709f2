"""The Sensors tab: search the lab's sensors by serial, a sensor's history (sensitivity at the
reference frequency over time with its U bars, drift per year), and what is due.

It reads `app.records.db.lab.Lab` through the window's `RecordsLink` and draws; it computes nothing
(history and drift come from `Lab.history`, the due list from `Lab.due`). When the records
cannot be opened the tab says why and the rest of the window works.
"""

from __future__ import annotations

import logging
from collections import OrderedDict
from datetime import UTC, date, datetime
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtWidgets import (
    QAbstractItemView,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.plots import ChartStack
from app.gui.records_link import RecordsLink
from app.gui.results_tab import compact_rows, wrapping_label
from app.gui.table_items import read_only_item
from app.records.db.errors import RecordsInputError

log = logging.getLogger(__name__)

SENSOR_COLUMNS = ("Serial", "Model", "Owner", "Interval", "Due")
DUE_COLUMNS = ("Kind", "Identifier", "Due", "Owner")
OVERDUE = "#c0392b"


DAY_S = 86400.0
MARGIN_DAYS = 30.0  # the history's date axis reaches this far before the first and after the last
MIN_DAYS_SHOWN = 14.0  # the narrowest date range the history chart zooms in to


def calendar_axis() -> pg.DateAxisItem:
    """pyqtgraph's date axis (UTC) with dates for ticks at every zoom: years, then months as
    2025-11, then days as 2025-11-03; never times of day (a calibration's date is what the
    history says; with one calibration the axis showed hours and seconds)."""
    from pyqtgraph.graphicsItems import DateAxisItem as dates

    years = dates.ZoomLevel(
        [
            dates.TickSpec(dates.YEAR_SPACING, dates.makeYStepper(1), "%Y", autoSkip=[1, 5, 10]),
            dates.TickSpec(dates.MONTH_SPACING, dates.makeMStepper(1), "%Y-%m", autoSkip=[1, 3, 6]),
        ],
        "2025-11",
    )
    days = dates.ZoomLevel(
        [
            dates.TickSpec(dates.MONTH_SPACING, dates.makeMStepper(1), "%Y-%m-%d"),
            dates.TickSpec(
                dates.DAY_SPACING, dates.makeSStepper(dates.DAY_SPACING), "%Y-%m-%d", [1, 5]
            ),
        ],
        "2025-11-03",
    )
    axis = pg.DateAxisItem(orientation="bottom", utcOffset=0)
    # the finest level is used at any density under its bound (DateAxisItem's own rule)
    axis.zoomLevels = OrderedDict([(np.inf, years), (15 * DAY_S, days)])
    return axis


def date_range(x: np.ndarray) -> tuple[float, float]:
    """The shown range (s since the epoch) around calibrations at `x`: MARGIN_DAYS before
    the first and after the last (one calibration: two months around it)."""
    margin = MARGIN_DAYS * DAY_S
    return float(np.min(x)) - margin, float(np.max(x)) + margin


def readable_columns(table: QTableWidget) -> None:
    """Each column as wide as its header and its cells (no elided serial, model, owner or
    date); the last takes what is left; rows one text line tall."""
    header = table.horizontalHeader()
    header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
    header.setStretchLastSection(True)
    compact_rows(table)


def _text(table: QTableWidget, row: int, column: int) -> str:
    cell = table.item(row, column)
    return cell.text() if cell is not None else ""


class SensorsTab(QWidget):
    """Search, history chart and due list over the records of `link`."""

    def __init__(self, link: RecordsLink, today: Any = None) -> None:
        super().__init__()
        self.link = link
        self._today = today  # a fixed date for tests; None: the current UTC date
        layout = QVBoxLayout(self)
        self.status = wrapping_label(link.describe())
        layout.addWidget(self.status)

        body = QHBoxLayout()
        left = QVBoxLayout()
        search_row = QHBoxLayout()
        self.search = QLineEdit()
        self.search.setPlaceholderText("serial contains ... (scan or type, Enter)")
        self.search.setToolTip("Search the sensors by serial number")
        self.search.textChanged.connect(self.search_sensors)
        refresh = QPushButton("Refresh")
        refresh.setToolTip("Read the sensors and the due list again")
        refresh.clicked.connect(self.refresh)
        search_row.addWidget(QLabel("Serial"))
        search_row.addWidget(self.search, 1)
        search_row.addWidget(refresh)
        left.addLayout(search_row)
        edit_row = QHBoxLayout()
        self.edit_buttons: dict[str, QPushButton] = {}
        for key, text, tip in (
            ("customers", "Customers ...", "Add or edit the lab's customers"),
            ("models", "Sensor models ...", "Add or edit sensor models (nominal, tolerance)"),
            (
                "references",
                "Reference standards ...",
                "Add a reference standard or enter its recalibration (table from a CSV file)",
            ),
        ):
            button = QPushButton(text)
            button.setToolTip(tip)
            button.clicked.connect(lambda _checked=False, k=key: self.edit_records(k))
            edit_row.addWidget(button)
            self.edit_buttons[key] = button
        edit_row.addStretch(1)
        left.addLayout(edit_row)
        self.sensors = QTableWidget(0, len(SENSOR_COLUMNS))
        self.sensors.setHorizontalHeaderLabels(list(SENSOR_COLUMNS))
        self.sensors.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.sensors.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        readable_columns(self.sensors)
        self.sensors.verticalHeader().setVisible(False)
        self.sensors.itemSelectionChanged.connect(self._selected)
        left.addWidget(self.sensors, 1)

        due_box = QGroupBox("Due for calibration")
        due_layout = QVBoxLayout(due_box)
        self.days = QSpinBox(minimum=0, maximum=3650, value=30, suffix=" days ahead")
        self.days.setToolTip("Sensors and reference standards due within this many days")
        self.days.valueChanged.connect(self.show_due)
        due_layout.addWidget(self.days)
        self.due = QTableWidget(0, len(DUE_COLUMNS))
        self.due.setHorizontalHeaderLabels(list(DUE_COLUMNS))
        readable_columns(self.due)
        self.due.verticalHeader().setVisible(False)
        self.due.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.due.itemDoubleClicked.connect(self._due_clicked)
        due_layout.addWidget(self.due, 1)
        left.addWidget(due_box, 1)
        body.addLayout(left, 1)  # half the width: the tables' columns whole at 1366 px

        right = QVBoxLayout()
        self.chart = pg.PlotWidget(
            title="History: sensitivity at the reference frequency, ± U",
            axisItems={"bottom": calendar_axis()},
        )
        # never zoomed in under a few weeks: the axis then has no date to show
        self.chart.getPlotItem().getViewBox().setLimits(minXRange=MIN_DAYS_SHOWN * DAY_S)
        self.chart.setLabel("left", "sensitivity", units="mV/(m/s²)")
        self.chart.setLabel("bottom", "calibration date (UTC)")
        self.chart.getAxis("left").enableAutoSIPrefix(False)
        self.chart.showGrid(x=True, y=True, alpha=0.3)
        self.points = pg.ScatterPlotItem(size=9, brush=pg.mkBrush("#2471a3"))
        self.line = pg.PlotDataItem(pen=pg.mkPen("#2471a3", width=1))
        self.bars = pg.ErrorBarItem(beam=0.0, pen=pg.mkPen("#2471a3"))
        for item in (self.line, self.bars, self.points):
            self.chart.addItem(item)
        self.chart_stack = ChartStack(self.chart, "Select a sensor to see its history.")
        right.addWidget(self.chart_stack, 1)
        self.history_text = wrapping_label("Select a sensor to see its history.")
        right.addWidget(self.history_text)
        body.addLayout(right, 1)
        layout.addLayout(body, 1)

        self.serial: str | None = None
        self.history: Any = None
        link.changed.connect(self.refresh)
        self.refresh()

    def today(self) -> date:
        return self._today or datetime.now(UTC).date()

    # --- reads ------------------------------------------------------------------------------

    def refresh(self) -> None:
        """Read the sensors (for the search) and the due list again."""
        self.status.setText(self.link.describe())
        enabled = self.link.lab is not None
        for widget in (self.search, self.sensors, self.days, self.due, self.chart):
            widget.setEnabled(enabled)
        for button in self.edit_buttons.values():
            button.setEnabled(enabled)
        if enabled:
            shown = self.serial
            self.search_sensors(self.search.text())
            self.show_due()
            if shown is not None and self.serial == shown:
                self.show_history(shown)  # a run since may have added a point
        else:
            self.sensors.setRowCount(0)
            self.due.setRowCount(0)
            self.show_history(None)

    def records_list(self, kind: str) -> Any:
        """The list dialog of `kind` ('customers', 'models', 'references') over the records."""
        from app.gui import records_dialogs

        make = {
            "customers": records_dialogs.customers_list,
            "models": records_dialogs.models_list,
            "references": records_dialogs.references_list,
        }[kind]
        return make(self, self.link.lab)

    def edit_records(self, kind: str) -> None:
        """Open the list of `kind`; afterwards every view of the records reads them again."""
        if self.link.lab is None:
            return
        self.records_list(kind).exec()
        self.link.changed.emit()  # the Setup tab's reference standard, this tab

    def _failed(self, exc: Exception) -> None:
        self.status.setText(f"records: {exc}")

    def search_sensors(self, text: str = "") -> list[Any]:
        """Sensors whose serial contains `text`; an exact match is selected."""
        lab = self.link.lab
        if lab is None:
            return []
        try:
            found = lab.sensors(text.strip())
        except RecordsInputError as exc:
            self._failed(exc)
            return []
        self.sensors.blockSignals(True)
        # no row selected: the row found is then selected anew, and its history drawn, also
        # when another serial stood in that row before
        self.sensors.clearSelection()
        self.sensors.setRowCount(len(found))
        today = self.today()
        for row, sensor in enumerate(found):
            overdue = sensor.due_date is not None and sensor.due_date < today
            cells = (
                sensor.serial,
                f"{sensor.model.maker} {sensor.model.model}",
                sensor.owner.name,
                f"{sensor.interval_months} months",
                str(sensor.due_date) if sensor.due_date else "never calibrated here",
            )
            for column, text_ in enumerate(cells):
                self.sensors.setItem(
                    row, column, read_only_item(text_, OVERDUE if overdue else None)
                )
        self.sensors.blockSignals(False)
        exact = [r for r, s in enumerate(found) if s.serial == text.strip()]
        if exact:
            self.sensors.selectRow(exact[0])
        elif len(found) == 1:
            self.sensors.selectRow(0)
        return found

    def _selected(self) -> None:
        rows = {i.row() for i in self.sensors.selectedItems()}
        if len(rows) == 1:
            self.show_history(_text(self.sensors, rows.pop(), 0))

    def show_history(self, serial: str | None) -> None:
        """The history chart of sensor `serial` (None: empty)."""
        self.serial, self.history = serial, None
        for item in (self.points, self.line):
            item.setData([], [])
        self.bars.setData(x=np.zeros(0), y=np.zeros(0), height=np.zeros(0))
        lab = self.link.lab
        self.chart_stack.show_chart(False, "Select a sensor to see its history.")
        if serial is None or lab is None:
            self.history_text.setText("Select a sensor to see its history.")
            return
        try:
            history = lab.history(serial)
        except RecordsInputError as exc:
            self.history_text.setText(str(exc))
            return
        self.history = history
        points = history.points
        if not points:
            self.history_text.setText(f"{serial}: no complete calibration on record yet.")
            self.chart_stack.show_chart(False, f"{serial}: no complete calibration on record yet.")
            return
        self.chart_stack.show_chart(True)
        x = np.array([p.started_utc.timestamp() for p in points])
        y = np.array([p.sensitivity_mv_per_ms2 for p in points])
        u = np.array([p.expanded_uncertainty_mv_per_ms2 or 0.0 for p in points])
        self.points.setData(x, y)
        self.line.setData(x, y)
        self.bars.setData(x=x, y=y, height=2 * u)
        self.chart.setXRange(*date_range(x), padding=0)  # days around one calibration
        self.chart.enableAutoRange(axis="y")
        drift = history.drift_percent_per_year
        drift_text = (
            "drift not stated (needs calibrations over at least 30 days)"
            if drift is None
            else f"drift {drift:+.3g} % per year"
        )
        last = points[-1]
        self.history_text.setText(
            f"{serial}: {len(points)} calibration(s); last {last.started_utc:%Y-%m-%d}, "
            f"{last.sensitivity_mv_per_ms2:.5g} mV/(m/s²) at {last.reference_frequency_hz:g} Hz; "
            f"{drift_text}."
        )

    def show_due(self) -> None:
        """Sensors and reference standards due within the chosen days; overdue in red."""
        lab = self.link.lab
        if lab is None:
            return
        today = self.today()
        try:
            items = lab.due(today=today, days=self.days.value())
        except RecordsInputError as exc:
            self._failed(exc)
            return
        self.due.setRowCount(len(items))
        for row, item in enumerate(items):
            overdue = item.due is not None and item.due < today
            due_text = (
                "never calibrated here"
                if item.due is None
                else f"{item.due}{'  OVERDUE' if overdue else ''}"
            )
            cells = (item.kind, item.identifier, due_text, item.owner)
            for column, text in enumerate(cells):
                self.due.setItem(row, column, read_only_item(text, OVERDUE if overdue else None))

    def _due_clicked(self, item: QTableWidgetItem) -> None:
        row = item.row()
        if _text(self.due, row, 0) == "sensor":
            self.search.setText(_text(self.due, row, 1))

    def due_identifiers(self) -> list[str]:
        return [_text(self.due, r, 1) for r in range(self.due.rowCount())]
