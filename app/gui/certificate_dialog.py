"""What a certificate needs beyond its run: asked afresh for every certificate.

Nothing is carried over from the previous certificate (another customer's name or another
DUT's model on a certificate is the error this prevents); the dialog names the run it is for.
When the records know the run's sensor (by its serial), its customer, address, model and serial
are filled in from them (and say so); the mounting remembered for the sensor's model or the
chosen run template is offered (app.certificate.remembered, and says from where); everything
else starts empty. Temperature and humidity left empty are taken from the stand's environment
sensor as read at run start; the specification names whose tolerances the verdict checked.

"Prepared by" is filled from the window's Technician field (else who the run records); with
the records open, "Prepared by" and "Approved by" (who signs it) are checked by the records'
own rule (`app.certificate.service.check_signatories`: the two-person rule) when OK is pressed,
and a refusal is shown at its field while the dialog stays open.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFormLayout,
    QLabel,
    QLineEdit,
    QWidget,
)

from app.certificate import CertificateInfo
from app.certificate.info import SPEC_WORDS, Specification, SpecKind
from app.gui.field_marks import ERROR, FieldMarks, NoteLabel
from app.records.db.errors import RecordsInputError
from app.records.run_record import RunRecord
from app.stand.instruments import parse_humidity

FIELD_CHARS = 64  # each field's narrowest, in average characters: an address of 55 whole
Signatories = Callable[[str, str], object]  # (prepared by, approved by): raises when refused


def run_identity(record: RunRecord) -> str:
    """'run <id>, DUT serial <serial>, <date>' of a stored run's record."""
    serial = (record.dut.id if record.dut else None) or "not given"
    return (
        f"run {record.run_id}, DUT serial {serial}, "
        f"{record.started_utc or record.finished_utc or 'date unknown'}"
    )


