"""The DUT serial field against the records: typed or scanned (a barcode scanner types and
presses Enter), looked up by exact serial only, never guessed.

A serial on record fills the DUT's nominal sensitivity, tolerance, level and preset from its
model (and says so under the field). An unknown serial fills nothing: it offers to register
the sensor (model and owner chosen from the records), and when declined the field is marked
"not in the records" (the run is still stored under that serial, and `accelcal db import`
links it once the sensor is registered). Records that cannot be opened are said so.
"""

from __future__ import annotations

import logging
from typing import Any

from PySide6.QtCore import QObject, Signal
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QFormLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QSpinBox,
    QWidget,
)

from app.gui.field_marks import INFO, WARNING, FieldMarks
from app.gui.table_items import shown_unit
from app.procedure.request import spec_from_sensor
from app.records.db.errors import RecordsInputError
from app.records.db.runs import defaults_of
from app.stand.dut import DutSpec
from dsp.multisine import PRESETS

log = logging.getLogger(__name__)


class RegisterSensorDialog(QDialog):
    """A new sensor: the serial as typed (not editable here), its model, owner and interval."""

    def __init__(self, parent: QWidget | None, serial: str, models: list[Any], owners: list[Any]):
        super().__init__(parent)
        self.setWindowTitle(f"Register sensor {serial}")
        form = QFormLayout(self)
        heading = QLabel(
            f"<b>{serial}</b> is not in the records. Register it with the model and owner "
            "below; nothing is taken from another sensor."
        )
        heading.setWordWrap(True)
        form.addRow(heading)
        self.serial = QLineEdit(serial)
        self.serial.setReadOnly(True)
        self.model = QComboBox()
        for m in models:
            self.model.addItem(
                f"{m.maker} {m.model} ({m.nominal_sensitivity:g} {shown_unit(m.unit)})",
                f"{m.maker} {m.model}",
            )
        self.owner = QComboBox()
        for c in owners:
            self.owner.addItem(c.name, c.name)
        self.interval = QSpinBox(minimum=1, maximum=120, value=12, suffix=" months")
        form.addRow("Serial", self.serial)
        form.addRow("Model", self.model)
        form.addRow("Owner", self.owner)
        form.addRow("Calibration interval", self.interval)
        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def values(self) -> dict[str, Any]:
        return {
            "model": self.model.currentData(),
            "owner": self.owner.currentData(),
            "interval_months": self.interval.value(),
        }


class SerialEntry(QObject):
    """Looks the DUT serial up when it is entered (Enter, or the field left). `sensor_changed`
    carries the sensor on record now (None: none), for the templates of its model."""

    sensor_changed = Signal(object)

    def __init__(self, setup: Any, link: Any, marks: FieldMarks, field: Any = None) -> None:
        super().__init__(setup)
        self.setup, self.link, self.marks = setup, link, marks
        # the serial field it looks up: the single DUT's, or a fixture position's
        self.field = field if field is not None else setup.dut_id
        self.sensor: Any = None
        self._looked_up: str | None = None
        self._busy = False
        self.field.editingFinished.connect(self.look_up)
        self.field.textEdited.connect(self._edited)

    def _edited(self, _text: str) -> None:
        """Typing again forgets the last look-up (the fields it filled stay until next sensor)."""
        had = self.sensor is not None
        self._looked_up = None
        self.sensor = None
        self.marks.note(self.field, None)
        if had:
            self.sensor_changed.emit(None)

    def reset(self) -> None:
        self._looked_up, self.sensor = None, None
        self.marks.note(self.field, None)
        self.sensor_changed.emit(None)

    def take(self, sensor: Any, how: str) -> None:
        """A sensor found another way (its TEDS): as if its serial had been typed."""
        self._looked_up = sensor.serial
        self.fill(sensor, how)

    def look_up(self) -> Any:
        """The sensor on record for the serial typed (None: unknown or no records)."""
        serial = self.field.text().strip()
        if self._busy or serial == self._looked_up:
            return self.sensor
        had = self.sensor is not None
        self._looked_up, self.sensor = serial, None
        if had:
            self.sensor_changed.emit(None)
        if not serial:
            self.marks.note(self.field, None)
            return None
        if self.link.lab is None:
            self.marks.note(
                self.field,
                f"not checked: {self.link.describe()}; the run is stored under this serial",
                WARNING,
            )
            return None
        self._busy = True
        try:
            sensor = self.link.sensor(serial)
            if sensor is None:
                self.marks.note(
                    self.field,
                    f"{serial} is not in the records: nothing filled in; register it, or the run "
                    "is stored under this serial only",
                    WARNING,
                )
                if self.offer_registration(serial):
                    sensor = self.link.sensor(serial)
        except RecordsInputError as exc:
            self.marks.note(self.field, f"records: {exc}", WARNING)
            sensor = None
        finally:
            self._busy = False
        if sensor is not None:
            self.fill(sensor)
        return sensor

    def offer_registration(self, serial: str) -> bool:
        """Ask; register through the records when accepted. Whether the sensor now exists."""
        lab = self.link.lab
        answer = QMessageBox.question(
            self.setup,
            "Unknown sensor",
            f"{serial} is not in the records.\n\nRegister it now? Nothing is filled in from "
            "another sensor.",
        )
        if answer != QMessageBox.StandardButton.Yes:
            return False
        models, owners = lab.models(), lab.customers()
        if not models or not owners:
            QMessageBox.information(
                self.setup,
                "Register sensor",
                "The records have no sensor model or no customer yet: add them first "
                "(tab 5 Sensors: Customers ..., Models ...).",
            )
            return False
        dialog = RegisterSensorDialog(self.setup, serial, models, owners)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return False
        try:
            lab.add_sensor(serial, **dialog.values())
        except RecordsInputError as exc:
            QMessageBox.warning(self.setup, "Sensor not registered", str(exc))
            return False
        return True

    @property
    def spec(self) -> DutSpec | None:
        """The specification of the sensor on record now (None: none looked up)."""
        return spec_from_sensor(defaults_of(self.sensor)) if self.sensor is not None else None

    def fill(self, sensor: Any, how: str = "") -> None:
        """The DUT's settings from its record (exact serial only), resolved as a run resolves
        them (the run service's `dut_settings`); `how` it was identified."""
        w = self.setup
        resolved = w.service.dut_settings(spec_from_sensor(defaults_of(sensor)))
        self.sensor = sensor
        model = sensor.model
        if resolved.nominal_mv_per_ms2 is not None:
            w.nominal.setValue(resolved.nominal_mv_per_ms2)
        if resolved.tolerance_percent is not None:
            w.tolerance.setValue(resolved.tolerance_percent)
        w.level.setValue(resolved.level_ms2)
        if resolved.preset in PRESETS:
            w.preset.setCurrentText(resolved.preset)
        due = f", due {sensor.due_date}" if sensor.due_date else ""
        self.marks.note(
            self.field,
            f"from the records{f' ({how})' if how else ''}: {model.maker} {model.model}, "
            f"owner {sensor.owner.name}{due}; "
            f"nominal {model.nominal_sensitivity:g} {shown_unit(model.unit)}, tolerance "
            f"{model.tolerance_percent:g} %",
            INFO,
        )
        self.sensor_changed.emit(sensor)
