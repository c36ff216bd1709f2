"""Table cells the GUI's tabs share: read-only text, optionally coloured."""

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