class CertificateDialog(QDialog):
    """Customer, signatory and conditions for one certificate; every field starts empty but
    what the records say of the run's sensor (`defaults`: CertificateInfo field -> value)."""

    FIELDS = (
        ("customer", "Customer"),
        ("customer_address", "Customer address"),
        ("address_not_stated", "Address not stated, because"),
        ("authorised_by", "Authorised by"),
        ("authorised_function", "Function (e.g. head of laboratory)"),
        ("mounting", "Mounting"),
        ("dut_model", "DUT model (empty: from the run)"),
        ("dut_serial", "DUT serial (empty: from the run)"),
        ("dut_type", "DUT type (empty: from the run)"),
        ("spec_id", "Specification: document and revision"),
        ("spec_tolerances", "Specification: tolerances (empty: those checked)"),
        ("notes", "Notes"),
    )
    NO_SPECIFICATION = "(none: the run's own, e.g. its catalogue data sheet)"

    def __init__(
        self,
        parent: QWidget | None,
        record: RunRecord,
        defaults: dict | None = None,
        *,
        prepared_by: str = "",
        check: Signatories | None = None,
        heading: str = "",
        offered_from: str = "",
        template: str = "",
    ):
        """`prepared_by` fills "Prepared by"; `check` is the records' rule for the two
        signatories, run when OK is pressed (None: no records, no rule); `offered_from` says
        where the mounting in `defaults` is remembered from ("model X"); `template` is the run
        template chosen (the mounting is remembered for it too)."""
        super().__init__(parent)
        self.setWindowTitle(f"Certificate of run {record.run_id}")
        self._check = check
        self.template = template
        form = QFormLayout(self)
        self.title = NoteLabel()  # wrapped, as tall as its text
        self.title.setText(f"<b>{heading or 'Certificate'} of {run_identity(record)}</b>")
        form.addRow(self.title)
        self.edits: dict[str, QLineEdit] = {}
        # a customer's name and address, a model or a document reads whole (px)
        field_width = FIELD_CHARS * self.fontMetrics().averageCharWidth()
        defaults = defaults or {}
        if defaults:
            form.addRow(QLabel("<i>Customer and sensor filled in from the records.</i>"))
        self.prepared = QLineEdit(prepared_by)
        self.prepared.setToolTip("who prepared the certificate (the technician)")
        form.addRow("Prepared by", self.prepared)
        for key, label in self.FIELDS:
            if key == "authorised_by" and check is not None:
                label = "Approved by (signs)"
            edit = QLineEdit()
            if defaults.get(key):
                edit.setText(str(defaults[key]))
                edit.setToolTip("from the records, for the run's sensor")
            if key == "mounting" and offered_from and defaults.get(key):
                edit.setToolTip(f"from {offered_from}")
                # "&" of a model's maker (Brüel & Kjær) shown, not taken for a shortcut key
                label = f"Mounting (from {offered_from.replace('&', '&&')})"
            edit.setMinimumWidth(field_width)
            if key == "spec_id":
                self.spec_kind = QComboBox()
                self.spec_kind.addItem(self.NO_SPECIFICATION, None)
                for kind in SpecKind:
                    self.spec_kind.addItem(SPEC_WORDS[kind], kind)
                form.addRow("Specification: kind", self.spec_kind)
            form.addRow(label, edit)
            self.edits[key] = edit
        self.temperature = QLineEdit()
        self.temperature.setPlaceholderText("°C, as measured during the run")
        form.addRow("Ambient temperature (°C)", self.temperature)
        self.humidity = QLineEdit()
        self.humidity.setPlaceholderText("%, e.g. 45 %; empty: as the stand's sensor read it")
        form.addRow("Relative humidity (%)", self.humidity)
        self.temperature.setPlaceholderText("°C; empty: as the stand's sensor read it")
        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)
        marked: dict[str, QWidget] = {
            "approved_by": self.edits["authorised_by"],
            "prepared_by": self.prepared,
            "humidity": self.humidity,
            "specification": self.edits["spec_id"],
        }
        self.marks = FieldMarks(marked)

    def prepared_by(self) -> str:
        """The "Prepared by" field as typed."""
        return self.prepared.text().strip()

    def accept(self) -> None:
        """Close only when the humidity reads and the specification is whole and the records
        take the two signatories; else say why at the field."""
        for key, problem in (
            ("humidity", self._humidity_problem()),
            ("specification", self._spec_problem()),
        ):
            widget = self.marks.fields[key]
            self.marks.note(widget, problem, ERROR)
            if problem:
                widget.setFocus()
                return
        if self._check is not None:
            approved = self.edits["authorised_by"]
            for edit in (approved, self.prepared):
                self.marks.note(edit, None)
            try:
                self._check(self.prepared_by(), approved.text())
            except RecordsInputError as exc:
                text = str(exc)
                field = approved
                if text.startswith("prepared by"):
                    field = self.prepared
                self.marks.note(field, text, ERROR)
                field.setFocus()
                return
        super().accept()

    def temperature_c(self) -> float | None:
        """The typed temperature (None when empty or not a finite number: refused by name
        when the certificate is built)."""
        text = self.temperature.text().strip().replace(",", ".")
        try:
            value = float(text)
        except ValueError:
            return None
        return value if math.isfinite(value) else None

    def humidity_percent(self) -> float | None:
        """The typed relative humidity in % (None: empty, or not one: refused at OK)."""
        try:
            return parse_humidity(self.humidity.text())
        except ValueError:
            return None

    def _humidity_problem(self) -> str | None:
        try:
            parse_humidity(self.humidity.text())
        except ValueError as exc:
            return str(exc).replace(" (--humidity)", "")
        return None

    def specification(self) -> Specification | None:
        """The specification chosen (None: the run's own)."""
        kind = self.spec_kind.currentData()
        identity = " ".join(self.edits["spec_id"].text().split())
        if kind is None or not identity:
            return None
        return Specification(SpecKind(kind), identity, self.edits["spec_tolerances"].text().strip())

    def _spec_problem(self) -> str | None:
        kind = self.spec_kind.currentData()
        identity = self.edits["spec_id"].text().strip()
        if kind is not None and not identity:
            return "specification: name its document and revision"
        if kind is None and identity:
            return "specification: choose its kind (data sheet, customer requirement, standard)"
        return None

    def info(self) -> CertificateInfo:
        values = {key: edit.text().strip() or None for key, edit in self.edits.items()}
        return CertificateInfo(
            customer=values["customer"],
            customer_address=values["customer_address"] or "",
            address_not_stated=values["address_not_stated"] or "",
            humidity_percent=self.humidity_percent(),
            specification=self.specification(),
            template=self.template,
            authorised_by=values["authorised_by"],
            authorised_function=values["authorised_function"] or "",
            mounting=values["mounting"],
            dut_model=values["dut_model"],
            dut_serial=values["dut_serial"],
            dut_type=values["dut_type"],
            notes=values["notes"] or "",
            temperature_c=self.temperature_c(),
            prepared_by=self.prepared_by(),
        )
