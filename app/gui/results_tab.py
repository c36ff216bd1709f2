"""The Results tab: one verified run's results, budget and charts; export and certificate."""

from __future__ import annotations

from pathlib import Path

import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QSizePolicy,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app import formatting as fmt
from app.gui.batch_view import BatchTable, MemberRow
from app.gui.plots import ChartStack, draw_bands, frequency_axis
from app.gui.verdict_view import VerdictView, verdict_of
from app.records.run_record import RunRecord
from dsp.calibration import LineResult, Results
from dsp.uncertainty import Budget, Quantity

COLUMNS = (  # name over unit: the table fits its half of a 1366 px window unscrolled
    "f\nHz",
    "S\nmV/(m/s²)",
    "U\nmV/(m/s²)",
    "dev.\n%",
    "phase\n°",
    "U\n°",
    "U rel.\n%",
    "k",
    "U vs ISO\nlimit",
    "tolerance",
)
ROW_MARGIN_PX = 6  # a table row's height over its font's (px)


def wrapping_label(text: str = "") -> QLabel:
    """A label that wraps and never asks its layout for more width than it is given."""
    label = QLabel(text)
    label.setWordWrap(True)
    label.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
    label.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
    label.setMinimumWidth(1)
    return label


def compact_rows(table: QTableWidget) -> None:
    """Rows one line of text tall (px: the font's height and a small margin; the style's
    default is about 30 px): a 25-line run's table is whole at 1920 x 1080, and 15 lines
    and more of it are in view at 1366 x 768."""
    rows = table.verticalHeader()
    rows.setMinimumSectionSize(1)
    rows.setDefaultSectionSize(table.fontMetrics().height() + ROW_MARGIN_PX)


