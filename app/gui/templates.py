"""Run templates on the Setup tab: the current sensor's model's templates in a list (chosen: the
plan fields are filled from it), and "Save as template ..." from the settings of the run just
made (or the fields as they are). Templates live in the records (`Lab.add_template`,
`Lab.templates`), which check every field and name it when refusing.
"""

from __future__ import annotations

import logging
from dataclasses import replace
from typing import Any

from PySide6.QtCore import QObject
from PySide6.QtWidgets import QComboBox, QInputDialog, QMessageBox, QPushButton

from app.procedure.run import RunRequest
from app.records.db.errors import RecordsInputError

log = logging.getLogger(__name__)

NONE_CHOSEN = "(the model's own settings)"


def model_name(sensor: Any) -> str:
    """'maker model' of a sensor's model, as the records name it."""
    return f"{sensor.model.maker} {sensor.model.model}"


class TemplatePicker(QObject):
    """The template list and the save button of the Setup tab's plan form."""

    def __init__(self, setup: Any, link: Any) -> None:
        super().__init__(setup)
        self.setup, self.link = setup, link
        self.combo = QComboBox()
        self.combo.setToolTip("Run templates of the sensor's model (from the records)")
        self.combo.activated.connect(self._chosen)
        self.save_button = QPushButton("Save as template ...")
        self.save_button.setToolTip(
            "Save the settings of the run just made (or the fields) as a template of the "
            "sensor's model"
        )
        self.save_button.clicked.connect(self.save)
        self.templates: list[Any] = []
        self.model: str | None = None
        self.show_for(None)

    def show_for(self, sensor: Any) -> None:
        """List the templates of `sensor`'s model (None: no sensor, an empty list)."""
        self.model = model_name(sensor) if sensor is not None else None
        self.templates = []
        lab = self.link.lab
        if self.model is not None and lab is not None:
            try:
                self.templates = lab.templates(self.model)
            except RecordsInputError as exc:
                log.warning("templates not read: %s", exc)
        self.combo.clear()
        if self.model is None:
            self.combo.addItem("(look a sensor up first)")
        else:
            self.combo.addItem(NONE_CHOSEN)
            for template in self.templates:
                self.combo.addItem(template.name)
        self.combo.setEnabled(bool(self.templates))
        self.save_button.setEnabled(self.model is not None)

    def names(self) -> list[str]:
        return [t.name for t in self.templates]

    def choose(self, name: str) -> bool:
        """Choose the template `name` (as the user does); whether it exists."""
        index = self.combo.findText(name)
        if index < 1:
            return False
        self.combo.setCurrentIndex(index)
        self._chosen(index)
        return True

    def _chosen(self, index: int) -> None:
        if 1 <= index <= len(self.templates):
            self.apply(self.templates[index - 1])

    def apply(self, template: Any) -> None:
        """The plan fields from `template` (tolerance only when the template sets one)."""
        now = self.setup.plan_settings()
        lines = template.lines_hz()
        self.setup.apply_plan(
            replace(
                now,
                preset=template.preset,
                frequencies=",".join(f"{f:g}" for f in lines) if lines else "",
                level_ms2=template.level_ms2,
                periods=template.periods,
                target_percent=100 * (template.target_type_a or 0.0),
                max_time_s=int(template.max_acquisition_s or 0),
                estimator=template.estimator,
                tolerance_percent=(
                    now.tolerance_percent
                    if template.tolerance_percent is None
                    else template.tolerance_percent
                ),
            )
        )

    def source(self) -> tuple[RunRequest, str]:
        """The settings a new template takes: the run just made when it was of this serial,
        else the fields; with a word saying which."""
        w = self.setup
        last: RunRequest | None = w.last_request
        serial = w.dut_id.text().strip()
        if last is not None and last.dut_id == serial:
            return last, f"the settings of the run just made on {serial}"
        return w.request(), "the settings in the fields"

    def save(self) -> str | None:
        """Ask a name and save the template; its name, None when cancelled or refused."""
        lab = self.link.lab
        if lab is None or self.model is None:
            QMessageBox.information(
                self.setup, "Template", "Look a sensor up first: a template belongs to a model."
            )
            return None
        try:
            request, what = self.source()
        except ValueError as exc:  # a refusal of the fields (lines, stand file), named
            QMessageBox.warning(self.setup, "Template not saved", str(exc))
            return None
        name, ok = QInputDialog.getText(
            self.setup,
            "Save as template",
            f"Name of the template for {self.model} ({what}):",
        )
        if not ok:
            return None
        try:
            lab.add_template(
                self.model,
                name,
                preset=request.preset or "piezo",
                frequencies_hz=request.frequencies_hz,
                level_ms2=request.level_ms2,
                periods=request.periods,
                target_type_a=request.target_type_a,
                max_acquisition_s=request.max_acquisition_s,
                tolerance_percent=request.tolerance_percent,
                estimator=request.estimator,
            )
        except RecordsInputError as exc:
            QMessageBox.warning(self.setup, "Template not saved", str(exc))
            return None
        name = name.strip()
        log.info("template %r saved for %s", name, self.model)
        self.show_for_model_again()
        self.combo.setCurrentIndex(self.combo.findText(name))
        return name

    def show_for_model_again(self) -> None:
        self.show_for(self.setup.serial_entry.sensor)
