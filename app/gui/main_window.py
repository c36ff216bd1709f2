"""The technician's window: set up, check the plan, run live, read results, issue certificates.

Threads: the procedure runs on a plain worker thread (`app.gui.worker.RunWorker`) that only
queues copies of its events; a 25 Hz timer on the GUI thread drains the queue and draws, so no
widget or plot item is ever touched from another thread. The procedure writes the run's record
itself; the window only reads records, each verified (`app.records.run_folder`). The Results
tab shows one
verified run, and the certificate action certifies exactly that run, after naming it.
Closing the window during a run fades the drive out first (then 0 V), with a bounded wait.
"""

from __future__ import annotations

import html
import json
import logging
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtCore import QSettings, Qt, QTimer, QUrl, Signal, Slot
from PySide6.QtGui import QDesktopServices, QFontMetrics
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QSizePolicy,
    QSpinBox,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app.certificate import CertificateError, CertificateInfo, build
from app.gui import certify, field_marks
from app.gui.actions import START, WindowActions, with_key
from app.gui.certificate_dialog import CertificateDialog, run_identity
from app.gui.plots import FRAME_HZ, LivePlots
from app.gui.records_link import RecordsLink
from app.gui.reference_view import describe_reference, reference_allows_run
from app.gui.register_tab import RegisterTab
from app.gui.results_tab import ResultsTab, wrapping_label
from app.gui.runs_tab import RunsTab
from app.gui.sensor_entry import SerialEntry
from app.gui.sensors_tab import SensorsTab
from app.gui.teds_entry import TedsEntry
from app.gui.templates import TemplatePicker
from app.gui.worker import RunWorker
from app.io.vocabulary import RunStatus
from app.lines import parse_frequencies
from app.procedure import (
    EqualisationStep,
    Finished,
    PeriodBlock,
    PeriodEstimate,
    Progress,
    State,
    StateChanged,
    WarningRaised,
)
from app.procedure.modes import MODES
from app.procedure.preflight import check_preflight
from app.procedure.run import RunRequest, start
from app.records.run_folder import RunIntegrityError, inspect_run, load_run
from app.records.run_record import RunRecord
from app.stand import config as stand_config
from dsp.calibration import ReferenceChain, Results
from dsp.estimators import ESTIMATORS
from dsp.multisine import PRESETS, Plan, check_lines, make_plan, preset_plan
from hardware.errors import HardwareError
from sim.models import DUT_CATALOGUE

log = logging.getLogger(__name__)

ORGANISATION, APPLICATION = "accelcal", "accelcal"
RUN_TAB, RESULTS_TAB, RUNS_TAB, SENSORS_TAB, REGISTER_TAB = 1, 2, 3, 4, 5
# the plan fields Next sensor puts back to how the window opened (nothing of the last sensor)
PLAN_FIELDS = (
    *("nominal", "tolerance", "preset", "frequencies", "level", "periods", "target"),
    *("max_time", "estimator", "mode"),
)
STOP_STYLE = (  # flat colours (a border makes Qt draw the background as given)
    "QPushButton { background: #c0392b; color: white; font-weight: bold; padding: 8px;"
    " border: 1px solid #922b21; border-radius: 4px; }"
    "QPushButton:disabled { background: #e5e7e9; color: #a6acaf; font-weight: normal;"
    " border: 1px solid #ccd1d1; }"
)


@dataclass(frozen=True)
class PlannedRequest(RunRequest):
    """A RunRequest whose multisine phases were optimised already (the window does it on a
    worker pool as the lines are typed): Start does not block the GUI for a second."""

    phases_rad: tuple[float, ...] | None = None

    def plan(self) -> Plan:
        if self.phases_rad is None:
            return super().plan()
        preset = PRESETS[self.preset or "piezo"]
        lines = self.frequencies_hz or tuple(preset.nominal_frequencies_hz)
        return make_plan(
            lines,
            preset.sample_rate_hz,
            preset.period_samples,
            self.level_ms2,
            preset.reference_frequency_hz,
            phases_rad=self.phases_rad,
        )


