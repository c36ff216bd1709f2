"""Add and edit the lab's customers, sensor models and reference standards (the calibration
table read from a CSV file by the records' own reader, relative uncertainties shown in %).

Every write goes through `app.records.db.lab.Lab` (checked there and audited); a dialog marks a
bad field at the field (`app.gui.field_marks`): what it can see itself (blank, not a number)
before it writes, and the records' refusal ("field: reason") at the field the refusal names.
The dialog stays open until the write succeeds or the technician cancels.
"""

from __future__ import annotations

import html
import logging
from collections.abc import Callable, Sequence
from datetime import date
from pathlib import Path
from typing import Any, ClassVar, TypeVar

from PySide6.QtCore import QDate
from PySide6.QtWidgets import (
    QAbstractItemView,
    QComboBox,
    QDateEdit,
    QDialog,
    QDialogButtonBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QTableWidget,
    QVBoxLayout,
    QWidget,
)

import app.gui.reference_dcc_entry as dcc_entry
from app.gui.field_marks import ERROR, FieldMarks
from app.gui.table_items import read_only_item, shown_unit
from app.io import quantities
from app.io.quantities import Quantity, QuantityError
from app.records.db.errors import RecordsInputError
from app.records.db.reference_table import TableRow, read_reference_table
from app.records.db.units import SENSITIVITY_UNITS
from dsp.multisine import PRESETS

log = logging.getLogger(__name__)

W = TypeVar("W", bound=QWidget)


class FieldError(ValueError):
    """A field the dialog refuses itself: `field` its key, the message the reason."""

    def __init__(self, field: str, reason: str) -> None:
        super().__init__(f"{field}: {reason}")
        self.field, self.reason = field, reason


class FieldErrors(ValueError):
    """Every field the dialog refuses itself at once (each marked at its field)."""

    def __init__(self, errors: list[FieldError]) -> None:
        super().__init__("; ".join(str(e) for e in errors))
        self.errors = errors


class Checked:
    """Reads fields, collecting what is wrong with each instead of stopping at the first."""

    def __init__(self) -> None:
        self.errors: list[FieldError] = []

    def number(self, edit: QLineEdit, field: str, *, optional: bool = False) -> Any:
        try:
            return number(edit, field, optional=optional)
        except FieldError as exc:
            self.errors.append(exc)
            return None

    def quantity(self, edit: QLineEdit, field: str, quantity: Quantity) -> float | None:
        """The quantity typed in `edit`, a bare number or with its unit, read as the command
        line reads it (app.io.quantities); None when refused (the reason kept)."""
        text = edit.text().strip()
        if not text:
            self.errors.append(FieldError(field, "must not be blank"))
            return None
        try:
            return quantity.parse(text, field)
        except QuantityError as exc:  # its reason names the field, as the records' own do
            self.errors.append(FieldError(field, str(exc)))
            return None

    def text(self, edit: QLineEdit, field: str) -> str:
        if not edit.text().strip():
            self.errors.append(FieldError(field, "must not be blank"))
        return edit.text()

    def done(self) -> None:
        """FieldErrors when anything was wrong."""
        if self.errors:
            raise FieldErrors(self.errors)


def number(edit: QLineEdit, field: str, *, optional: bool = False) -> float | None:
    """The number typed in `edit` (None when blank and `optional`); FieldError naming `field`."""
    text = edit.text().strip().replace(",", ".")
    if not text:
        if optional:
            return None
        raise FieldError(field, "must not be blank")
    try:
        return float(text)
    except ValueError:
        raise FieldError(field, f"{text!r} is not a number") from None


def _date(edit: QDateEdit) -> date:
    d = edit.date()
    return date(d.year(), d.month(), d.day())


def _date_edit(day: QDate) -> QDateEdit:
    edit = QDateEdit(day)
    edit.setCalendarPopup(True)
    edit.setDisplayFormat("yyyy-MM-dd")
    return edit


