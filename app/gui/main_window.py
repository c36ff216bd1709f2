"""The technician's window: set up, check the plan, run live, read results, issue certificates.

It composes the tabs and wires them: Setup & plan (`setup_tab`), Run (`run_tab`: the worker
and the live view), Results, Runs, Sensors and Register. The procedure writes the run's record
itself; the window only reads records, each verified (`app.records.run_folder`). The Results
tab shows one verified run, and the certificate action certifies exactly that run, after naming
it. Closing the window during a run fades the drive out first (then 0 V), with a bounded wait.
"""

from __future__ import annotations

import dataclasses
import html
import json
import logging
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

from PySide6.QtCore import QRect, QSettings, QSize, Signal, Slot
from PySide6.QtGui import QGuiApplication
from PySide6.QtWidgets import QMainWindow, QMessageBox, QTabWidget

from app.certificate import CertificateInfo
from app.gui import certify
from app.gui.actions import WindowActions
from app.gui.batch_view import MemberRow, member_rows
from app.gui.records_link import RecordsLink
from app.gui.reference_view import ask_override, mark_refusal
from app.gui.register_tab import RegisterTab
from app.gui.results_tab import ResultsTab
from app.gui.run_tab import RunTab
from app.gui.runs_tab import RunsTab
from app.gui.sensors_tab import SensorsTab
from app.gui.setup_tab import SetupTab, WindowOptions
from app.gui.worker import warm_imports
from app.io.csv_cells import neutralised
from app.io.vocabulary import RunStatus
from app.procedure import Finished
from app.procedure.reference import ReferenceRefusal
from app.procedure.service import PreparedRun
from app.records.db.errors import RecordsInputError
from app.records.run_folder import RunIntegrityError, inspect_run, load_run
from app.records.run_record import RunRecord
from app.stand import config as stand_config

log = logging.getLogger(__name__)

ORGANISATION, APPLICATION = "accelcal", "accelcal"
DEFAULT_SIZE = QSize(1280, 820)  # px, the window's first size (then its last, remembered)
SETUP_TAB, RUN_TAB, RESULTS_TAB, RUNS_TAB, SENSORS_TAB, REGISTER_TAB = 0, 1, 2, 3, 4, 5


