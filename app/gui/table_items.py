"""Table cells the GUI's tabs share (read-only text, optionally coloured) and the one way the GUI
writes a sensitivity unit ("mV/(m/s²)", never "mV/(m/s^2)")."""

from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import QTableWidgetItem


def read_only_item(text: str, colour: str | None = None) -> QTableWidgetItem:
    """A table cell the technician reads but cannot edit; `colour` a Qt colour name."""
    item = QTableWidgetItem(text)
    item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
    if colour:
        item.setForeground(QColor(colour))
    return item


def shown_unit(text: str) -> str:
    """A unit, or a message of the layers below naming units ("m/s^2", "mV/(m/s^2)"), as the
    GUI writes them ("m/s²", "mV/(m/s²)")."""
    return text.replace("/s^2", "/s²")
