"""The Qt GUI (PySide6 + pyqtgraph): `accelcal gui`."""

from __future__ import annotations

import logging
import os
import sys
from pathlib import Path

from app.procedure.outcome import exit_status

log = logging.getLogger(__name__)


def run_gui(
    *,
    stand_file: Path | None,
    out: Path,
    paced: bool,
    seed: int,
    autorun: bool,
    screenshot: Path | None,
    quit_after_run: bool,
    dut: str | None = None,
    sim: bool = False,
    db: str | None = None,
    sim_hum: tuple = (),
) -> int:
    """Open the window; optionally run at once, save a screenshot and quit (headless smoke)."""
    if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
        os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    from PySide6.QtCore import QCoreApplication, QEvent, QSettings, QTimer
    from PySide6.QtWidgets import QApplication

    from app.gui.binding import qt_binding_problem
    from app.gui.collector import collected_on_gui_thread
    from app.gui.main_window import APPLICATION, ORGANISATION, MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    problem = qt_binding_problem()
    if problem is not None:
        log.error("%s", problem)
        sys.stderr.write(f"accelcal gui: {problem}\n")
        return 1
    # from the first window object on, cyclic garbage is collected on this thread only,
    # never in a worker's (app/gui/collector.py)
    with collected_on_gui_thread():
        if stand_file is None and not sim:  # the stand of the last session, if it is still there
            last = str(QSettings(ORGANISATION, APPLICATION).value("stand_file", ""))
            stand_file = Path(last) if last and Path(last).exists() else None
        window = MainWindow(
            stand_file=stand_file, out=out, paced=paced, seed=seed, db=db, sim_hum=sim_hum
        )
        if dut:
            window.setup_tab.dut.setCurrentText(dut)
        if screenshot is not None:
            window.resize(1400, 900)  # the documented size, whatever the last session left
        window.show()
        outcome = {"code": 0}

        def after_run(finished) -> None:
            if screenshot is not None:
                window.grab().save(str(screenshot))
            outcome["code"] = int(exit_status(finished.record))  # as `accelcal run` exits
            if quit_after_run:
                QTimer.singleShot(0, app.quit)

        def begin() -> None:
            window.wait_for_plans()
            window.run_finished.connect(after_run)
            window.start_run()
            if window.run_tab.worker is None and quit_after_run:
                outcome["code"] = 2
                app.quit()

        if autorun:
            QTimer.singleShot(0, begin)
        elif screenshot is not None:

            def shot() -> None:
                window.wait_for_plans()
                window.grab().save(str(screenshot))
                if quit_after_run:
                    app.quit()

            QTimer.singleShot(200, shot)
        app.exec()
        # the window goes before the application (a QApplication destroyed under a live window,
        # as locals may be, can crash at exit after the work is done)
        window.deleteLater()
        QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
        return outcome["code"]
