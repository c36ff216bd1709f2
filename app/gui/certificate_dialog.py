"""What a certificate needs beyond its run: asked afresh for every certificate.

Nothing is carried over from the previous certificate (another customer's name or another
DUT's model on a certificate is the error this prevents); the dialog names the run it is for.
When the records know the run's sensor (by its serial), its customer, address, model and serial
are filled in from them (and say so); everything else starts empty.
"""

from __future__ import annotations

import math

from PySide6.QtWidgets import QDialog, QDialogButtonBox, QFormLayout, QLabel, QLineEdit, QWidget

from app.certificate import CertificateInfo
from app.gui.field_marks import NoteLabel
from app.run_record import RunRecord


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
        ("authorised_by", "Authorised by"),
        ("mounting", "Mounting"),
        ("dut_model", "DUT model (empty: from the run)"),
        ("dut_serial", "DUT serial (empty: from the run)"),
        ("dut_type", "DUT type (empty: from the run)"),
        ("notes", "Notes"),
    )

    def __init__(self, parent: QWidget | None, record: RunRecord, defaults: dict | None = None):
        super().__init__(parent)
        self.setWindowTitle(f"Certificate of run {record.run_id}")
        form = QFormLayout(self)
        heading = NoteLabel()  # wrapped, as tall as its text
        heading.setText(f"<b>Certificate of {run_identity(record)}</b>")
        form.addRow(heading)
        self.edits: dict[str, QLineEdit] = {}
        defaults = defaults or {}
        if defaults:
            form.addRow(QLabel("<i>Customer and sensor filled in from the records.</i>"))
        for key, label in self.FIELDS:
            edit = QLineEdit()
            if defaults.get(key):
                edit.setText(str(defaults[key]))
                edit.setToolTip("from the records, for the run's sensor")
            form.addRow(label, edit)
            self.edits[key] = edit
        self.temperature = QLineEdit()
        self.temperature.setPlaceholderText("°C, as measured during the run")
        form.addRow("Ambient temperature (°C)", self.temperature)
        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def temperature_c(self) -> float | None:
        """The typed temperature (None when empty or not a finite number: refused by name
        when the certificate is built)."""
        text = self.temperature.text().strip().replace(",", ".")
        try:
            value = float(text)
        except ValueError:
            return None
        return value if math.isfinite(value) else None

    def info(self) -> CertificateInfo:
        values = {key: edit.text().strip() or None for key, edit in self.edits.items()}
        return CertificateInfo(
            customer=values["customer"],
            customer_address=values["customer_address"] or "",
            authorised_by=values["authorised_by"],
            mounting=values["mounting"],
            dut_model=values["dut_model"],
            dut_serial=values["dut_serial"],
            dut_type=values["dut_type"],
            notes=values["notes"] or "",
            temperature_c=self.temperature_c(),
        )