class RecordDialog(QDialog):
    """A form whose OK writes through the records; `save` does the write. `owners` maps the
    field a records refusal names (its text before ':') to a field key of `fields`."""

    owners: ClassVar[dict[str, str]] = {}

    def __init__(self, parent: QWidget | None, lab: Any, title: str) -> None:
        super().__init__(parent)
        self.lab = lab
        self.setWindowTitle(title)
        self.form = QFormLayout(self)
        self.form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.fields: dict[str, QWidget] = {}
        self.marks: FieldMarks | None = None
        self.error = QLabel("")  # a refusal that names no field of the form
        self.error.setWordWrap(True)
        self.saved: Any = None  # what the records hold after OK
        self.setMinimumWidth(480)

    def add(self, key: str, label: str, widget: W) -> W:
        self.fields[key] = widget
        self.form.addRow(label, widget)
        return widget

    def finish(self) -> None:
        """The marks and the buttons (after every field is added)."""
        self.marks = FieldMarks(self.fields)
        self.form.addRow(self.error)
        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        self.form.addRow(buttons)

    def save(self) -> Any:
        raise NotImplementedError

    def marked(self) -> dict[str, str]:
        """{field key: reason} marked now."""
        return self.marks.marked() if self.marks is not None else {}

    def refuse(self, field: str | None, reason: str) -> None:
        """Mark `reason` at `field` (None: under the form)."""
        assert self.marks is not None
        if field in self.fields:
            self.marks.note(self.fields[field], reason, ERROR)
        else:
            self.error.setText(f"<span style='color:#c0392b'>✖ {html.escape(reason)}</span>")

    def field_of(self, message: str) -> str | None:
        """The field key a records refusal is about (None: none of the form's)."""
        head = message.split(":", 1)[0].strip().lower()
        if head in self.fields:
            return head
        for prefix, key in self.owners.items():
            if head.startswith(prefix):
                return key
        return None

    def accept(self) -> None:
        assert self.marks is not None
        for widget in self.fields.values():
            self.marks.note(widget, None)
        self.error.setText("")
        try:
            self.saved = self.save()
        except FieldError as exc:
            self.refuse(exc.field, exc.reason)
            return
        except FieldErrors as many:
            for problem in many.errors:
                self.refuse(problem.field, problem.reason)
            return
        except RecordsInputError as exc:
            self.refuse(self.field_of(str(exc)), str(exc))
            return
        log.info("%s: saved", self.windowTitle())
        super().accept()


class CustomerDialog(RecordDialog):
    """A new customer, or customer `current` edited (name and address)."""

    owners: ClassVar[dict[str, str]] = {"customer": "name"}

    def __init__(self, parent: QWidget | None, lab: Any, current: Any = None) -> None:
        title = f"Edit customer {current.name}" if current is not None else "New customer"
        super().__init__(parent, lab, title)
        self.current = current
        self.name = self.add("name", "Name", QLineEdit(current.name if current else ""))
        self.address = self.add("address", "Address", QLineEdit(current.address if current else ""))
        self.address.setPlaceholderText("street, town, country (printed on certificates)")
        self.finish()

    def save(self) -> Any:
        name, address = self.name.text(), self.address.text()
        if self.current is None:
            return self.lab.add_customer(name, address)
        return self.lab.update_customer(self.current.name, new_name=name, address=address)