class MainWindow(QMainWindow):
    """Setup & plan, Run (live), Results, Runs, Sensors and Register (the lab's records)."""

    run_finished = Signal(object)  # emitted on the GUI thread when a run has ended

    def __init__(
        self,
        *,
        stand_file: Path | None = None,
        out: Path = Path("runs"),
        paced: bool = True,
        seed: int = 0,
        faults: tuple = (),
        sim_hum: tuple = (),
        db: str | None = None,
    ):
        super().__init__()
        # the lab's records (--db, $ACCELCAL_DB or the default file), opened off this thread
        self.records = RecordsLink(db, self)
        self.setWindowTitle("accelcal: accelerometer calibration")
        self.settings = QSettings(ORGANISATION, APPLICATION)
        # simulated stand only: seed and faults for demonstrations and tests
        self.options = WindowOptions(
            out=Path(out), paced=paced, seed=seed, faults=faults, sim_hum=sim_hum
        )
        self.last_finished: Finished | None = None
        self.prepared: PreparedRun | None = None  # the run started last, as the service made it
        self.last_index_note: str | None = None  # the records' report of the last run indexed
        self.last_certificate: str | None = None  # the number the register gave last
        self.certificate_dialog_open: Any = None
        self.today: date | None = None  # a fixed date for tests; None: the UTC date

        self.setup_tab = SetupTab(
            stand_config.load(stand_file), stand_file, self.records, self.settings, self.options
        )
        self.run_tab = RunTab()
        self.warm = warm_imports()  # what a run imports, imported now (app.gui.worker)
        self.results_tab = ResultsTab()
        self.runs_tab = RunsTab(self.options.out)
        self.sensors_tab = SensorsTab(self.records)
        self.register_tab = RegisterTab(self)
        self.tabs = QTabWidget()
        self.setCentralWidget(self.tabs)
        self.tabs.addTab(self.setup_tab, "1  Setup && plan")
        self.tabs.addTab(self.run_tab, "2  Run")
        self.tabs.addTab(self.results_tab, "3  Results")
        self.tabs.addTab(self.runs_tab, "4  Runs")
        self.tabs.addTab(self.sensors_tab, "5  Sensors")
        self.tabs.addTab(self.register_tab, "6  Register")

        self.setup_tab.start_requested.connect(self.start_run)
        self.setup_tab.said.connect(self.run_tab.messages.setText)
        self.run_tab.ended.connect(self._on_done)
        self.results_tab.export_button.clicked.connect(self.export_results)
        self.results_tab.certificate_button.clicked.connect(self.certificate_action)
        self.results_tab.batch_certificate_button.clicked.connect(self.batch_certificate_action)
        self.results_tab.members.member_chosen.connect(self.open_member)
        self.runs_tab.open_requested.connect(self.open_stored)
        self.records.changed.connect(self.setup_tab.show_reference)
        self.run_finished.connect(self._index_run)
        self.window_actions = WindowActions(self)  # menus and shortcuts (Ctrl+R, Ctrl+., Esc, ...)
        self.setup_tab.validate()  # its checks and predicted peaks: part of what it needs
        # the last size and place, but never under what the tabs need nor over the screen
        geometry = self.settings.value("geometry")
        if geometry is None or not self.restoreGeometry(geometry):
            self.resize(self.default_size())
        self.fit_screen()

    def default_size(self) -> QSize:
        """1280 x 820 px, or more where a tab (the Setup tab's form) asks for more: no tab is
        drawn under the size its layout asks for (`fit_screen` then bounds it by the screen)."""
        hint = self.sizeHint()
        return QSize(
            max(DEFAULT_SIZE.width(), hint.width()), max(DEFAULT_SIZE.height(), hint.height())
        )

    def needed_size(self) -> QSize:
        """The smallest size (px) at the window's width that draws every tab as its layout
        asks: the window's minimum size hint, and tall enough for the Setup tab's form to
        show every row whole and unscrolled at that width (its wrapped labels and notes)."""
        self.setup_tab.forget_sizes()
        self.tabs.updateGeometry()
        layout = self.layout()
        if layout is not None:
            layout.invalidate()  # the window's minimum, cached before
        hint = self.minimumSizeHint()
        width = max(self.width(), hint.width())
        # tab bar, menu bar and frames (px): the Setup tab's form is the tallest and widest
        # minimum of the tabs, so the window's minimum is the Setup tab's plus these
        chrome = hint - self.setup_tab.minimumSizeHint()
        height = self.setup_tab.height_for(width - chrome.width()) + chrome.height()
        return QSize(width, max(hint.height(), height))

    def fit_screen(self, area: QRect | None = None) -> None:
        """At least `needed_size` (a restored window never comes up smaller than its content
        needs), never wider or taller than the available `area` of the screen (None: of the
        screen the window is on), and inside it. Where the screen is smaller than the need,
        the Setup tab's form scrolls."""
        if area is None:
            screen = self.screen() or QGuiApplication.primaryScreen()
            area = screen.availableGeometry() if screen is not None else None
        size = self.needed_size().expandedTo(self.size())
        if area is None:
            self.resize(size)
            return
        size = size.boundedTo(area.size())
        self.resize(size)
        x = min(max(self.x(), area.left()), area.right() + 1 - size.width())
        y = min(max(self.y(), area.top()), area.bottom() + 1 - size.height())
        if (x, y) != (self.x(), self.y()):
            self.move(x, y)

    def next_sensor(self) -> None:
        """A fresh start for the next sensor: serial, nominal, tolerance, template and plan
        fields as the window opened, no results, no run, no certificate of the last one."""
        if self.run_tab.worker is not None:
            return
        self.results_tab.clear("No results yet: the next sensor's run shows here.")
        self.results_tab.show_batch("", [])
        self.run_tab.clear()
        self.run_tab.state.setText("idle")
        self.last_finished, self.last_certificate = None, None
        self.tabs.setCurrentIndex(SETUP_TAB)
        self.setup_tab.reset()

    # --- running ------------------------------------------------------------------------

    @Slot()
    def start_run(self) -> None:
        """Start the run the Setup tab describes, prepared by the run service as the CLI's
        (the records' gate and reference rule first)."""
        setup = self.setup_tab
        if self.run_tab.worker is not None or setup.validate():
            return
        prepared = self.prepare_run(self.today_utc())
        if prepared is None:
            return
        self.settings.setValue("dut", setup.dut.currentText())
        self.settings.setValue("stand_file", str(setup.stand_file or ""))
        for note in prepared.notes:  # an override granted is a warning in the log
            log.log(logging.WARNING if prepared.request.overrides else logging.INFO, "%s", note)
        ranges: dict[str, float] = {c.name: c.range_v for c in setup.config.inputs}
        said = "; ".join(prepared.notes) or None
        members = setup.fixture.members()  # a stand with a fixture: its DUTs in one run
        if not self.run_tab.begin(setup.service, prepared, ranges, said, members):
            return
        self.prepared = prepared
        setup.last_request = prepared.request
        setup.set_running(True)
        self.tabs.setCurrentIndex(RUN_TAB)
        self.runs_tab.refresh()

    def prepare_run(self, today: date) -> PreparedRun | None:
        """The Setup tab's run prepared by the run service: refused (None, the refusal shown)
        when the records fail their quick check, when the reference standard is refused and
        no override reason is typed, or when a field cannot be resolved."""
        setup = self.setup_tab
        setup.field_marks.note(setup.reference_label, None)
        reason: str | None = None
        while True:
            try:
                return setup.prepare(reference_override=reason, today=today)
            except ReferenceRefusal as exc:
                if reason is None and exc.overridable:
                    reason = ask_override(setup, str(exc))
                    if reason is not None:
                        continue
                self.run_tab.messages.setText(html.escape(mark_refusal(setup, str(exc))))
                return None
            except RecordsInputError as exc:  # the records' gate (ChainBroken) or their rule
                self.run_tab.messages.setText(html.escape(mark_refusal(setup, str(exc))))
                return None
            except ValueError as exc:  # a refusal naming the field (stand file, DUT)
                QMessageBox.warning(self, "Cannot start", str(exc))
                self.run_tab.messages.setText(html.escape(f"Cannot start: {exc}"))
                return None

    def _on_done(self, finished: Finished | None) -> None:
        """The run has ended (GUI thread): list it, open its results if complete."""
        self.last_finished = finished
        self.runs_tab.refresh()
        self.setup_tab.set_running(False)
        if finished is None:  # the worker ended without a result (its error is shown)
            return
        batch = self.run_tab.batch
        if batch is not None:  # several DUTs: a row each, the first complete one shown
            self.show_batch(batch)
            for _, member in batch.members:
                self.run_finished.emit(member)  # each indexed as its sensor's calibration
            return
        self.results_tab.show_batch("", [])
        run_id = finished.record.run_id
        if finished.status == RunStatus.COMPLETE and run_id:
            self.open_run(self.options.out / str(run_id), switch=False)
            self.tabs.setCurrentIndex(RESULTS_TAB)
        self.run_finished.emit(finished)

    def _index_run(self, finished: Finished) -> None:
        """A finished run goes into the records' index through the run service (the folder
        stays the record); its report, warnings included, is shown and logged."""
        prepared = self.prepared
        if prepared is None or finished.record.run_id is None:
            return

        def indexed(note: str) -> None:
            for line in note.splitlines():
                log.log(logging.WARNING if line.startswith("WARNING") else logging.INFO, "%s", line)
            self.last_index_note = note
            if "WARNING" in note:
                self.run_tab.messages.setText(html.escape(note).replace("\n", "<br/>"))
            self.sensors_tab.refresh()

        self.records.finish_later(self.setup_tab.service, prepared, finished, indexed)

    # --- results, runs and certificates -------------------------------------------------

    def show_batch(self, batch: Any) -> None:
        """The DUTs of a finished batch (BatchFinished) in the Results tab, the first complete
        one's results shown under them."""
        rows = member_rows(batch, self.options.out)
        self.results_tab.show_batch(batch.batch_id, rows)
        complete = [i for i, row in enumerate(rows) if row.complete]
        if complete:
            self.results_tab.members.choose(complete[0])
            self.tabs.setCurrentIndex(RESULTS_TAB)
        else:
            self.results_tab.clear(f"<b>Batch {html.escape(batch.batch_id)}</b>: no DUT complete.")

    def open_member(self, row: MemberRow) -> None:
        """A DUT of the batch chosen in the Results tab: its run shown as a single run's."""
        if row.folder is None:
            self.results_tab.clear(html.escape(f"{row.position} {row.serial}: {row.verdict}"))
            return
        self.open_run(row.folder, switch=False)

    def open_stored(self, folder: Path) -> bool:
        """A run opened from the Runs tab: shown alone (no batch listed)."""
        self.results_tab.show_batch("", [])
        return self.open_run(folder)

    @Slot()
    def batch_certificate_action(self) -> list[Path]:
        """Certificates for every complete DUT of the batch shown, in one confirmation."""
        table = self.results_tab.members
        return certify.ask_batch(self, table.batch_id, table.certifiable)

    def open_run(self, folder: Path, *, switch: bool = True) -> bool:
        """Show the stored run `folder` in the Results tab after verifying it; only a
        complete, verified run is shown as certifiable. Whether results are shown."""
        folder = Path(folder)
        try:
            check = inspect_run(folder)
        except ValueError as exc:
            self.results_tab.clear(html.escape(str(exc)))
            return False
        name = html.escape(folder.name)
        if check.record is None:  # running, interrupted or modified
            problems = "<br/>".join(html.escape(p) for p in check.problems)
            self.results_tab.clear(
                f"<b>Run {name}: {check.state}</b>, never certified.<br/>{problems}"
            )
        elif not check.certifiable or not check.record.results:
            reason = html.escape(str(check.record.abort_reason))
            self.results_tab.clear(
                f"<b>Run {name}: {check.state}</b> ({reason}); kept, never certified."
            )
        else:
            record = check.record
            results = record.results_object()
            assert results is not None  # checked above
            self.results_tab.show_results(results, record, folder)
        if switch:
            self.tabs.setCurrentIndex(RESULTS_TAB)
        return self.results_tab.folder is not None

    def export_results(self) -> Path | None:
        """Copy the stored results of the shown run (CSV and JSON) beside the run folders."""
        results, record = self.results_tab.results, self.results_tab.record
        if results is None or record is None:
            return None
        target = self.options.out / f"{record.run_id}-results"
        target.with_suffix(".csv").write_text(neutralised(results.to_csv()), encoding="utf-8")
        target.with_suffix(".json").write_text(
            json.dumps(results.to_dict(), indent=2), encoding="utf-8"
        )
        self.run_tab.messages.setText(html.escape(f"exported {target}.csv and .json"))
        return target

    def certifiable_run(self) -> tuple[Path, RunRecord] | None:
        """The run the certificate action would certify: the one shown in the Results tab,
        verified again now (None, with the reason shown, when there is none)."""
        folder = self.results_tab.folder
        if folder is None:
            QMessageBox.information(
                self, "Certificate", "Open a complete run first (tab 4); it will be certified."
            )
            return None
        try:
            record = load_run(folder)
        except (RunIntegrityError, ValueError) as exc:
            QMessageBox.warning(self, "Certificate refused", str(exc))
            self.open_run(folder)
            return None
        if not record.complete:
            QMessageBox.warning(self, "Certificate refused", f"{folder.name}: {record.status} run")
            return None
        return folder, record

    @Slot()
    def certificate_action(self) -> Path | None:
        """Certificate of the run shown: asks the fields afresh, names the run once, writes
        and opens the PDF."""
        target = self.certifiable_run()
        if target is None:
            return None
        folder, record = target
        return certify.ask(self, folder, record)

    def issue_certificate(self, folder: Path, info: CertificateInfo) -> Path | None:
        """Issue the certificate of the run `folder` with `info` (Prepared by, when not given,
        the window's Technician field) through the certificate service, as the dialog does;
        errors shown, not raised."""
        technician = self.setup_tab.technician.text().strip()
        info = dataclasses.replace(info, prepared_by=info.prepared_by or technician)
        return certify.issue(self, Path(folder), info)

    # --- closing ------------------------------------------------------------------------

    def closeEvent(self, event: Any) -> None:
        """Fade out and stop a running calibration first; never hang."""
        self.settings.setValue("geometry", self.saveGeometry())
        self.run_tab.shut_down("window closed")
        self.setup_tab.close_pools()
        event.accept()

    def today_utc(self) -> date:
        """Today (UTC), or the date a test fixed."""
        return self.today or datetime.now(UTC).date()

    def wait_for_plans(self) -> None:
        """Block until the plans asked for are optimised and what a run imports is imported
        (tests, screenshots, bench)."""
        self.warm.join()
        self.setup_tab.wait_for_plans()
