"""The Register tab: the lab's certificate register (number, state, sensor, customer, run, date,
prepared and approved by, what it replaces, the reason). From a selected certificate: "Amend /
reissue ..." asks the reason (required), the run (the sensor's complete runs, the certificate's
own first) and the certificate's fields, and issues a new certificate that replaces it;
"Withdraw ..." asks the reason; "Open PDF" opens its PDF when its SHA-256 is the register's.
A certificate under review (17025 7.10, `accelcal impact`) says so in the Review column; "Close
review ..." asks confirmed or amended (by which amendment) and a reason. The
rules (which state may be replaced, the two-person rule, the numbers) are the records'
(`app.records.db.lab.Lab`); this tab asks and shows.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from PySide6.QtCore import QUrl
from PySide6.QtGui import QDesktopServices
from PySide6.QtWidgets import (
    QAbstractItemView,
    QHBoxLayout,
    QHeaderView,
    QInputDialog,
    QMessageBox,
    QPushButton,
    QTableWidget,
    QVBoxLayout,
    QWidget,
)

from app.gui import certify
from app.gui.results_tab import wrapping_label
from app.gui.table_items import read_only_item
from app.records.db.errors import RecordsInputError
from app.records.run_folder import RunIntegrityError, load_run

log = logging.getLogger(__name__)

COLUMNS = (
    "Number",
    "State",
    "Review",
    "Sensor",
    "Customer",
    "Run",
    "Issued (UTC)",
    "Prepared by",
    "Approved by",
    "Replaces",
    "Reason",
)
STATE_COLOUR = {"issued": "#1e8449", "replaced": "#7f8c8d", "withdrawn": "#c0392b"}
UNDER_REVIEW = "under review"  # the Review column's words for an open review (then its subject)
REVIEW_COLOUR = "#d35400"
CONFIRM, AMEND = "confirmed: the result stands", "amended: an amendment replaces it"


class RegisterTab(QWidget):
    """The certificate register of the window's records; amend, reissue and withdraw."""

    def __init__(self, window: Any) -> None:
        super().__init__()
        self.main = window
        self.link = window.records
        layout = QVBoxLayout(self)
        self.status = wrapping_label(self.link.describe())
        layout.addWidget(self.status)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.verticalHeader().setVisible(False)
        header = self.table.horizontalHeader()
        header.setSectionResizeMode(QHeaderView.ResizeMode.ResizeToContents)
        header.setStretchLastSection(True)
        self.table.itemSelectionChanged.connect(self._selected)
        layout.addWidget(self.table, 1)
        buttons = QHBoxLayout()
        self.refresh_button = QPushButton("Refresh")
        self.refresh_button.setToolTip("Read the register again")
        self.refresh_button.clicked.connect(self.refresh)
        self.amend_button = QPushButton("Amend / reissue ...")
        self.amend_button.setToolTip(
            "Issue a new certificate that replaces the selected one (a reason is required)"
        )
        self.amend_button.clicked.connect(self.amend)
        self.withdraw_button = QPushButton("Withdraw ...")
        self.withdraw_button.setToolTip("Withdraw the selected certificate (a reason is required)")
        self.withdraw_button.clicked.connect(self.withdraw)
        self.open_button = QPushButton("Open PDF")
        self.open_button.setToolTip("Open the selected certificate's PDF (its SHA-256 checked)")
        self.open_button.clicked.connect(self.open_pdf)
        self.review_button = QPushButton("Close review ...")
        self.review_button.setToolTip(
            "Close the selected certificate's review: confirmed, or amended by its amendment "
            "(a reason is required)"
        )
        self.review_button.clicked.connect(self.close_review)
        self.files: dict[str, tuple[str, str | None]] = {}  # number -> (PDF path, SHA-256)
        for button in (
            self.refresh_button,
            self.open_button,
            self.amend_button,
            self.withdraw_button,
            self.review_button,
        ):
            buttons.addWidget(button)
        buttons.addStretch(1)
        layout.addLayout(buttons)
        self.link.changed.connect(self.refresh)
        self.refresh()

    # --- reading -------------------------------------------------------------------------

    def refresh(self) -> None:
        """Read the register (milliseconds, GUI thread) and list it, newest last."""
        self.status.setText(self.link.describe())
        lab = self.link.lab
        rows: list[tuple[str, ...]] = []
        if lab is not None:
            try:
                register = lab.register()
                reviews = self._review_words(lab.reviews())
                rows = [self._row(c, reviews.get(c.number, "")) for c in register]
                self.files = {c.number: (c.file, c.sha256) for c in register if c.file}
            except RecordsInputError as exc:
                self.status.setText(f"register not read: {exc}")
        selected = self.selected_number()
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, text in enumerate(row):
                colour = STATE_COLOUR.get(text) if c == 1 else None
                if c == 2 and text.startswith(UNDER_REVIEW):
                    colour = REVIEW_COLOUR
                self.table.setItem(r, c, read_only_item(text, colour))
        if selected is not None:
            self.select(selected)
        self._selected()

    @staticmethod
    def _review_words(reviews: list[Any]) -> dict[str, str]:
        """Each reviewed certificate's Review cell: "under review (subject; ...)" while any
        review is open, else how the last one was closed."""
        words: dict[str, str] = {}
        open_subjects: dict[str, list[str]] = {}
        for review in reviews:  # oldest first: the last closed one wins
            if review.outcome is None:
                open_subjects.setdefault(review.number, []).append(review.subject)
            elif review.amended_by:
                words[review.number] = f"amended by {review.amended_by}"
            else:
                words[review.number] = str(review.outcome)
        for number, subjects in open_subjects.items():
            words[number] = f"{UNDER_REVIEW} ({'; '.join(subjects)})"
        return words

    @staticmethod
    def _row(c: Any, review: str = "") -> tuple[str, ...]:
        """One certificate's cells (read while its session's objects are fresh)."""
        return (
            c.number,
            c.state,
            review,
            c.sensor.serial,
            c.customer.name,  # issued to (migration 0014), whoever owns the sensor now
            c.run.run_id,
            c.issued_utc.strftime("%Y-%m-%d %H:%M"),
            c.prepared_by,
            c.approved_by,
            c.replaces or "",
            c.reason or "",
        )

    def cell(self, row: int, column: str) -> str:
        item = self.table.item(row, COLUMNS.index(column))
        return item.text() if item is not None else ""

    def numbers(self) -> list[str]:
        return [self.cell(r, "Number") for r in range(self.table.rowCount())]

    def select(self, number: str) -> bool:
        """Select the certificate `number`; whether it is listed."""
        for row in range(self.table.rowCount()):
            if self.cell(row, "Number") == number:
                self.table.selectRow(row)
                return True
        return False

    def selected_number(self) -> str | None:
        rows = self.table.selectionModel().selectedRows()
        return self.cell(rows[0].row(), "Number") if rows else None

    def _selected(self) -> None:
        rows = self.table.selectionModel().selectedRows()
        issued = bool(rows) and self.cell(rows[0].row(), "State") == "issued"
        running = self.main.run_tab.worker is not None  # no amendment while a run goes
        self.amend_button.setEnabled(issued and not running)
        self.withdraw_button.setEnabled(issued)
        self.open_button.setEnabled(bool(rows) and self.selected_number() in self.files)
        reviewed = bool(rows) and self.cell(rows[0].row(), "Review").startswith(UNDER_REVIEW)
        self.review_button.setEnabled(reviewed)

    def open_pdf(self) -> Path | None:
        """Open the selected certificate's PDF when its bytes are the register's; the path."""
        from app.records.run_folder import sha256_of

        entry = self.files.get(self.selected_number() or "")
        if entry is None:
            return None
        path = Path(entry[0])
        try:
            same = sha256_of(path) == entry[1]
        except (OSError, ValueError) as exc:
            QMessageBox.warning(self, "PDF not opened", f"{path}: {exc}")
            return None
        if not same:
            QMessageBox.warning(self, "PDF not opened", f"{path}: not the register's file")
            return None
        QDesktopServices.openUrl(QUrl.fromLocalFile(str(path.resolve())))
        return path

    # --- amending and withdrawing --------------------------------------------------------

    def _reason(self, title: str, prompt: str) -> str | None:
        """A reason typed by the user (None when cancelled; a blank one is refused by name)."""
        text, ok = QInputDialog.getText(self, title, prompt)
        if not ok:
            return None
        if not text.strip():
            QMessageBox.warning(self, title, "reason: must not be blank")
            return None
        return text.strip()

    def amend(self) -> Path | None:
        """Amend or reissue the selected certificate: reason, run, fields; the new PDF."""
        number = self.selected_number()
        lab = self.link.lab
        if number is None or lab is None:
            return None
        row = self.table.selectionModel().selectedRows()[0].row()
        serial, old_run = self.cell(row, "Sensor"), self.cell(row, "Run")
        reason = self._reason(
            f"Amend or reissue {number}",
            f"Why is {number} amended or reissued? (required; it is kept in the register)",
        )
        if reason is None:
            return None
        try:
            runs = lab.complete_runs(serial)
        except RecordsInputError as exc:
            QMessageBox.warning(self, "Amendment refused", str(exc))
            return None
        choices = {r.run_id: Path(r.folder) for r in runs}
        names = sorted(choices, key=lambda run_id: run_id != old_run)  # its own run first
        if len(names) > 1:
            run_id, ok = QInputDialog.getItem(
                self, f"Amend {number}", f"Run of {serial} to certify:", names, 0, False
            )
            if not ok:
                return None
        elif names:
            run_id = names[0]
        else:
            QMessageBox.warning(self, "Amendment refused", f"run: no complete run of {serial}")
            return None
        folder = choices[run_id]
        try:
            record = load_run(folder)  # verified again
        except (RunIntegrityError, ValueError) as exc:
            QMessageBox.warning(self, "Amendment refused", str(exc))
            return None
        path = certify.ask(self.main, folder, record, replaces=number, reason=reason)
        self.refresh()
        return path

    def withdraw(self) -> bool:
        """Withdraw the selected certificate with a reason; whether it was withdrawn."""
        number = self.selected_number()
        lab = self.link.lab
        if number is None or lab is None:
            return False
        reason = self._reason(
            f"Withdraw {number}", f"Why is {number} withdrawn? (required; kept in the register)"
        )
        if reason is None:
            return False
        try:
            lab.withdraw_certificate(number, reason)
        except RecordsInputError as exc:
            QMessageBox.warning(self, "Withdrawal refused", str(exc))
            return False
        log.info("certificate %s withdrawn: %s", number, reason)
        self.refresh()
        return True

    def close_review(self) -> bool:
        """Close the selected certificate's open reviews: confirmed, or amended by one of
        the certificates that replace it; a reason asked. Whether they were closed."""
        number = self.selected_number()
        lab = self.link.lab
        if number is None or lab is None:
            return False
        title = f"Close the review of {number}"
        how, ok = QInputDialog.getItem(
            self, title, f"How is the review of {number} decided?", [CONFIRM, AMEND], 0, False
        )
        if not ok:
            return False
        amended_by = None
        if how == AMEND:
            amendments = [
                self.cell(r, "Number")
                for r in range(self.table.rowCount())
                if self.cell(r, "Replaces") == number
            ]
            if not amendments:
                QMessageBox.warning(
                    self,
                    "Review not closed",
                    f"amended by: no certificate replaces {number} yet; issue its amendment "
                    "first (Amend / reissue ...)",
                )
                return False
            amended_by = amendments[0]
            if len(amendments) > 1:
                amended_by, ok = QInputDialog.getItem(
                    self, title, f"The amendment of {number}:", amendments, 0, False
                )
                if not ok:
                    return False
        reason = self._reason(title, "Why? (required; kept in the register and audited)")
        if reason is None:
            return False
        outcome = "amended" if how == AMEND else "confirmed"
        try:
            lab.close_review(number, outcome=outcome, reason=reason, amended_by=amended_by)
        except RecordsInputError as exc:
            QMessageBox.warning(self, "Review not closed", str(exc))
            return False
        log.info("review of %s closed: %s (%s)", number, outcome, reason)
        self.refresh()
        return True