class ElidedLabel(QLabel):
    """One line of text, elided to the width it is given (the whole text in the tooltip);
    it never widens its window."""

    def __init__(self, text: str = "") -> None:
        super().__init__()
        self._full = ""
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setMinimumWidth(1)
        self.setText(text)

    def setText(self, text: str) -> None:
        self._full = text
        self.setToolTip(text if len(text) > 60 else "")
        self._elide()

    def text(self) -> str:
        return self._full

    def resizeEvent(self, event: Any) -> None:
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        width = max(self.width(), 40)
        shown = QFontMetrics(self.font()).elidedText(self._full, Qt.TextElideMode.ElideRight, width)
        super().setText(shown)


class MainWindow(QMainWindow):
    """Setup & plan, Run (live), Results, Runs, Sensors (the lab's records)."""

    run_finished = Signal(object)  # emitted on the GUI thread when a run has ended

    def __init__(
        self,
        *,
        stand_file: Path | None = None,
        out: Path = Path("runs"),
        paced: bool = True,
        seed: int = 0,
        faults: tuple = (),
        db: str | None = None,
    ):
        super().__init__()
        # the lab's records (--db, $ACCELCAL_DB or the default file), opened off this thread
        self.records = RecordsLink(db, self)
        self.setWindowTitle("accelcal: accelerometer calibration")
        self.config = stand_config.load(stand_file)
        self.stand_file, self.out, self.paced, self.seed = stand_file, Path(out), paced, seed
        self.faults = faults  # simulated stand only: for demonstrations and tests
        self.settings = QSettings(ORGANISATION, APPLICATION)
        self.worker: RunWorker | None = None
        self.last_finished: Finished | None = None
        self.last_request: RunRequest | None = None  # the settings of the run just made
        self.last_certificate: str | None = None  # the number the register gave last
        self.certificate_dialog_open: Any = None
        self.today: date | None = None  # a fixed date for tests; None: the UTC date
        self._live: dict[str, Any] = {}
        self._plans: dict[Any, Future] = {}
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        for name, preset in PRESETS.items():  # optimised phases take ~1 s: off the GUI thread
            key = (name, tuple(preset.nominal_frequencies_hz))
            self._plans[key] = self._pool.submit(preset_plan, name, level_ms2=1.0)

        self.tabs = QTabWidget()
        self.setCentralWidget(self.tabs)
        self.tabs.addTab(self._setup_tab(), "1  Setup && plan")
        self.tabs.addTab(self._run_tab(), "2  Run")
        self.results_tab = ResultsTab()
        self.results_tab.export_button.clicked.connect(self.export_results)
        self.results_tab.certificate_button.clicked.connect(self.certificate_action)
        self.tabs.addTab(self.results_tab, "3  Results")
        self.runs_tab = RunsTab(self.out)
        self.runs_tab.open_requested.connect(self.open_run)
        self.tabs.addTab(self.runs_tab, "4  Runs")
        self.sensors_tab = SensorsTab(self.records)
        self.tabs.addTab(self.sensors_tab, "5  Sensors")
        self.register_tab = RegisterTab(self)
        self.tabs.addTab(self.register_tab, "6  Register")
        self._plan_defaults = self._plan_values()
        # the names tests and older code use
        self.summary, self.table = self.results_tab.summary, self.results_tab.table
        self.budget, self.result_mag = self.results_tab.budget, self.results_tab.result_mag
        self.runs = self.runs_tab

        self.window_actions = WindowActions(self)  # menus and shortcuts (Ctrl+R, Ctrl+., Esc, ...)
        self.field_marks = field_marks.install(self)  # bad input marked at its field
        self.serial_entry = SerialEntry(self, self.records, self.field_marks)
        self.serial_entry.sensor_changed.connect(self.templates.show_for)
        self.records.changed.connect(self.show_reference)
        self.run_finished.connect(self._index_run)
        self.timer = QTimer(self, interval=int(1000 / FRAME_HZ))
        self.timer.timeout.connect(self._tick)
        self.timer.start()
        geometry = self.settings.value("geometry")
        if geometry is not None:
            self.restoreGeometry(geometry)
        else:
            self.resize(1280, 820)
        self.fit_screen()
        self.validate()

    # --- properties kept for callers ----------------------------------------------------

    @property
    def procedure(self) -> Any:
        """The running procedure (None when idle)."""
        return self.worker.procedure if self.worker is not None else None

    @property
    def results(self) -> Results | None:
        return self.results_tab.results

    def fit_screen(self) -> None:
        """Never wider or taller than the available area of the screen the window is on."""
        screen = self.screen() or self.window().screen()
        if screen is None:
            return
        area = screen.availableGeometry()
        if self.width() > area.width() or self.height() > area.height():
            self.resize(min(self.width(), area.width()), min(self.height(), area.height()))

    # --- tabs ---------------------------------------------------------------------------

    def _setup_tab(self) -> QWidget:
        page = QWidget()
        layout = QHBoxLayout(page)
        stand = QGroupBox("Stand and DUT")
        form = QFormLayout(stand)
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.stand_label = QLabel(f"{self.config.source} ({self.config.backend})")
        self.stand_label.setWordWrap(True)
        choose = QPushButton("Stand file ...")
        choose.clicked.connect(self.choose_stand)
        simulated = QPushButton("Simulated stand")
        simulated.clicked.connect(lambda: self.load_stand(None))
        stand_row = QHBoxLayout()
        stand_row.addWidget(self.stand_label, 1)
        stand_row.addWidget(choose)
        stand_row.addWidget(simulated)
        form.addRow("Stand", stand_row)
        self.reference_label = wrapping_label(describe_reference(self.config))
        self.reference_label.setTextFormat(Qt.TextFormat.RichText)
        form.addRow("Reference standard", self.reference_label)
        self.technician = QLineEdit(str(self.settings.value("technician", "")) or _login_name())
        self.technician.setToolTip(
            "who is working at the stand today: 'Prepared by' on the certificates"
        )
        self.technician.editingFinished.connect(
            lambda: self.settings.setValue("technician", self.technician.text().strip())
        )
        form.addRow("Technician", self.technician)
        self.dut = QComboBox()
        self.dut.addItems(list(DUT_CATALOGUE))
        self.dut.setCurrentText(str(self.settings.value("dut", "piezo")))
        self.dut.setToolTip("DUT of the simulated stand's catalogue")
        # never restored from the last session: another day's sensor is another serial
        self.dut_id = QLineEdit()
        self.dut_id.setPlaceholderText("serial number of the sensor on the stand")
        self.nominal = QDoubleSpinBox(decimals=3, maximum=10000.0, suffix=" mV/(m/s²)")
        self.nominal.setSpecialValueText("not given, mV/(m/s²)")
        self.tolerance = QDoubleSpinBox(decimals=1, maximum=50.0, value=5.0, suffix=" %")
        form.addRow("DUT", self.dut)
        form.addRow("DUT serial", self.dut_id)
        self.teds = TedsEntry(self, self.records)
        form.addRow("", self.teds.button)
        form.addRow("Nominal sensitivity", self.nominal)
        form.addRow("Tolerance of the characteristic", self.tolerance)
        layout.addWidget(stand, 1)

        plan = QGroupBox("Plan")
        pform = QFormLayout(plan)
        pform.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.preset = QComboBox()
        self.preset.addItems(list(PRESETS))
        self.frequencies = QLineEdit()
        self.frequencies.setPlaceholderText("preset lines; or e.g. 10,12.5,...,1000 (Hz)")
        self.level = QDoubleSpinBox(
            decimals=2, minimum=0.01, maximum=1000.0, value=5.0, suffix=" m/s² peak per line"
        )
        self.periods = QSpinBox(minimum=3, maximum=10000, value=8, suffix=" periods")
        self.target = QDoubleSpinBox(decimals=3, maximum=10.0, suffix=" % type A target")
        self.target.setSpecialValueText("off (% type A): acquire the periods above")
        self.max_time = QSpinBox(maximum=100_000, suffix=" s at most")
        self.max_time.setSpecialValueText("no time bound (s)")
        self.estimator = QComboBox()
        self.estimator.addItems(list(ESTIMATORS))
        self.mode = QComboBox()
        self.mode.addItems(list(MODES))
        for widget in (self.preset, self.estimator, self.mode, self.dut):
            widget.currentTextChanged.connect(self.validate)
        for spin in (self.level, self.nominal, self.tolerance):
            spin.valueChanged.connect(self.validate)
        self.periods.valueChanged.connect(self.validate)
        self.frequencies.textChanged.connect(self.validate)
        self.templates = TemplatePicker(self, self.records)
        template_row = QHBoxLayout()
        template_row.addWidget(self.templates.combo, 1)
        template_row.addWidget(self.templates.save_button)
        pform.addRow("Template", template_row)
        pform.addRow("Preset", self.preset)
        pform.addRow("Lines", self.frequencies)
        pform.addRow("Level", self.level)
        pform.addRow("Acquire", self.periods)
        pform.addRow("Or until", self.target)
        pform.addRow("Time bound", self.max_time)
        pform.addRow("Estimator", self.estimator)
        pform.addRow("Mode", self.mode)
        self.peaks = QLabel()
        self.peaks.setWordWrap(True)
        self.peaks.setMinimumHeight(48)
        pform.addRow("Predicted", self.peaks)
        self.checks = QLabel()
        self.checks.setWordWrap(True)
        self.checks.setTextFormat(Qt.TextFormat.RichText)
        pform.addRow("Checks", self.checks)
        self.start_button = QPushButton("Start  (Ctrl+R)")
        self.start_button.clicked.connect(self.start_run)
        pform.addRow(self.start_button)
        layout.addWidget(plan, 2)
        return page

    def _run_tab(self) -> QWidget:
        page = QWidget()
        layout = QVBoxLayout(page)
        top = QHBoxLayout()
        self.state = ElidedLabel("idle")
        self.state.setStyleSheet("font-size: 15px; font-weight: bold")
        self.equalisation = ElidedLabel("")
        self.coherence = ElidedLabel("")
        self.progress = QProgressBar()
        self.stop_button = QPushButton("Stop (fade out)  Ctrl+.")
        self.stop_button.setStyleSheet(STOP_STYLE)  # disabled: grey, visibly not active
        self.stop_button.clicked.connect(self.stop_run)
        self.stop_button.setEnabled(False)
        top.addWidget(self.state, 2)
        top.addWidget(self.equalisation, 2)
        top.addWidget(self.coherence, 2)
        top.addWidget(self.progress, 2)
        top.addWidget(self.stop_button, 1)
        layout.addLayout(top)
        meters = QHBoxLayout()
        self.meters: dict[str, QProgressBar] = {}
        for name in ("reference", "dut"):
            bar = QProgressBar(maximum=100, format=f"{name} %p % of range")
            meters.addWidget(bar)
            self.meters[name] = bar
        layout.addLayout(meters)
        self.live = LivePlots()
        layout.addWidget(self.live.widget, 1)
        self.messages = wrapping_label("")
        self.messages.setTextFormat(Qt.TextFormat.RichText)
        layout.addWidget(self.messages)
        return page

    def _plan_values(self) -> dict[str, Any]:
        """The values of PLAN_FIELDS now (Next sensor puts the window's first ones back)."""
        values: dict[str, Any] = {}
        for name in PLAN_FIELDS:
            widget = getattr(self, name)
            if isinstance(widget, QComboBox):
                values[name] = widget.currentText()
            elif isinstance(widget, QLineEdit):
                values[name] = widget.text()
            else:
                values[name] = widget.value()
        return values

    def next_sensor(self) -> None:
        """A fresh start for the next sensor: serial, nominal, tolerance, template and plan
        fields as the window opened, no results, no run, no certificate of the last one."""
        if self.worker is not None:
            return
        self.dut_id.clear()
        self.serial_entry.reset()
        for name, value in self._plan_defaults.items():
            widget = getattr(self, name)
            if isinstance(widget, QComboBox):
                widget.setCurrentText(value)
            elif isinstance(widget, QLineEdit):
                widget.setText(value)
            else:
                widget.setValue(value)
        self.results_tab.clear("No results yet: the next sensor's run shows here.")
        self.clear_run_tab()
        self.state.setText("idle")
        self.last_finished, self.last_request, self.last_certificate = None, None, None
        self.field_marks.note(self.reference_label, None)
        self.tabs.setCurrentIndex(0)
        self.dut_id.setFocus(Qt.FocusReason.ShortcutFocusReason)
        self.validate()

    def clear_run_tab(self) -> None:
        """A new run starts from an empty Run tab: no curve, meter or word of the last run."""
        self.live.clear()
        for label in (self.equalisation, self.coherence):
            label.setText("")
        self.messages.setText("")
        self.progress.setValue(0)
        self.progress.resetFormat()
        for bar in self.meters.values():
            bar.setValue(0)
            bar.setStyleSheet("")

    # --- plan checks --------------------------------------------------------------------

    def request(self) -> RunRequest:
        """The run the fields describe, with the phases already optimised off this thread
        (the same phases the CLI computes: they do not depend on the level)."""
        preset = PRESETS[self.preset.currentText()]
        custom = self._custom_lines()
        future = self._plans.get(
            (preset.name, tuple(custom if custom is not None else preset.nominal_frequencies_hz))
        )
        phases = None
        if future is not None and future.done() and future.exception() is None:
            phases = tuple(float(p) for p in future.result().phases_rad)
        return PlannedRequest(
            phases_rad=phases,
            stand_file=self.stand_file,
            dut=self.dut.currentText(),
            dut_id=self.dut_id.text().strip() or None,
            preset=self.preset.currentText(),
            frequencies_hz=self._custom_lines(),
            level_ms2=self.level.value(),
            periods=self.periods.value(),
            target_type_a=self.target.value() / 100 or None,
            max_acquisition_s=float(self.max_time.value()) or None,
            estimator=self.estimator.currentText(),
            mode=self.mode.currentText(),
            tolerance_percent=self.tolerance.value() or None,
            nominal_mv_per_ms2=self.nominal.value() or None,
            seed=self.seed,
            paced=self.paced,
            faults=self.faults,
            out=self.out,
        )

    def choose_stand(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Stand configuration", "", "TOML (*.toml)")
        if path:
            self.load_stand(Path(path))

    def load_stand(self, path: Path | None) -> bool:
        """Switch to the stand of `path` (None: the simulated one); errors name the field."""
        if self.worker is not None:
            return False
        try:
            config = stand_config.load(path)
        except stand_config.ConfigError as exc:
            QMessageBox.warning(self, "Stand configuration", str(exc))
            self.messages.setText(str(exc))
            return False
        self.config, self.stand_file = config, path
        self.stand_label.setText(f"{config.source} ({config.backend})")
        self.show_reference()
        self.settings.setValue("stand_file", str(path or ""))
        self.validate()
        return True

    def show_reference(self) -> None:
        """The reference standard the run will use: the stand file's, with its record."""
        self.reference_label.setText(describe_reference(self.config, self.records))

    def _index_run(self, finished: Finished) -> None:
        """A finished run goes into the records' index (the folder stays the record)."""
        run_id = finished.record.run_id

        def indexed(note: str) -> None:
            log.info("%s", note)
            self.sensors_tab.refresh()

        self.records.index_run_later(self.out / str(run_id) if run_id else None, indexed)

    def _custom_lines(self) -> tuple[float, ...] | None:
        """The typed line list (Hz), None for the preset's; ValueError says what is wrong."""
        text = self.frequencies.text().strip()
        return tuple(parse_frequencies(text)) if text else None

    @Slot()
    def _config_chain(self) -> ReferenceChain | None:
        """The stand file's reference chain, None when it has no certificate table (the
        simulated stand's chain comes with the stand when the run opens it)."""
        try:
            return self.config.reference_chain()
        except stand_config.ConfigError:
            return None

    def validate(self) -> list[str]:
        """Plan checks and stand limits beside the fields; Start only when nothing fails."""
        problems: list[str] = []
        warnings: list[str] = []
        preset = PRESETS[self.preset.currentText()]
        try:
            custom = self._custom_lines()
        except ValueError as exc:
            custom = None
            problems.append(f"lines: {exc}")
        freqs = tuple(custom if custom is not None else preset.nominal_frequencies_hz)
        check = check_lines(
            freqs, preset.sample_rate_hz, preset.period_samples, preset.reference_frequency_hz
        )
        problems += list(check.errors)
        warnings += [w for w in check.warnings if "mains" in w]
        key = (preset.name, freqs)
        if key not in self._plans and not problems:  # optimise a new line list off this thread
            self._plans[key] = self._pool.submit(
                make_plan,
                freqs,
                preset.sample_rate_hz,
                preset.period_samples,
                1.0,
                preset.reference_frequency_hz,
            )
        future = self._plans.get(key)
        if future is None:
            self.peaks.setText("")
        elif not future.done():
            problems.append("optimising the multisine phases ...")
            self.peaks.setText("")
            QTimer.singleShot(200, self, self.validate)  # look again when it may be ready
        else:
            plan: Plan = future.result()  # optimised at 1 m/s^2 per line: scaled to the level
            report = check_preflight(  # the same preflight as the CLI and the run itself
                plan,
                self.config,
                self._config_chain(),
                self.nominal.value() or None,
                level_scale=self.level.value(),
            )
            peaks, limits = report.peaks, self.config.limits
            self.peaks.setText(
                f"acceleration {peaks.acceleration_ms2:.1f} m/s² (limit "
                f"{limits.acceleration_peak_ms2:g}), velocity "
                f"{1e3 * peaks.velocity_m_per_s:.0f} mm/s (limit "
                f"{1e3 * limits.velocity_peak_m_per_s:g}), displacement "
                f"{1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p (limit "
                f"{1e3 * limits.displacement_peak_to_peak_m:g}); crest factor "
                f"{report.crest_factor:.2f}"
            )
            problems += list(report.problems)
        running = self.worker is not None
        text = "".join(f"<div style='color:#c0392b'>✖ {p}</div>" for p in problems)
        if not problems:
            text = "<div style='color:#1e8449'>✔ the plan can run</div>"
        text += "".join(f"<div style='color:#b9770e'>⚠ {w}</div>" for w in warnings[:4])
        self.checks.setText(text)
        self.start_button.setEnabled(not problems and not running)
        self.start_button.setToolTip(
            "; ".join(problems) or with_key("Start the calibration", START)
        )
        marks = getattr(self, "field_marks", None)
        if marks is not None:
            marks.show_problems(problems)
        return problems

    # --- running ------------------------------------------------------------------------

    @Slot()
    def start_run(self) -> None:
        if self.worker is not None or self.validate():
            return
        allowed, note = reference_allows_run(self)  # the records' due-date rule, as the CLI
        if not allowed:
            return
        self.settings.setValue("dut", self.dut.currentText())
        self.settings.setValue("stand_file", str(self.stand_file or ""))
        request = self.request()
        try:
            procedure, stand = start(request)
        except (ValueError, HardwareError) as exc:  # config, plan, missing driver or device
            QMessageBox.warning(self, "Cannot start", f"{type(exc).__name__}: {exc}")
            self.messages.setText(html.escape(f"Cannot start: {exc}"))
            return
        self.clear_run_tab()
        self.last_request = request
        if note:
            self.messages.setText(html.escape(note))
        self.state.setText("starting ...")
        self._live = {"plan": procedure.plan}
        self.worker = RunWorker(procedure, stand)
        self.stop_button.setEnabled(True)
        self.start_button.setEnabled(False)
        self.tabs.setCurrentIndex(RUN_TAB)
        self.worker.start()
        self.runs_tab.refresh()

    @Slot()
    def stop_run(self) -> None:
        if self.worker is not None:
            self.worker.procedure.abort("stopped by the operator")
            self.state.setText("stopping: fading out ...")

    @Slot()
    def emergency_stop(self) -> None:
        if self.worker is not None:
            self.worker.procedure.emergency_stop()
            self.state.setText("EMERGENCY STOP: drive at 0 V")

    def _tick(self) -> None:
        """At most FRAME_HZ times a second, on the GUI thread: take the worker's events,
        draw the latest of each kind, and end the run in the window once the worker has."""
        worker = self.worker
        if worker is None:
            return
        events = worker.drain()
        if events:
            self._take(events)
            self._draw()
        if worker.done:
            self._take(worker.drain())
            self._draw()
            self._on_done(worker.finished)

    def _take(self, events: list[Any]) -> None:
        """Keep only what the next frame draws."""
        live = self._live
        for event in events:
            if isinstance(event, PeriodBlock):
                if event.state != State.FADING_OUT:  # keep showing the last steady period
                    live["block"] = event
            elif isinstance(event, PeriodEstimate):
                live["estimate"] = event
            elif isinstance(event, StateChanged):
                live["state"] = f"{event.state}  {event.message}"
            elif isinstance(event, EqualisationStep):
                live["equalisation"] = (
                    f"equalisation {event.iteration}: worst line {100 * event.worst:.2f} %"
                )
            elif isinstance(event, Progress):
                live["progress"] = (event.fraction, event.remaining_s)
            elif isinstance(event, WarningRaised):
                live.setdefault("warnings", []).append(event.text)

    def _draw(self) -> None:
        live = self._live
        if "state" in live:
            self.state.setText(live.pop("state"))
        if "equalisation" in live:
            self.equalisation.setText(live.pop("equalisation"))
        if "progress" in live:
            fraction, remaining = live.pop("progress")
            self.progress.setValue(int(100 * fraction))
            left = "" if remaining is None else f", about {remaining:.0f} s left"
            self.progress.setFormat(f"%p %{left}")
        if live.get("warnings"):
            self.messages.setText(
                "<br/>".join(f"⚠ {html.escape(w)}" for w in live["warnings"][-4:])
            )
        block: PeriodBlock | None = live.pop("block", None)
        plan: Plan | None = live.get("plan")
        if block is not None and plan is not None:
            names = list(block.channels)
            ref = block.samples[names.index("reference")]
            dut = block.samples[names.index("dut")]
            self.live.draw_period(ref, dut, plan)
            for name, x in (("reference", ref), ("dut", dut)):
                range_v = next(c.range_v for c in self.config.inputs if c.name == name)
                fill = int(100 * np.max(np.abs(x)) / range_v)
                bar = self.meters[name]
                bar.setValue(min(fill, 100))
                bar.setStyleSheet(
                    "QProgressBar::chunk {background: %s}"
                    % ("#c0392b" if fill >= 95 else "#27ae60")
                )
        estimate: PeriodEstimate | None = live.pop("estimate", None)
        if estimate is not None:
            self._draw_characteristic(estimate.results)

    def _draw_characteristic(self, results: Results) -> None:
        worst = min(results.lines, key=lambda ln: ln.coherence)
        self.coherence.setText(
            f"coherence >= {worst.coherence:.4f} (lowest at {worst.nominal_frequency_hz:g} Hz)"
        )
        self.live.draw_characteristic(results)

    def _on_done(self, finished: Finished | None) -> None:
        """The run has ended (GUI thread): show how, list it, open its results if complete."""
        self.last_finished = finished
        self.worker = None
        self._live = {}
        self.stop_button.setEnabled(False)
        self.runs_tab.refresh()
        if finished is None:  # the worker ended without a result (its error is shown)
            return
        run_id = finished.record.run_id
        folder = self.out / str(run_id) if run_id else None
        if finished.status == RunStatus.COMPLETE and folder is not None:
            self.open_run(folder, switch=False)
            self.tabs.setCurrentIndex(RESULTS_TAB)
            self.state.setText("finished: results on tab 3")
        else:
            self.state.setText(f"ABORTED: {finished.abort_reason}")
            self.messages.setText(
                f"<b>The run was aborted:</b> {html.escape(str(finished.abort_reason))}<br/>"
                f"The drive is at {finished.record.final_output_v} V. The data so far is "
                f"kept in {html.escape(str(folder))}."
            )
        self.validate()
        self.run_finished.emit(finished)

    # --- results, runs and certificates -------------------------------------------------

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
        target = self.out / f"{record.run_id}-results"
        target.with_suffix(".csv").write_text(results.to_csv(), encoding="utf-8")
        target.with_suffix(".json").write_text(
            json.dumps(results.to_dict(), indent=2), encoding="utf-8"
        )
        self.messages.setText(html.escape(f"exported {target}.csv and .json"))
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
        if self.records.lab is not None:  # the lab's register numbers it
            return certify.ask(self, folder, record)
        dialog = CertificateDialog(self, record, self.records.certificate_defaults(record))
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return None
        info = dialog.info()
        answer = QMessageBox.question(
            self,
            "Issue the certificate?",
            f"Issue the certificate of {run_identity(record)}?",
        )
        if answer != QMessageBox.StandardButton.Yes:
            return None
        return self.issue_certificate(folder, info)

    # kept for the menu's old name
    certificate_dialog = certificate_action

    def issue_certificate(self, folder: Path, info: CertificateInfo) -> Path | None:
        """Write the certificate of the run `folder` into it; errors shown, not raised."""
        folder = Path(folder)
        try:
            path = build(folder, info, folder / "certificate.pdf")
        except (CertificateError, RunIntegrityError, ValueError, OSError) as exc:
            QMessageBox.warning(self, "Certificate refused", str(exc))
            return None
        log.info("certificate of %s written: %s", folder.name, path)
        self.messages.setText(html.escape(f"certificate written: {path}"))
        if self.results_tab.folder == folder:
            self.summary.setText(
                self.summary.text() + f"<br/>Certificate: {html.escape(str(path))}"
            )
        QDesktopServices.openUrl(QUrl.fromLocalFile(str(path.resolve())))
        return path

    def refresh_runs(self) -> None:
        self.runs_tab.refresh()

    # --- closing ------------------------------------------------------------------------

    def closeEvent(self, event: Any) -> None:
        """Fade out and stop a running calibration first; never hang."""
        self.settings.setValue("geometry", self.saveGeometry())
        worker = self.worker
        if worker is not None:
            period = worker.procedure.plan.period_s
            worker.procedure.abort("window closed")
            if not worker.join(3 * period + 5):
                worker.procedure.emergency_stop()
                worker.join(period + 5)
            if worker.done:
                self._on_done(worker.finished)
        self.timer.stop()
        self._pool.shutdown(wait=False, cancel_futures=True)
        self.teds.close()
        event.accept()

    def today_utc(self) -> date:
        """Today (UTC), or the date a test fixed."""
        return self.today or datetime.now(UTC).date()

    def wait_for_plans(self) -> None:
        """Block until the preset plans are optimised (tests, screenshots)."""
        for future in self._plans.values():
            future.result()
        self.validate()


def _login_name() -> str:
    """The operating-system user: the technician until one is typed."""
    from app.records.db.audit import current_actor

    return current_actor()
