"""A field that takes a quantity as the command line takes it: a bare number in the field's
unit or a number with its unit (`0.5g`, `100 mV/g`, `0.2 %`), read by the same parser
(app.io.quantities), so the GUI accepts and refuses exactly what `accelcal run` does.

It keeps the spin box's interface the Setup tab and its helpers use (`value`, `setValue`,
`valueChanged`): `value()` is the last value read (0 while blank: "not given"), `error()` the
reason the text is refused now (None when it is read). The Setup tab marks a refused field and
keeps Start disabled until it is read (app.gui.field_marks).
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QSize, Qt, Signal
from PySide6.QtGui import QPalette
from PySide6.QtWidgets import QLabel, QLineEdit, QWidget

from app.gui.table_items import shown_unit
from app.io.quantities import PERCENT, Quantity, QuantityError


class QuantityEdit(QLineEdit):
    """A quantity field: `field` names it in messages ("level"), `quantity` its dimension and
    range; `blank` (if not None) is what an empty field means, shown as its placeholder, and
    reads as 0 (so does a typed 0). A value put in by the program is shown as a bare number
    (`digits` significant) in the quantity's unit, which `suffix` states inside the field at
    its right (default: the unit); text typed with its unit shows its value in the field's
    unit there instead ("= 4.903 m/s²")."""

    valueChanged = Signal(float)  # a new value was read (not emitted for refused text)
    edited = Signal()  # the text or the value changed: the checks look again

    def __init__(
        self,
        quantity: Quantity,
        field: str,
        *,
        value: float = 0.0,
        blank: str | None = None,
        digits: int = 6,
        suffix: str | None = None,
        parent: QWidget | None = None,
    ) -> None:
        super().__init__(parent)
        self.quantity, self.field, self.blank, self.digits = quantity, field, blank, digits
        self._value = 0.0
        self._error: str | None = None
        unit = shown_unit(quantity.dimension.shown)
        self._unit, self._suffix_text = unit, f" {suffix or unit}"
        self._suffix = QLabel(self._suffix_text, self)
        self._suffix.setForegroundRole(QPalette.ColorRole.PlaceholderText)
        self._suffix.setAttribute(Qt.WidgetAttribute.WA_TransparentForMouseEvents)
        accepted = shown_unit(quantity.dimension.accepted)
        self.setPlaceholderText(blank or "")
        rule = (
            "a bare number is percent: 0.2 and 0.2 % both mean 0.2 %"
            if quantity.dimension is PERCENT
            else f"a bare number is in {unit}; or type it with its unit: {accepted}"
        )
        empty = f"; empty: {blank}" if blank is not None else ""
        self.setToolTip(f"{field}, {shown_unit(quantity.describe())}: {rule}{empty}")
        self.textChanged.connect(self._read)  # typed or set as text (setValue: not read)
        self.setValue(value)

    def _read(self, text: str) -> None:
        """Read the typed text (the units library only when a unit is typed)."""
        value: float | None
        if self.blank is not None and _zero_or_blank(text):  # as the spin box's 0 did
            value, self._error = 0.0, None
        else:
            try:
                value, self._error = self.quantity.parse(text, self.field), None
            except QuantityError as exc:
                value, self._error = None, str(exc)
        with_unit = value is not None and any(c.isalpha() or c == "%" for c in text)
        self._show_suffix(f" = {value:.4g} {self._unit}" if with_unit else self._suffix_text)
        if value is not None and value != self._value:
            self._value = value
            self.valueChanged.emit(value)
        self.edited.emit()

    def suffix(self) -> str:
        """What the field shows at its right: the unit, or the typed value in it."""
        return self._suffix.text()

    def _show_suffix(self, text: str) -> None:
        self._suffix.setText(text)
        self._place_suffix()

    def _place_suffix(self) -> None:
        width = self._suffix.sizeHint().width()
        self._suffix.setGeometry(self.width() - width - 6, 0, width, self.height())
        self.setTextMargins(0, 0, width + 6, 0)

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._place_suffix()

    def sizeHint(self) -> QSize:
        """Room for a number and the suffix."""
        hint = super().sizeHint()
        needed = self.fontMetrics().horizontalAdvance("0000.000" + self._suffix_text) + 16
        return QSize(max(hint.width(), needed), hint.height())

    def value(self) -> float:
        """The last value read, in the quantity's unit (0: blank)."""
        return self._value

    def setValue(self, value: float) -> None:
        """Show `value` (in the quantity's unit, kept exactly; 0 blanks a field that may be
        blank)."""
        value = float(value)
        blank = value == 0 and self.blank is not None
        self.blockSignals(True)  # the value is kept exactly, not read back from its text
        self.setText("" if blank else f"{value:.{self.digits}g}")
        self.blockSignals(False)
        self._show_suffix(self._suffix_text)
        self._error = None
        if not blank:
            try:
                self.quantity.check(value, self.field)
            except QuantityError as exc:  # a value out of the field's range
                self._error = str(exc)
        changed = value != self._value
        self._value = value
        if changed:
            self.valueChanged.emit(value)
        self.edited.emit()

    def error(self) -> str | None:
        """Why the text is refused now ("level: ..."), None when it is read."""
        return self._error


def _zero_or_blank(text: str) -> bool:
    """Whether `text` is empty or a bare zero (a field's "not given")."""
    try:
        return not text.strip() or float(text) == 0
    except ValueError:
        return False