class ModelDialog(RecordDialog):
    """A new sensor model, or model `current` edited: nominal sensitivity in its unit,
    tolerance in %, range in Hz, level in m/s² peak per line, phase tolerance in degrees."""

    owners: ClassVar[dict[str, str]] = {
        "nominal sensitivity": "nominal",
        "unit": "unit",
        "tolerance": "tolerance",
        "frequency min": "frequency_min",
        "frequency max": "frequency_max",
        "level": "level",
        "phase tolerance": "phase_tolerance",
        "model": "model",
        "maker": "maker",
    }

    def __init__(self, parent: QWidget | None, lab: Any, current: Any = None) -> None:
        title = (
            f"Edit model {current.maker} {current.model}" if current is not None else "New model"
        )
        super().__init__(parent, lab, title)
        self.current = current
        c = current

        def line(value: float | None, placeholder: str = "") -> QLineEdit:
            edit = QLineEdit("" if value is None else f"{value:g}")
            edit.setPlaceholderText(placeholder)
            return edit

        self.maker = self.add("maker", "Maker", QLineEdit(c.maker if c else ""))
        self.model = self.add("model", "Model", QLineEdit(c.model if c else ""))
        self.nominal = self.add(
            "nominal", "Nominal sensitivity", line(c.nominal_sensitivity if c else None)
        )
        self.unit = QComboBox()
        for unit in SENSITIVITY_UNITS:
            self.unit.addItem(shown_unit(unit), unit)
        if c is not None:
            self.unit.setCurrentIndex(max(0, self.unit.findData(c.unit)))
        self.add("unit", "Unit", self.unit)
        self.tolerance = self.add(
            "tolerance", "Tolerance (%)", line(c.tolerance_percent if c else 5.0)
        )
        self.tolerance.setToolTip("in percent: 5 and 5 % both mean 5 %")
        self.frequency_min = self.add(
            "frequency_min", "Lowest frequency (Hz)", line(c.frequency_min_hz if c else None)
        )
        self.frequency_max = self.add(
            "frequency_max", "Highest frequency (Hz)", line(c.frequency_max_hz if c else None)
        )
        self.preset = QComboBox()
        self.preset.addItems(list(PRESETS))
        if c is not None and c.preset in PRESETS:
            self.preset.setCurrentText(c.preset)
        self.add("preset", "Preset", self.preset)
        self.level = self.add(
            "level", "Level (m/s² peak per line)", line(c.level_ms2 if c else 5.0)
        )
        self.level.setToolTip("in m/s², or with its unit: e.g. 0.5 g (standard gravity)")
        self.phase_tolerance = self.add(
            "phase_tolerance",
            "Phase tolerance (°)",
            line(c.phase_tolerance_deg if c else None, "blank: phase not assessed"),
        )
        self.finish()

    def save(self) -> Any:
        read = Checked()
        values = {
            "maker": read.text(self.maker, "maker"),
            "model": read.text(self.model, "model"),
            "nominal_sensitivity": read.number(self.nominal, "nominal"),
            "unit": self.unit.currentData(),
            "tolerance_percent": read.quantity(self.tolerance, "tolerance", quantities.TOLERANCE),
            "frequency_min_hz": read.number(self.frequency_min, "frequency_min"),
            "frequency_max_hz": read.number(self.frequency_max, "frequency_max"),
            "preset": self.preset.currentText(),
            "level_ms2": read.quantity(self.level, "level", quantities.LEVEL),
            "phase_tolerance_deg": read.number(
                self.phase_tolerance, "phase_tolerance", optional=True
            ),
        }
        read.done()
        if self.current is None:
            return self.lab.add_model(values.pop("maker"), values.pop("model"), **values)
        name = f"{self.current.maker} {self.current.model}"
        return self.lab.update_model(name, **values)


TABLE_COLUMNS = ("f Hz", "S mV/(m/s²)", "U rel. %", "phase °")


