"""A form that scrolls instead of overlapping (the Setup tab's two boxes): a window smaller than
the form needs shows it with a vertical scroll bar, never with rows drawn over each other or
wrapped labels cut at a row's height. Its size hints say what the form needs, as tall as its
wrapped labels and notes are at a width (Qt's own minimum of a layout leaves them out), so that
the window can come up at least that size (`app.gui.main_window.MainWindow.needed_size`).
"""

from __future__ import annotations

from PySide6.QtCore import QSize, Qt
from PySide6.QtWidgets import QFrame, QLayout, QScrollArea, QWidget


class FormArea(QScrollArea):
    """`form` in a frameless area that scrolls vertically; sizes in px."""

    def __init__(self, form: QWidget) -> None:
        super().__init__()
        self.form = form
        self.setWidgetResizable(True)
        self.setFrameShape(QFrame.Shape.NoFrame)
        self.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        self.setWidget(form)

    def sizeHint(self) -> QSize:
        """The form's size hint, as tall as its wrapped labels are at that width (a scroll
        area's own hint is capped at a few dozen lines of text)."""
        hint = self.form.sizeHint()
        width = hint.width() + self.scroll_bar_px()
        return QSize(width, max(hint.height(), self.height_for(width)))

    def minimumSizeHint(self) -> QSize:
        """The form's narrowest. Narrower, or lower than `height_for` its width, the form
        scrolls: its rows never overlap."""
        hint = self.form.minimumSizeHint()
        return QSize(hint.width() + self.scroll_bar_px(), hint.height())

    def height_for(self, width: int) -> int:
        """The height the area needs at `width` to show every row of the form whole and
        unscrolled: its wrapped labels and notes at that width."""
        narrowest = self.form.minimumSizeHint()
        height = self.form.heightForWidth(max(width - self.scroll_bar_px(), narrowest.width()))
        return max(height, narrowest.height())

    def forget_sizes(self) -> None:
        """Drop the form's cached sizes: a widget changed before its window was first shown
        (a label given its text) does not invalidate the layouts around it, and `height_for`
        would read the heights they cached before."""
        self.form.ensurePolished()  # the style's fonts and margins, as when shown
        for widget in self.form.findChildren(QWidget):
            widget.updateGeometry()
        for layout in self.form.findChildren(QLayout):
            layout.invalidate()
        self.form.updateGeometry()
        self.updateGeometry()

    def scroll_bar_px(self) -> int:
        """The vertical scroll bar's width, kept free beside the form."""
        return int(self.verticalScrollBar().sizeHint().width())