class ResultsTab(QWidget):
    """Shows the results of one run; `folder` is that run (None: nothing certifiable shown)."""

    def __init__(self) -> None:
        super().__init__()
        self.results: Results | None = None
        self.record: RunRecord | None = None
        self.folder: Path | None = None
        layout = QVBoxLayout(self)
        # a run of several DUTs: a row per DUT; the one chosen is shown below (issue 36)
        self.members = BatchTable()
        compact_rows(self.members)
        layout.addWidget(self.members)
        self.verdict = VerdictView()
        layout.addWidget(self.verdict)
        self.summary = wrapping_label("No results yet.")
        self.summary.setTextFormat(Qt.TextFormat.RichText)
        layout.addWidget(self.summary)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        self.table.verticalHeader().setVisible(False)
        compact_rows(self.table)
        middle = QHBoxLayout()
        middle.addWidget(self.table, 3)
        charts = pg.GraphicsLayoutWidget()
        self.result_mag = charts.addPlot(
            title="Deviation from the reference frequency, ± U",
            labels={"left": "%", "bottom": "Hz"},
        )
        charts.nextRow()
        self.result_phase = charts.addPlot(
            title="Phase, ± U", labels={"left": "degree", "bottom": "Hz"}
        )
        for plot in (self.result_mag, self.result_phase):
            frequency_axis(plot)
            plot.getAxis("left").enableAutoSIPrefix(False)  # "%", never "% (x0.001)"
            plot.showGrid(x=True, y=True, alpha=0.3)
        self.charts = ChartStack(charts, "No results yet: a finished run shows its charts here.")
        middle.addWidget(self.charts, 2)
        layout.addLayout(middle, 3)
        self.budget = QTableWidget(0, 4)
        self.budget.setHorizontalHeaderLabels(
            ["Component (at the reference frequency)", "value", "distribution", "standard u"]
        )
        self.budget.horizontalHeader().setStretchLastSection(True)
        self.budget.verticalHeader().setVisible(False)
        compact_rows(self.budget)
        self.budget.setColumnWidth(0, 420)
        layout.addWidget(self.budget, 1)
        buttons = QHBoxLayout()
        self.export_button = QPushButton("Export CSV and JSON")
        buttons.addWidget(self.export_button)
        self.certificate_button = QPushButton("Certificate ...")
        self.certificate_button.setToolTip("Issue the certificate of the run shown here")
        buttons.addWidget(self.certificate_button)
        self.batch_certificate_button = QPushButton("Certificates for all DUTs ...")
        self.batch_certificate_button.setToolTip(
            "Issue a certificate for each complete DUT of the run, in one confirmation"
        )
        self.batch_certificate_button.setVisible(False)
        buttons.addWidget(self.batch_certificate_button)
        layout.addLayout(buttons)
        self.clear("No results yet.")

    def show_batch(self, batch_id: str, rows: list[MemberRow]) -> None:
        """The DUTs of batch `batch_id` ([]: a single run, none listed)."""
        self.members.show_rows(batch_id, rows)
        certifiable = len(self.members.certifiable)
        self.batch_certificate_button.setVisible(bool(rows))
        self.batch_certificate_button.setEnabled(certifiable > 0)
        self.batch_certificate_button.setText(f"Certificates for all {certifiable} DUTs ...")

    def clear(self, message: str) -> None:
        """Nothing shown, nothing to export or certify; `message` (rich text) says why."""
        self.results, self.record, self.folder = None, None, None
        self.verdict.show_verdict(None)
        self.summary.setText(message)
        self.table.setRowCount(0)
        self.budget.setRowCount(0)
        draw_bands(self.result_mag, self.result_phase, None)
        self.charts.show_chart(False)
        self.export_button.setEnabled(False)
        self.certificate_button.setEnabled(False)

    def show_results(self, results: Results, record: RunRecord, folder: Path | None) -> None:
        """The results of the verified run in `folder` (None: not certifiable)."""
        self.results, self.record, self.folder = results, record, folder
        self.verdict.show_verdict(*verdict_of(results, record))
        r = results.reference
        value, u = fmt.round_gum(r.sensitivity_mv_per_ms2, r.expanded_uncertainty_mv_per_ms2)
        self.summary.setText(
            f"<b>Reference sensitivity at {r.frequency_hz:g} Hz: ({value} ± {u}) mV/(m/s²)</b> "
            f"({r.sensitivity_db:.2f} dB re 1 mV/(m/s²)), k = {r.coverage_factor:.2f}, "
            f"p = {100 * r.coverage_probability:.2f} %. Run {record.run_id}, "
            f"{results.periods} periods, {record.mode}."
        )
        self.table.setRowCount(len(results.lines))
        for row, ln in enumerate(results.lines):
            s, us = fmt.round_gum(ln.sensitivity_mv_per_ms2, ln.expanded_uncertainty_mv_per_ms2)
            p, up = fmt.round_gum(ln.phase_deg, ln.phase_expanded_uncertainty_deg)
            cells = (
                _not_stated_cells(ln)
                if not ln.stated
                else [
                    f"{ln.nominal_frequency_hz:g}",
                    s,
                    us,
                    fmt.signed(ln.deviation_percent, 2),
                    p,
                    up,
                    fmt.significant(100 * ln.relative_expanded_uncertainty),
                    f"{ln.coverage_factor:.2f}",
                    ln.iso_verdict,
                    ln.tolerance_verdict or "",
                ]
            )
            for column, text in enumerate(cells):
                self.table.setItem(row, column, QTableWidgetItem(text))
            first = self.table.item(row, 0)
            if not ln.stated and first is not None:
                first.setToolTip(f"not stated: {ln.not_stated}")
        draw_bands(self.result_mag, self.result_phase, results)
        self.charts.show_chart(True)
        self._fill_budget(results, record)
        self.export_button.setEnabled(True)
        self.certificate_button.setEnabled(folder is not None)

    def _fill_budget(self, results: Results, record: RunRecord) -> None:
        """The stored budget at the reference frequency, with this run's type A."""
        budget = Budget.from_list(list(record.budget))
        line = next(
            ln for ln in results.lines if ln.nominal_frequency_hz == results.reference.frequency_hz
        )
        rows = [
            (
                "type A within this run (scatter of the periods)",
                "",
                "normal (t)",
                f"{100 * line.relative_type_a:.3g} %",
            ),
        ]
        rows += [
            (
                c.name,
                f"{100 * c.value:.3g} %",
                str(c.distribution),
                f"{100 * c.standard_uncertainty:.3g} %",
            )
            for c in budget.at(line.frequency_hz, Quantity.MAGNITUDE)
        ]
        rows += [
            (
                "combined standard uncertainty",
                "",
                "",
                f"{100 * line.relative_standard_uncertainty:.3g} %",
            ),
            (
                f"expanded (k = {line.coverage_factor:.2f})",
                "",
                "",
                f"{fmt.significant(100 * line.relative_expanded_uncertainty)} %",
            ),
        ]
        self.budget.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, text in enumerate(row):
                self.budget.setItem(r, c, QTableWidgetItem(text))


def _not_stated_cells(ln: LineResult) -> list[str]:
    """A line that is not stated (outside the reference's calibrated range): "n/s" in every
    value, U and verdict cell, its reason in the tooltip of the row's first cell."""
    return [
        f"{ln.nominal_frequency_hz:g}",
        *([fmt.NOT_STATED_SHORT] * 8),
        ln.tolerance_verdict or "",
    ]