class ReferenceDialog(RecordDialog):
    """A new reference standard, or `current` recalibrated: its certificate, dates and
    calibration table (a CSV file as `accelcal refs add --table` reads it; kept when editing
    and no new file is chosen). The table is shown with its relative uncertainties in %."""

    owners: ClassVar[dict[str, str]] = {
        "reference id": "identifier",
        "reference": "identifier",
        "model": "model",
        "serial": "serial",
        "certificate number": "certificate",
        "due date": "due",
        "table": "table",
    }

    def __init__(self, parent: QWidget | None, lab: Any, current: Any = None) -> None:
        title = (
            f"Recalibration of {current.identifier}"
            if current is not None
            else "New reference standard"
        )
        super().__init__(parent, lab, title)
        self.current = current
        c = current
        self.rows: list[TableRow] | None = None  # read from the chosen file
        self.dcc: Any = None  # the DCC read (app.io.reference_dcc) when a DCC was chosen
        self.identifier = self.add("identifier", "Identifier", QLineEdit(c.identifier if c else ""))
        self.identifier.setReadOnly(c is not None)
        self.model = self.add("model", "Model", QLineEdit(c.model if c else ""))
        self.serial = self.add("serial", "Serial", QLineEdit(c.serial if c else ""))
        self.certificate = self.add(
            "certificate",
            "Calibration certificate",
            QLineEdit(c.certificate_number if c else ""),
        )
        today = QDate.currentDate()
        self.calibrated = _date_edit(QDate(c.calibration_date) if c else today)
        self.due = _date_edit(QDate(c.due_date) if c else today.addYears(1))
        self.add("calibrated", "Calibrated on", self.calibrated)
        self.add("due", "Due on", self.due)
        self.table_file = QLineEdit()
        self.table_file.setPlaceholderText(
            "CSV file or DCC" + (" (blank: keep the table on record)" if c is not None else "")
        )
        self.table_file.setToolTip(
            "one line per frequency: frequency_hz, sensitivity_mv_per_ms2, "
            "relative_expanded_uncertainty[, phase_deg] (as accelcal refs add --table), or "
            "the reference's DCC (.xml, as accelcal refs add --dcc)"
        )
        self.table_file.editingFinished.connect(self.load_table)
        self.add("table", "Calibration table", self.table_file)
        browse = QPushButton("Choose CSV file or DCC ...")
        browse.clicked.connect(self.choose_table)
        self.form.addRow("", browse)
        self.preview = QTableWidget(0, len(TABLE_COLUMNS))
        self.preview.setHorizontalHeaderLabels(list(TABLE_COLUMNS))
        self.preview.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.preview.verticalHeader().setVisible(False)
        self.preview.setMinimumHeight(160)
        self.form.addRow(self.preview)
        if c is not None:
            self.show_rows(
                [
                    (
                        p.frequency_hz,
                        p.sensitivity_mv_per_ms2,
                        p.relative_expanded_uncertainty,
                        p.phase_deg,
                    )
                    for p in c.points
                ]
            )
        self.finish()
        self.resize(560, self.sizeHint().height())

    def choose_table(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Calibration table", "", dcc_entry.FILE_FILTER)
        if path:
            self.table_file.setText(path)
            self.load_table()

    def load_table(self, fill: bool = True) -> list[TableRow] | None:
        """Read the CSV named in the file field (the records' reader), or the DCC
        (app.gui.reference_dcc_entry; `fill`: its fields filled in), and show it; a bad file
        is marked at the field. None when the field is blank or the file is refused."""
        assert self.marks is not None
        self.marks.note(self.table_file, None)
        text = self.table_file.text().strip()
        self.rows, self.dcc = None, None
        if not text:
            return None
        if dcc_entry.is_dcc(Path(text)):
            self.rows = dcc_entry.load_dcc(self, Path(text), fill=fill)
            if self.rows is not None:
                self.show_rows(self.rows)
            return self.rows
        try:
            self.rows = read_reference_table(Path(text), "table")
        except RecordsInputError as exc:
            self.marks.note(self.table_file, str(exc), ERROR)
            return None
        self.show_rows(self.rows)
        return self.rows

    def show_rows(self, rows: Sequence[TableRow]) -> None:
        """The table as read: Hz, mV/(m/s²), U relative in %, degrees."""
        self.preview.setRowCount(len(rows))
        for r, (f, s, u, phase) in enumerate(rows):
            cells = (f"{f:g}", f"{s:.6g}", f"{100 * u:.3g}", "" if phase is None else f"{phase:g}")
            for column, text in enumerate(cells):
                self.preview.setItem(r, column, read_only_item(text))

    def save(self) -> Any:
        rows = None
        if self.table_file.text().strip():
            rows = self.load_table(fill=False)  # the fields as typed are checked
            if rows is None:
                raise FieldError("table", self.marks.reason(self.table_file) if self.marks else "")
        elif self.current is None:
            raise FieldError("table", "choose the CSV file of its calibration table or its DCC")
        if self.dcc is not None:
            wrong = dcc_entry.mismatches(
                self.dcc,
                serial=self.serial.text(),
                certificate=self.certificate.text(),
                calibrated=_date(self.calibrated),
            )
            if wrong:
                raise FieldErrors([FieldError(key, reason) for key, reason in wrong])
        values: dict[str, Any] = {
            "model": self.model.text(),
            "serial": self.serial.text(),
            "certificate_number": self.certificate.text(),
            "calibration_date": _date(self.calibrated),
            "due_date": _date(self.due),
        }
        if self.current is None:
            return self.lab.add_reference(
                self.identifier.text(), table=rows, dcc=self.dcc, **values
            )
        return self.lab.update_reference(
            self.current.identifier, table=rows, dcc=self.dcc, **values
        )


class RecordsList(QDialog):
    """One kind of record in a table with Add and Edit (double-click edits too)."""

    def __init__(
        self,
        parent: QWidget | None,
        title: str,
        columns: Sequence[str],
        read: Callable[[], list[Any]],
        cells: Callable[[Any], Sequence[str]],
        editor: Callable[[QWidget, Any], RecordDialog],
    ) -> None:
        super().__init__(parent)
        self.setWindowTitle(title)
        self.read, self.cells, self.editor = read, cells, editor
        self.items: list[Any] = []
        layout = QVBoxLayout(self)
        self.table = QTableWidget(0, len(columns))
        self.table.setHorizontalHeaderLabels(list(columns))
        self.table.horizontalHeader().setSectionResizeMode(QHeaderView.ResizeMode.Stretch)
        self.table.verticalHeader().setVisible(False)
        self.table.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.table.setSelectionMode(QAbstractItemView.SelectionMode.SingleSelection)
        self.table.itemDoubleClicked.connect(lambda _item: self.edit())
        layout.addWidget(self.table, 1)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        layout.addWidget(self.status)
        buttons = QHBoxLayout()
        self.add_button = QPushButton("Add ...")
        self.add_button.clicked.connect(self.add)
        self.edit_button = QPushButton("Edit ...")
        self.edit_button.clicked.connect(self.edit)
        close = QPushButton("Close")
        close.clicked.connect(self.accept)
        for button in (self.add_button, self.edit_button):
            buttons.addWidget(button)
        buttons.addStretch(1)
        buttons.addWidget(close)
        layout.addLayout(buttons)
        self.resize(720, 420)
        self.refresh()

    def refresh(self) -> None:
        try:
            self.items = self.read()
        except RecordsInputError as exc:
            self.status.setText(str(exc))
            self.items = []
        self.table.setRowCount(len(self.items))
        for r, item in enumerate(self.items):
            for c, text in enumerate(self.cells(item)):
                self.table.setItem(r, c, read_only_item(text))

    def open_editor(self, current: Any) -> RecordDialog:
        """The editor of `current` (None: a new record); tests drive it without exec."""
        return self.editor(self, current)

    def add(self) -> bool:
        return self._run(self.open_editor(None))

    def edit(self) -> bool:
        rows = {i.row() for i in self.table.selectedItems()}
        if len(rows) != 1:
            self.status.setText("Select one row to edit.")
            return False
        return self._run(self.open_editor(self.items[rows.pop()]))

    def _run(self, dialog: RecordDialog) -> bool:
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return False
        self.refresh()
        return True


def customers_list(parent: QWidget | None, lab: Any) -> RecordsList:
    return RecordsList(
        parent,
        "Customers",
        ("Name", "Address"),
        lab.customers,
        lambda c: (c.name, c.address or ""),
        lambda p, current: CustomerDialog(p, lab, current),
    )


def models_list(parent: QWidget | None, lab: Any) -> RecordsList:
    return RecordsList(
        parent,
        "Sensor models",
        ("Maker", "Model", "Nominal", "Tolerance", "Range"),
        lab.models,
        lambda m: (
            m.maker,
            m.model,
            f"{m.nominal_sensitivity:g} {shown_unit(m.unit)}",
            f"± {m.tolerance_percent:g} %",
            f"{m.frequency_min_hz:g} to {m.frequency_max_hz:g} Hz",
        ),
        lambda p, current: ModelDialog(p, lab, current),
    )


def references_list(parent: QWidget | None, lab: Any) -> RecordsList:
    return RecordsList(
        parent,
        "Reference standards",
        ("Identifier", "Model / serial", "Certificate", "Calibrated", "Due", "Table"),
        lab.references,
        lambda r: (
            r.identifier,
            f"{r.model} {r.serial}",
            r.certificate_number,
            str(r.calibration_date),
            str(r.due_date),
            f"{len(r.points)} lines",
        ),
        lambda p, current: ReferenceDialog(p, lab, current),
    )
