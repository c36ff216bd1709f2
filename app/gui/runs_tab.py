"""The Runs tab: every stored run with its verified state.

Each folder is checked with `app.records.run_folder.inspect_run` (manifest verified, lock
looked at):

    complete     finished, every file matches its manifest: may be certified
    aborted      finished early (reason stored): kept, never certified
    running      a process still writes it
    interrupted  no manifest and nobody writing: the process died (recording readable)
    modified     a stored file does not match the manifest: refused, never certified
"""

from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QAbstractItemView,
    QHeaderView,
    QLabel,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from app.gui.verdict_view import COLOURS as VERDICT_COLOURS
from app.gui.verdict_view import verdict_of
from app.records.run_folder import FolderState, RunCheck, inspect_run

log = logging.getLogger(__name__)

STATE_COLOURS = {
    FolderState.COMPLETE: "#1e8449",
    FolderState.ABORTED: "#b9770e",
    FolderState.RUNNING: "#2471a3",
    FolderState.INTERRUPTED: "#c0392b",
    FolderState.MODIFIED: "#c0392b",
}
FOLDER_ROLE = Qt.ItemDataRole.UserRole
STATE_ROLE = Qt.ItemDataRole.UserRole + 1


def fingerprint(folder: Path) -> tuple:
    """Name, size, modification time and mode of the folder and of every file in it: what
    changes when anything in a run folder is edited, replaced, added or removed."""
    entries = [folder, *sorted(folder.iterdir())]
    return tuple(
        (p.name, st.st_size, st.st_mtime_ns, st.st_mode) for p in entries for st in [p.stat()]
    )


def check_folder(folder: Path) -> RunCheck | None:
    """inspect_run, or None for a folder that is no run (left out of the list)."""
    try:
        return inspect_run(folder)
    except (ValueError, OSError) as exc:
        log.debug("not listed: %s", exc)
        return None


class RunsTab(QWidget):
    """Stored runs under `root`, newest first, each with its state and overall verdict (a
    column); double-click opens one."""

    open_requested = Signal(Path)

    def __init__(self, root: Path) -> None:
        super().__init__()
        self.root = root
        # finished runs verified before, by fingerprint: a list of many runs is not hashed
        # again on every refresh (opening or certifying a run always verifies it afresh)
        self._verified: dict[Path, tuple[tuple, RunCheck]] = {}
        layout = QVBoxLayout(self)
        self.heading = QLabel(
            f"Stored runs in {root} (double-click to open; only a complete run can be certified)"
        )
        self.heading.setWordWrap(True)
        self.runs = QTableWidget(0, 2)
        self.runs.setHorizontalHeaderLabels(["Run and state", "Verdict"])
        self.runs.verticalHeader().setVisible(False)
        self.runs.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.runs.setEditTriggers(QAbstractItemView.EditTrigger.NoEditTriggers)
        header = self.runs.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.Stretch)
        header.setSectionResizeMode(1, QHeaderView.ResizeMode.ResizeToContents)
        self.runs.itemDoubleClicked.connect(
            lambda item: self.open_requested.emit(Path(item.data(FOLDER_ROLE)))
        )
        refresh = QPushButton("Refresh")
        refresh.clicked.connect(self.refresh)
        layout.addWidget(self.heading)
        layout.addWidget(self.runs, 1)
        layout.addWidget(refresh)
        self.refresh()

    def refresh(self) -> None:
        """List the run folders again, each verified."""
        self.runs.setRowCount(0)
        if not self.root.is_dir():
            return
        rows = []
        for folder in sorted(self.root.iterdir(), reverse=True):
            if not folder.is_dir():
                continue
            check = self.check(folder)
            if check is not None:
                rows.append((folder, check))
        self.runs.setRowCount(len(rows))
        for row, (folder, check) in enumerate(rows):
            item = QTableWidgetItem(f"{folder.name}   {check.state}")
            item.setForeground(QColor(STATE_COLOURS.get(check.state, "#000000")))
            tip = "\n".join(check.problems) or (
                "verified: may be certified" if check.certifiable else "verified"
            )
            if check.record and check.record.abort_reason:
                tip = f"aborted: {check.record.abort_reason}"
            item.setToolTip(tip)
            verdict, reasons = (
                verdict_of(None, check.record) if check.record is not None else ("", [])
            )
            if check.state != FolderState.COMPLETE:
                verdict, reasons = "", []  # only a verified complete run has a verdict
            verdict_item = QTableWidgetItem(verdict)
            verdict_item.setForeground(QColor(VERDICT_COLOURS.get(verdict, "#555555")))
            font = verdict_item.font()
            font.setBold(True)
            verdict_item.setFont(font)
            verdict_item.setToolTip("\n".join(reasons))
            for column, cell in enumerate((item, verdict_item)):
                cell.setData(FOLDER_ROLE, str(folder))
                cell.setData(STATE_ROLE, check.state)
                self.runs.setItem(row, column, cell)

    def check(self, folder: Path) -> RunCheck | None:
        """inspect_run of `folder`, from the cache when nothing in it changed since."""
        try:
            key = fingerprint(folder)
        except OSError:
            return None
        cached = self._verified.get(folder)
        if cached is not None and cached[0] == key:
            return cached[1]
        check = check_folder(folder)
        if check is not None and check.state not in (FolderState.RUNNING, FolderState.INTERRUPTED):
            self._verified[folder] = (key, check)  # finished: only a change can change it
        return check

    def _row_of(self, name: str) -> int | None:
        for row in range(self.runs.rowCount()):
            item = self.runs.item(row, 0)
            if item is not None and Path(item.data(FOLDER_ROLE)).name == name:
                return row
        return None

    def state_of(self, name: str) -> str | None:
        """The listed state of the run folder `name` (None: not listed)."""
        row = self._row_of(name)
        return None if row is None else self.item(row).data(STATE_ROLE)

    def verdict_of(self, name: str) -> str | None:
        """The verdict column of the run folder `name` ("" when none; None: not listed)."""
        row = self._row_of(name)
        cell = None if row is None else self.runs.item(row, 1)
        return None if cell is None else cell.text()

    def count(self) -> int:
        return self.runs.rowCount()

    def item(self, row: int) -> QTableWidgetItem:
        """The first cell of `row` (run and state)."""
        cell = self.runs.item(row, 0)
        assert cell is not None, f"no run listed in row {row}"
        return cell
