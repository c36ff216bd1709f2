"""Bad input marked at its field: a red frame and the reason in a line right under the field
(and in its tooltip), before Start is enabled. The window's plan checks (`SetupTab.validate`)
already refuse Start while anything fails; this says *where*.

Each problem of the checks is given to the field it is about (the lines field for a line, the
level for a predicted peak over the stand's limits); a field may also carry a note of its own
(the DUT serial: "not in the records").
"""

from __future__ import annotations

import html
from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QFormLayout, QLabel, QSizePolicy, QWidget

from app.gui.table_items import shown_unit

ERROR, WARNING, INFO = "error", "warning", "info"
STYLE = {ERROR: "#c0392b", WARNING: "#b9770e", INFO: "#1e8449"}
SYMBOL = {ERROR: "✖", WARNING: "⚠", INFO: "✔"}
# the refusal of a quantity field starts with its name (app.gui.quantity_edit): the field
FIELD_PREFIXES = {
    "level:": "level",
    "nominal sensitivity:": "nominal",
    "tolerance:": "tolerance",
    "type a target:": "target",
    "stepped block:": "stepped_block",
}


def field_for(problem: str, fields: dict[str, QWidget]) -> QWidget | None:
    """The field a plan-check problem is about (None: no single field)."""
    text = problem.lower()
    if text.startswith("optimising"):
        return None
    for prefix, name in FIELD_PREFIXES.items():  # a field's own refusal ("level: ...")
        if text.startswith(prefix):
            return fields.get(name)
    if any(word in text for word in ("displacement", "velocity", "acceleration")):
        return fields.get("level")
    if text.startswith(("lines:", "line ", "reference frequency")):
        return fields.get("frequencies")
    return None


class NoteLabel(QLabel):
    """A wrapped note exactly as tall as its text at the width it is given (a wrapped label in
    a form otherwise reserves the height of a much narrower one), never widening the form."""

    def __init__(self) -> None:
        super().__init__()
        self.setWordWrap(True)
        self.setAlignment(Qt.AlignmentFlag.AlignLeft | Qt.AlignmentFlag.AlignTop)
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Fixed)
        self.setMinimumWidth(1)

    def _fit(self) -> None:
        height = self.heightForWidth(max(self.width(), 1)) if self.text() else 0
        if height >= 0 and height != self.height():
            self.setFixedHeight(height)

    def setText(self, text: str) -> None:
        super().setText(text)
        self._fit()

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._fit()


class FieldMarks:
    """Marks on the fields of QFormLayouts; each field gets a note row under it."""

    def __init__(self, fields: dict[str, QWidget]) -> None:
        self.fields = fields
        self.notes: dict[QWidget, QLabel] = {}
        self._styles: dict[QWidget, str] = {}
        self._tips: dict[QWidget, str] = {}
        self._own: dict[QWidget, tuple[str, str]] = {}  # notes set by `note`
        for widget in fields.values():
            self._attach(widget)

    def _form(self, widget: QWidget) -> tuple[QFormLayout, int] | None:
        parent = widget.parentWidget()
        layout = parent.layout() if parent is not None else None
        if not isinstance(layout, QFormLayout):
            return None
        row = int(layout.getWidgetPosition(widget)[0])  # type: ignore[index]
        return (layout, row) if row >= 0 else None

    def _attach(self, widget: QWidget) -> None:
        label = NoteLabel()
        place = self._form(widget)
        self.notes[widget] = label
        self._styles[widget] = widget.styleSheet()
        self._tips[widget] = widget.toolTip()
        if place is not None:
            form, row = place
            form.insertRow(row + 1, "", label)
        self._show(widget, None)

    def _show(self, widget: QWidget, mark: tuple[str, str] | None) -> None:
        label = self.notes[widget]
        place = self._form(label)
        if mark is None:
            label.setText("")
            widget.setStyleSheet(self._styles[widget])
            widget.setToolTip(self._tips[widget])
            if place is not None:
                place[0].setRowVisible(place[1], False)
            return
        severity, reason = mark
        colour = STYLE[severity]
        label.setText(
            f"<span style='color:{colour}'>{SYMBOL[severity]} "
            f"{html.escape(shown_unit(reason))}</span>"
        )
        if severity != INFO:
            name = type(widget).__name__
            widget.setStyleSheet(f"{name} {{ border: 2px solid {colour}; }}")
        else:
            widget.setStyleSheet(self._styles[widget])
        widget.setToolTip(reason)
        if place is not None:
            place[0].setRowVisible(place[1], True)

    def reason(self, widget: QWidget) -> str:
        """The reason shown at `widget` ("" when none)."""
        return self.notes[widget].text() if widget in self.notes else ""

    def note(self, widget: QWidget, reason: str | None, severity: str = WARNING) -> None:
        """A note of the field's own (None: remove it)."""
        if widget not in self.notes:
            self._attach(widget)
        if reason:
            self._own[widget] = (severity, reason)
        else:
            self._own.pop(widget, None)
        self._show(widget, self._own.get(widget))

    def forget(self, widget: QWidget) -> None:
        """Mark `widget` no more (its row is removed: a fixture's position, another stand)."""
        for table in (self.notes, self._styles, self._tips, self._own):
            table.pop(widget, None)  # type: ignore[attr-defined]

    def show_problems(self, problems: list[str]) -> None:
        """Mark each field named by the checks' `problems`; clear the others."""
        by_field: dict[QWidget, list[str]] = {}
        for problem in problems:
            widget = field_for(problem, self.fields)
            if widget is not None:
                by_field.setdefault(widget, []).append(problem)
        for widget in self.notes:
            found = by_field.get(widget)
            self._show(widget, (ERROR, "; ".join(found)) if found else self._own.get(widget))

    def marked(self) -> dict[str, str]:
        """{field name: reason} of every field marked now."""
        names = {w: n for n, w in self.fields.items()}
        return {
            names.get(w, type(w).__name__): label.text()
            for w, label in self.notes.items()
            if label.text()
        }


def install(setup: Any) -> FieldMarks:
    """The marks of the Setup tab's fields."""
    return FieldMarks(
        {
            "frequencies": setup.frequencies,
            "level": setup.level,
            "dut_id": setup.dut_id,
            "nominal": setup.nominal,
            "tolerance": setup.tolerance,
            "target": setup.target,
            "stepped_block": setup.stepped_block,
        }
    )
