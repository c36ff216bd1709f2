"""The window's menus and keyboard: every command once, as a QAction with its shortcut, shown in
the menu and in the tooltip of the button that does the same.

    Start                    Ctrl+R
    Stop (fade out)          Ctrl+.
    Abort: drive to 0 V now  Esc        (only while a run is going: Esc still closes dialogs)
    Next sensor              Ctrl+N
    Certificate ...          Ctrl+Shift+C
"""

from __future__ import annotations

from typing import Any

from PySide6.QtCore import QObject, Qt, QTimer
from PySide6.QtGui import QAction, QKeySequence

SETUP_TAB = 0
START, STOP, ABORT, NEXT, CERTIFICATE = "Ctrl+R", "Ctrl+.", "Esc", "Ctrl+N", "Ctrl+Shift+C"


def with_key(text: str, key: str) -> str:
    """A tooltip that names its shortcut."""
    return f"{text}  ({QKeySequence(key).toString(QKeySequence.SequenceFormat.NativeText)})"


class WindowActions(QObject):
    """Menus, shortcuts and their enabled state (kept in step with the window 5 times a s)."""

    def __init__(self, window: Any) -> None:
        super().__init__(window)
        self.window = window
        bar = window.menuBar()
        run_menu = bar.addMenu("&Run")
        self.start = self._action("&Start", START, window.start_run, "Start the calibration")
        run_tab, setup_tab = window.run_tab, window.setup_tab
        self.stop = self._action("S&top (fade out)", STOP, run_tab.stop, "Fade out and stop")
        self.abort = self._action(
            "&Abort: drive to 0 V now", ABORT, run_tab.emergency_stop, "Zero the drive at once"
        )
        self.abort.setShortcutContext(Qt.ShortcutContext.ApplicationShortcut)
        self.next_sensor = self._action(
            "&Next sensor", NEXT, self.next, "Clear every field of the last sensor for the next"
        )
        run_menu.addActions([self.start, self.stop, self.abort])
        run_menu.addSeparator()
        run_menu.addAction(self.next_sensor)
        results_menu = bar.addMenu("Re&sults")
        self.certificate = self._action(
            "&Certificate ...",
            CERTIFICATE,
            window.certificate_action,
            "Issue the certificate of the run shown in the Results tab",
        )
        self.export = self._action(
            "&Export CSV and JSON", None, window.export_results, "Export the results shown"
        )
        results_menu.addActions([self.certificate, self.export])
        stand_menu = bar.addMenu("S&tand")
        stand_menu.addAction(self._action("Stand &file ...", None, setup_tab.choose_stand, None))
        stand_menu.addAction(
            self._action("&Simulated stand", None, lambda: setup_tab.load_stand(None), None)
        )
        for action in (self.start, self.stop, self.abort, self.next_sensor, self.certificate):
            window.addAction(action)  # shortcuts work whichever widget has the focus

        run_tab.stop_button.setToolTip(with_key("Fade the drive out and stop", STOP))
        run_tab.stop_button.setText("Stop (fade out)  Ctrl+.")
        window.results_tab.certificate_button.setText("Certificate ...  (Ctrl+Shift+C)")
        window.results_tab.certificate_button.setToolTip(
            with_key("Issue the certificate of the run shown here", CERTIFICATE)
        )
        self.timer = QTimer(self, interval=200)
        self.timer.timeout.connect(self.refresh)
        self.timer.start()
        self.refresh()

    def _action(self, text: str, key: str | None, slot: Any, tip: str | None) -> QAction:
        action = QAction(text, self.window)
        if key:
            action.setShortcut(QKeySequence(key))
            action.setShortcutContext(Qt.ShortcutContext.WindowShortcut)
        if tip:
            action.setToolTip(with_key(tip, key) if key else tip)
            action.setStatusTip(action.toolTip())
        action.triggered.connect(lambda _checked=False: slot())
        return action

    def refresh(self) -> None:
        """Enabled as the buttons are; Esc and Stop only while a run is going."""
        w = self.window
        running = w.run_tab.worker is not None
        self.start.setEnabled(w.setup_tab.start_button.isEnabled())
        self.stop.setEnabled(running)
        self.abort.setEnabled(running)
        self.next_sensor.setEnabled(not running)
        self.certificate.setEnabled(w.results_tab.certificate_button.isEnabled())
        self.export.setEnabled(w.results_tab.export_button.isEnabled())

    def next(self) -> None:
        """A fresh start for the next sensor: nothing of the last one carried over."""
        self.window.next_sensor()
