"""One GUI session that plays many simulated runs back to back (the soak test's child process).

    python tests/gui/soak_session.py OUT RUNS SUMMARY_JSON

Runs under whatever Qt platform the environment names (the soak test: xcb on Xvfb). Exits 0
when every run ended; 1 when the binding is refused or a run did not end in time. A crash
(e.g. "Fatal Python error: none_dealloc") shows as a negative exit code in the parent.
"""

from __future__ import annotations

import json
import logging
import sys
import time
from pathlib import Path

from PySide6.QtCore import QCoreApplication, QEvent, QEventLoop, QTimer
from PySide6.QtWidgets import QApplication

from app.gui.binding import qt_binding_problem
from app.gui.main_window import MainWindow

log = logging.getLogger("soak")
SHORT_LINES = "40,80,160,315,630"
RUN_TIMEOUT_MS = 30_000


def main(out: Path, runs: int, summary: Path) -> int:
    app = QApplication.instance() or QApplication(sys.argv[:1])
    problem = qt_binding_problem()
    if problem:
        log.error("%s", problem)
        return 1
    window = MainWindow(out=out, paced=False, seed=11)
    window.show()
    window.wait_for_plans()
    window.setup_tab.frequencies.setText(SHORT_LINES)
    window.setup_tab.periods.setValue(3)  # the fewest with a stated type A
    deadline = time.monotonic() + 30
    while not window.setup_tab.start_button.isEnabled() and time.monotonic() < deadline:
        app.processEvents(QEventLoop.ProcessEventsFlag.AllEvents, 50)
    screen = window.screen().availableGeometry()
    started = time.monotonic()
    ended: list[dict] = []
    for index in range(runs):
        window.setup_tab.dut_id.setText(f"SOAK-{index:03d}")
        loop = QEventLoop()
        finished: list = []
        window.run_finished.connect(lambda f, fs=finished, lp=loop: (fs.append(f), lp.quit()))
        QTimer.singleShot(RUN_TIMEOUT_MS, loop.quit)
        window.start_run()
        if window.run_tab.worker is None and not finished:
            log.error("run %d did not start: %s", index, window.run_tab.messages.text())
            return 1
        if not finished:
            loop.exec()
        window.run_finished.disconnect()
        if not finished:
            log.error("run %d did not end within %d ms", index, RUN_TIMEOUT_MS)
            return 1
        window.tabs.setCurrentIndex(index % 4)  # draw every tab's axes now and then
        app.processEvents()
        ended.append(
            {
                "run_id": finished[0].record.run_id,
                "status": finished[0].status,
                "window_width": window.frameGeometry().width(),
            }
        )
    seconds = time.monotonic() - started
    summary.write_text(
        json.dumps({"runs": ended, "seconds": seconds, "screen_width": screen.width()}),
        encoding="utf-8",
    )
    window.close()
    # the window goes before the application does (locals die in no set order: a QApplication
    # destroyed under a live window crashes at exit)
    window.deleteLater()
    QCoreApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
    del window
    app.processEvents()
    return 0


if __name__ == "__main__":
    logging.basicConfig(level=logging.INFO)
    sys.exit(main(Path(sys.argv[1]), int(sys.argv[2]), Path(sys.argv[3])))
