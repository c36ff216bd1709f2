"""The Results tab's members of a run of several DUTs (issue 36): a row per DUT (position,
serial, verdict, worst line) in the fixture's order; choosing a row shows that DUT's stored run
as a single run's results (the window's `open_run`). The verdicts are the runs' own (computed
once by the procedure, `verdict_of`); nothing here computes beyond picking the line to name.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PySide6.QtCore import Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QAbstractItemView, QHeaderView, QTableWidget, QTableWidgetItem

from app.gui.verdict_view import COLOURS, verdict_of
from app.io.vocabulary import RunStatus
from dsp.calibration import Results

HEADERS = ("position", "serial", "verdict", "worst line (deviation)", "run")


@dataclass(frozen=True)
class MemberRow:
    """One DUT of a batch as the Results tab lists it; `folder` its run folder (None: it has
    none), `complete` whether it can be shown and certified."""

    position: str
    serial: str
    verdict: str
    worst: str
    folder: Path | None
    complete: bool


def worst_line(results: Results | None) -> str:
    """The stated line of the largest deviation from the reference frequency, as
    '+1.23 % at 5000 Hz' ('' without results or stated lines)."""
    if results is None:
        return ""
    stated = [ln for ln in results.lines if ln.stated and math.isfinite(ln.deviation_percent)]
    if not stated:
        return ""
    worst = max(stated, key=lambda ln: abs(ln.deviation_percent))
    return f"{worst.deviation_percent:+.2f} % at {worst.nominal_frequency_hz:g} Hz"


def member_rows(batch: Any, out: Path) -> list[MemberRow]:
    """The rows of a finished batch (app.procedure.batch.BatchFinished) whose run folders are
    under the runs root `out`."""
    rows = []
    for choice, finished in batch.members:
        run_id = finished.record.run_id
        complete = finished.status == RunStatus.COMPLETE and finished.results is not None
        verdict, _ = verdict_of(finished.results, finished.record)
        if finished.status != RunStatus.COMPLETE:
            verdict = f"{finished.status}: {finished.abort_reason}"
        rows.append(
            MemberRow(
                choice.position,
                choice.serial,
                verdict,
                worst_line(finished.results),
                out / str(run_id) if run_id else None,
                complete,
            )
        )
    return rows


class BatchTable(QTableWidget):
    """The members, one row each; `member_chosen` carries the row's MemberRow."""

    member_chosen = Signal(object)

    def __init__(self) -> None:
        super().__init__(0, len(HEADERS))
        self.rows: list[MemberRow] = []
        self.batch_id = ""
        self.setHorizontalHeaderLabels(list(HEADERS))
        header = self.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        self.verticalHeader().setVisible(False)
        self.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        self.setAccessibleName("DUTs of the run")
        self.itemSelectionChanged.connect(self._chosen)
        self.setVisible(False)

    def show_rows(self, batch_id: str, rows: list[MemberRow]) -> None:
        """List `rows` of batch `batch_id` ([]: no batch, the table hidden), as tall as they
        are (at most 8 rows: the simulated stand's DUTs)."""
        self.batch_id, self.rows = batch_id, list(rows)
        self.blockSignals(True)
        self.clearSelection()
        self.setRowCount(len(rows))
        for r, row in enumerate(rows):
            cells = (
                row.position,
                row.serial,
                row.verdict,
                row.worst,
                row.folder.name if row.folder else "",
            )
            for c, text in enumerate(cells):
                item = QTableWidgetItem(text)
                if c == 2 and row.verdict in COLOURS:
                    item.setForeground(QColor(COLOURS[row.verdict]))
                self.setItem(r, c, item)
        self.blockSignals(False)
        self.setVisible(bool(rows))
        if rows:
            height = self.horizontalHeader().height() + 2 * self.frameWidth()
            height += sum(self.rowHeight(r) for r in range(len(rows)))
            self.setFixedHeight(height)

    def choose(self, index: int) -> None:
        """Select the row `index` (its run shown: `member_chosen`)."""
        self.selectRow(index)

    def _chosen(self) -> None:
        selected = self.selectionModel().selectedRows()
        if selected:
            self.member_chosen.emit(self.rows[selected[0].row()])

    @property
    def certifiable(self) -> list[MemberRow]:
        """The complete members (each gets a certificate)."""
        return [row for row in self.rows if row.complete and row.folder is not None]
