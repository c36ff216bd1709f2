"""The technician's window: set up, check the plan, run live, read results, issue certificates.

The procedure runs on a worker thread (`RunWorker`); its events reach this window as Qt
signals and only land in a small buffer. A 25 Hz timer draws from that buffer into preallocated
pyqtgraph curves, so nothing is drawn per DAQ period and no widget is touched from the worker.
Closing the window during a run fades the drive out first (then 0 V), with a bounded wait.
"""

from __future__ import annotations

import json
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QObject, QSettings, Qt, QThread, QTimer, QUrl, Signal, Slot
from PySide6.QtGui import QDesktopServices, QKeySequence, QShortcut
from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QDialogButtonBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QMainWindow,
    QMessageBox,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from app import formatting as fmt
from app import stand_config
from app.certificate import CertificateError, CertificateInfo, build
from app.lines import parse_frequencies
from app.procedure import (
    EqualisationStep,
    Finished,
    PeriodBlock,
    PeriodEstimate,
    Procedure,
    Progress,
    StateChanged,
    WarningRaised,
)
from app.records import load_run
from app.run import RunRequest, start
from dsp.calibration import Results
from dsp.multisine import PRESETS, Plan, check_lines, make_plan, preset_plan
from dsp.spectral import period_spectrum
from dsp.uncertainty import Budget, Quantity
from hardware.errors import HardwareError
from sim.models import DUT_CATALOGUE

FRAME_HZ = 25
# labelled ticks of the logarithmic frequency axes (Hz): decades, then 2 and 5 between them
DECADE_TICKS_HZ = (1, 10, 100, 1000, 10000)
MINOR_TICKS_HZ = (2, 5, 20, 50, 200, 500, 2000, 5000, 20000)


def _hz_label(frequency_hz: float) -> str:
    return f"{frequency_hz / 1000:g}k" if frequency_hz >= 1000 else f"{frequency_hz:g}"


def _frequency_axis(plot: pg.PlotItem) -> None:
    """Logarithmic frequency axis with readable labels (pyqtgraph's own crowd together)."""
    plot.setLogMode(x=True)
    plot.getAxis("bottom").setTicks(
        [
            [(float(np.log10(f)), _hz_label(f)) for f in DECADE_TICKS_HZ],
            [(float(np.log10(f)), _hz_label(f)) for f in MINOR_TICKS_HZ],
        ]
    )


ORGANISATION, APPLICATION = "accelcal", "accelcal"


class RunWorker(QObject):
    """Runs one procedure on its own thread; forwards its events as signals."""

    event = Signal(object)
    done = Signal(object)

    def __init__(self, procedure: Procedure, stand: Any):
        super().__init__()
        self.procedure = procedure
        self.stand = stand
        procedure.listener = self.event.emit  # emitted on the worker thread, queued to the GUI

    @Slot()
    def run(self) -> None:
        try:
            finished = self.procedure.run()
        finally:
            self.stand.close()
        self.done.emit(finished)


class MainWindow(QMainWindow):
    """Setup & plan, Run (live), Results, Runs."""

    run_finished = Signal(object)  # emitted on the GUI thread when a run has ended

    def __init__(
        self,
        *,
        stand_file: Path | None = None,
        out: Path = Path("runs"),
        paced: bool = True,
        seed: int = 0,
        faults: tuple = (),
    ):
        super().__init__()
        self.setWindowTitle("accelcal: accelerometer calibration")
        self.config = stand_config.load(stand_file)
        self.stand_file, self.out, self.paced, self.seed = stand_file, Path(out), paced, seed
        self.faults = faults  # simulated stand only: for demonstrations and tests
        self.settings = QSettings(ORGANISATION, APPLICATION)
        self.procedure: Procedure | None = None
        self.thread: QThread | None = None
        self.worker: RunWorker | None = None
        self.results: Results | None = None
        self.last_finished: Finished | None = None
        self._buffer: dict[str, Any] = {}
        self._dirty = False
        self._plans: dict[str, Future] = {}
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="plan")
        for name, preset in PRESETS.items():  # optimised phases take ~1 s: off the GUI thread
            key = (name, tuple(preset.nominal_frequencies_hz))
            self._plans[key] = self._pool.submit(preset_plan, name, level_ms2=1.0)

        self.tabs = QTabWidget()
        self.setCentralWidget(self.tabs)
        self.tabs.addTab(self._setup_tab(), "1  Setup && plan")
        self.tabs.addTab(self._run_tab(), "2  Run")
        self.tabs.addTab(self._results_tab(), "3  Results")
        self.tabs.addTab(self._runs_tab(), "4  Runs")

        QShortcut(QKeySequence("Ctrl+R"), self, activated=self.start_run)
        QShortcut(QKeySequence("Ctrl+."), self, activated=self.stop_run)
        QShortcut(
            QKeySequence(Qt.Key.Key_Escape),
            self,
            activated=self.emergency_stop,
            context=Qt.ShortcutContext.ApplicationShortcut,
        )
        self.timer = QTimer(self, interval=int(1000 / FRAME_HZ), timeout=self._render)
        self.timer.start()
        geometry = self.settings.value("geometry")
        if geometry is not None:
            self.restoreGeometry(geometry)
        else:
            self.resize(1280, 820)
        self.validate()

    # --- tabs ---------------------------------------------------------------------------

    def _setup_tab(self) -> QWidget:
        page = QWidget()
        layout = QHBoxLayout(page)
        stand = QGroupBox("Stand and DUT")
        form = QFormLayout(stand)
        ref = self.config.reference
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
        form.addRow(
            "Reference standard",
            QLabel(
                f"{ref.model}\nserial {ref.serial}, certificate "
                f"{ref.certificate_number} of {ref.certificate_date}"
            ),
        )
        self.dut = QComboBox()
        self.dut.addItems(list(DUT_CATALOGUE))
        self.dut.setCurrentText(str(self.settings.value("dut", "piezo")))
        self.dut.setToolTip("DUT of the simulated stand's catalogue")
        self.dut_id = QLineEdit(str(self.settings.value("dut_id", "")))
        self.dut_id.setPlaceholderText("serial number")
        self.nominal = QDoubleSpinBox(decimals=3, maximum=10000.0, suffix=" mV/(m/s²)")
        self.nominal.setSpecialValueText("not given")
        self.tolerance = QDoubleSpinBox(decimals=1, maximum=50.0, value=5.0, suffix=" %")
        form.addRow("DUT", self.dut)
        form.addRow("DUT serial", self.dut_id)
        form.addRow("Nominal sensitivity", self.nominal)
        form.addRow("Tolerance of the characteristic", self.tolerance)
        layout.addWidget(stand, 1)

        plan = QGroupBox("Plan")
        pform = QFormLayout(plan)
        self.preset = QComboBox()
        self.preset.addItems(list(PRESETS))
        self.frequencies = QLineEdit()
        self.frequencies.setPlaceholderText("preset lines; or e.g. 10,12.5,...,1000 (Hz)")
        self.level = QDoubleSpinBox(
            decimals=2, minimum=0.01, maximum=1000.0, value=5.0, suffix=" m/s² peak per line"
        )
        self.periods = QSpinBox(minimum=3, maximum=10000, value=8, suffix=" periods")
        self.target = QDoubleSpinBox(decimals=3, maximum=10.0, suffix=" % type A target")
        self.target.setSpecialValueText("off: acquire the periods above")
        self.max_time = QSpinBox(maximum=100_000, suffix=" s at most")
        self.max_time.setSpecialValueText("no time bound")
        self.estimator = QComboBox()
        self.estimator.addItems(["periodic", "h1", "seed"])
        self.mode = QComboBox()
        self.mode.addItems(["multisine", "stepped-sine"])
        for widget in (self.preset, self.estimator, self.mode, self.dut):
            widget.currentTextChanged.connect(self.validate)
        for widget in (self.level, self.nominal, self.tolerance):
            widget.valueChanged.connect(self.validate)
        self.periods.valueChanged.connect(self.validate)
        self.frequencies.textChanged.connect(self.validate)
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
        self.state = QLabel("idle")
        self.state.setStyleSheet("font-size: 15px; font-weight: bold")
        self.equalisation = QLabel("")
        self.coherence = QLabel("")
        self.progress = QProgressBar()
        self.stop_button = QPushButton("Stop (fade out)  Ctrl+.")
        self.stop_button.setStyleSheet(
            "background: #c0392b; color: white; font-weight: bold; padding: 8px"
        )
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
        self.graphs = pg.GraphicsLayoutWidget()
        layout.addWidget(self.graphs, 1)
        self.wave_plot = self.graphs.addPlot(
            title="Last period", labels={"left": "V", "bottom": "s"}
        )
        self.wave_ref = self.wave_plot.plot(pen=pg.mkPen("#1f77b4"), name="reference")
        self.wave_dut = self.wave_plot.plot(pen=pg.mkPen("#d62728"), name="DUT")
        self.spec_plot = self.graphs.addPlot(
            title="Spectra (lines marked)", labels={"left": "dB re 1 V", "bottom": "Hz"}
        )
        _frequency_axis(self.spec_plot)
        self.spec_ref = self.spec_plot.plot(pen=pg.mkPen("#1f77b4", width=1))
        self.spec_dut = self.spec_plot.plot(pen=pg.mkPen("#d62728", width=1))
        self.spec_lines = self.spec_plot.plot(pen=None, symbol="t", symbolSize=6, symbolBrush="k")
        self.graphs.nextRow()
        self.sens_plot = self.graphs.addPlot(
            title="Sensitivity deviation from reference frequency",
            labels={"left": "%", "bottom": "Hz"},
        )
        _frequency_axis(self.sens_plot)
        self.sens_curve = self.sens_plot.plot(pen=pg.mkPen("#2c3e50"), symbol="o", symbolSize=5)
        self.sens_err = pg.ErrorBarItem(beam=0.02, pen=pg.mkPen("#7f8c8d"))
        self.sens_plot.addItem(self.sens_err)
        self.phase_plot = self.graphs.addPlot(
            title="Phase", labels={"left": "degree", "bottom": "Hz"}
        )
        _frequency_axis(self.phase_plot)
        self.phase_curve = self.phase_plot.plot(pen=pg.mkPen("#8e44ad"), symbol="o", symbolSize=5)
        self.phase_err = pg.ErrorBarItem(beam=0.02, pen=pg.mkPen("#7f8c8d"))
        self.phase_plot.addItem(self.phase_err)
        self.messages = QLabel("")
        self.messages.setWordWrap(True)
        layout.addWidget(self.messages)
        return page

    def _results_tab(self) -> QWidget:
        page = QWidget()
        layout = QVBoxLayout(page)
        self.summary = QLabel("No results yet.")
        self.summary.setStyleSheet("font-size: 14px")
        self.summary.setWordWrap(True)
        layout.addWidget(self.summary)
        self.table = QTableWidget(0, 10)
        self.table.setHorizontalHeaderLabels(
            [
                "Hz",
                "S mV/(m/s²)",
                "U",
                "dev. %",
                "phase °",
                "U °",
                "U rel. %",
                "k",
                "ISO",
                "tolerance",
            ]
        )
        middle = QHBoxLayout()
        middle.addWidget(self.table, 3)
        charts = pg.GraphicsLayoutWidget()
        self.result_mag = charts.addPlot(
            title="Deviation from the reference frequency, ± U",
            labels={"left": "%", "bottom": "Hz"},
        )
        charts.nextRow()
        self.result_phase = charts.addPlot(
            title="Phase, ± U", labels={"left": "degree", "bottom": "Hz"}
        )
        for plot in (self.result_mag, self.result_phase):
            _frequency_axis(plot)
            plot.showGrid(x=True, y=True, alpha=0.3)
        middle.addWidget(charts, 2)
        layout.addLayout(middle, 3)
        self.budget = QTableWidget(0, 4)
        self.budget.setHorizontalHeaderLabels(
            ["Component (at the reference frequency)", "value", "distribution", "standard u"]
        )
        self.budget.horizontalHeader().setStretchLastSection(True)
        self.budget.setColumnWidth(0, 420)
        layout.addWidget(self.budget, 1)
        buttons = QHBoxLayout()
        self.export_button = QPushButton("Export CSV and JSON")
        self.export_button.clicked.connect(self.export_results)
        buttons.addWidget(self.export_button)
        self.certificate_button = QPushButton("Certificate ...")
        self.certificate_button.clicked.connect(self.certificate_dialog)
        buttons.addWidget(self.certificate_button)
        layout.addLayout(buttons)
        return page

    def _runs_tab(self) -> QWidget:
        page = QWidget()
        layout = QVBoxLayout(page)
        self.runs = QListWidget()
        self.runs.itemDoubleClicked.connect(
            lambda item: self.open_run(self.out / item.text().split()[0])
        )
        refresh = QPushButton("Refresh")
        refresh.clicked.connect(self.refresh_runs)
        layout.addWidget(QLabel(f"Stored runs in {self.out} (double-click to open)"))
        layout.addWidget(self.runs, 1)
        layout.addWidget(refresh)
        self.refresh_runs()
        return page

    # --- plan checks --------------------------------------------------------------------

    def request(self) -> RunRequest:
        return RunRequest(
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
        if self.procedure is not None:
            return False
        try:
            config = stand_config.load(path)
        except stand_config.ConfigError as exc:
            QMessageBox.warning(self, "Stand configuration", str(exc))
            self.messages.setText(str(exc))
            return False
        self.config, self.stand_file = config, path
        self.stand_label.setText(f"{config.source} ({config.backend})")
        self.settings.setValue("stand_file", str(path or ""))
        self.validate()
        return True

    def _custom_lines(self) -> tuple[float, ...] | None:
        """The typed line list (Hz), None for the preset's; ValueError says what is wrong."""
        text = self.frequencies.text().strip()
        return tuple(parse_frequencies(text)) if text else None

    @Slot()
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
            QTimer.singleShot(200, self.validate)  # look again when it may be ready
        else:
            plan: Plan = future.result()
            peaks = plan.predicted_peaks()
            level = self.level.value()
            limits = self.config.limits
            d, v, a = (
                peaks.displacement_peak_to_peak_m * level,
                peaks.velocity_m_per_s * level,
                peaks.acceleration_ms2 * level,
            )
            self.peaks.setText(
                f"acceleration {a:.1f} m/s² (limit {limits.acceleration_peak_ms2:g}), velocity "
                f"{1e3 * v:.0f} mm/s (limit {1e3 * limits.velocity_peak_m_per_s:g}), displacement "
                f"{1e3 * d:.2f} mm p-p (limit {1e3 * limits.displacement_peak_to_peak_m:g}); crest "
                f"factor {plan.crest_factor():.2f}"
            )
            if d > limits.displacement_peak_to_peak_m:
                problems.append(
                    f"displacement {1e3 * d:.2f} mm p-p exceeds the exciter's "
                    f"{1e3 * limits.displacement_peak_to_peak_m:g} mm: lower the level"
                )
            if v > limits.velocity_peak_m_per_s:
                problems.append(
                    f"velocity {v:.3g} m/s exceeds {limits.velocity_peak_m_per_s:g} m/s"
                )
            if a > limits.acceleration_peak_ms2:
                problems.append(
                    f"acceleration {a:.1f} m/s² exceeds {limits.acceleration_peak_ms2:g}"
                )
        running = self.procedure is not None
        text = "".join(f"<div style='color:#c0392b'>✖ {p}</div>" for p in problems)
        if not problems:
            text = "<div style='color:#1e8449'>✔ the plan can run</div>"
        text += "".join(f"<div style='color:#b9770e'>⚠ {w}</div>" for w in warnings[:4])
        self.checks.setText(text)
        self.start_button.setEnabled(not problems and not running)
        self.start_button.setToolTip("; ".join(problems) or "Start the calibration")
        return problems

    # --- running ------------------------------------------------------------------------

    @Slot()
    def start_run(self) -> None:
        if self.procedure is not None or self.validate():
            return
        self.settings.setValue("dut", self.dut.currentText())
        self.settings.setValue("stand_file", str(self.stand_file or ""))
        self.settings.setValue("dut_id", self.dut_id.text())
        try:
            procedure, stand = start(self.request())
        except (ValueError, HardwareError) as exc:  # config, plan, missing driver or device
            QMessageBox.warning(self, "Cannot start", f"{type(exc).__name__}: {exc}")
            self.messages.setText(f"Cannot start: {exc}")
            return
        self.procedure = procedure
        self.thread = QThread(self)
        self.worker = RunWorker(procedure, stand)
        self.worker.moveToThread(self.thread)
        self.worker.event.connect(self._on_event)
        self.worker.done.connect(self._on_done)
        # ends the thread's event loop from the worker itself: a wait() on the GUI thread
        # (closing the window) cannot deadlock on a queued signal
        self.worker.done.connect(self.thread.quit, Qt.ConnectionType.DirectConnection)
        self.thread.started.connect(self.worker.run)
        self._buffer = {"plan": procedure.plan}
        self.messages.setText("")
        self.stop_button.setEnabled(True)
        self.start_button.setEnabled(False)
        self.tabs.setCurrentIndex(1)
        self.thread.start()

    @Slot()
    def stop_run(self) -> None:
        if self.procedure is not None:
            self.procedure.abort("stopped by the operator")
            self.state.setText("stopping: fading out ...")

    @Slot()
    def emergency_stop(self) -> None:
        if self.procedure is not None:
            self.procedure.emergency_stop()
            self.state.setText("EMERGENCY STOP: drive at 0 V")

    @Slot(object)
    def _on_event(self, event: Any) -> None:
        """Runs on the GUI thread; only stores, the timer draws."""
        if isinstance(event, PeriodBlock):
            self._buffer["block"] = event
        elif isinstance(event, PeriodEstimate):
            self._buffer["estimate"] = event
        elif isinstance(event, StateChanged):
            self._buffer["state"] = f"{event.state}  {event.message}"
        elif isinstance(event, EqualisationStep):
            self._buffer["equalisation"] = (
                f"equalisation {event.iteration}: worst line {100 * event.worst:.2f} %"
            )
        elif isinstance(event, Progress):
            self._buffer["progress"] = (event.fraction, event.remaining_s)
        elif isinstance(event, WarningRaised):
            self._buffer.setdefault("warnings", []).append(event.text)
        self._dirty = True

    @Slot(object)
    def _on_done(self, finished: Finished) -> None:
        self.last_finished = finished
        self._buffer.pop("state", None)  # the final word is below; the renderer must not undo it
        if self.thread is not None:
            self.thread.quit()
            self.thread.wait(5000)
        self.procedure = self.thread = self.worker = None
        self.stop_button.setEnabled(False)
        self.refresh_runs()
        if finished.status == "complete" and finished.results is not None:
            self.show_results(finished.results, finished.record)
            self.tabs.setCurrentIndex(2)
            self.state.setText("finished: results on tab 3")
        else:
            self.state.setText(f"ABORTED: {finished.abort_reason}")
            self.messages.setText(
                f"<b>The run was aborted:</b> {finished.abort_reason}<br/>The drive is at "
                f"{finished.record.get('final_output_v')} V. The data so far is kept in "
                f"{self.out / str(finished.record.get('run_id'))}."
            )
        self.validate()
        self.run_finished.emit(finished)

    def _render(self) -> None:
        """At most FRAME_HZ times a second: draw what the buffer holds."""
        if not self._dirty:
            return
        self._dirty = False
        b = self._buffer
        if "state" in b:
            self.state.setText(b["state"])
        if "equalisation" in b:
            self.equalisation.setText(b["equalisation"])
        if "progress" in b:
            fraction, remaining = b["progress"]
            self.progress.setValue(int(100 * fraction))
            left = "" if remaining is None else f", about {remaining:.0f} s left"
            self.progress.setFormat(f"%p %{left}")
        if "warnings" in b:
            self.messages.setText("<br/>".join(f"⚠ {w}" for w in b["warnings"][-4:]))
        block: PeriodBlock | None = b.get("block")
        plan: Plan | None = b.get("plan")
        if block is not None and plan is not None:
            names = list(block.channels)
            ref, dut = block.samples[names.index("reference")], block.samples[names.index("dut")]
            t = np.arange(ref.size) / plan.sample_rate_hz
            step = max(1, ref.size // 4000)  # enough points for the eye
            self.wave_ref.setData(t[::step], ref[::step])
            self.wave_dut.setData(t[::step], dut[::step])
            spectra = np.abs(period_spectrum(np.vstack([ref, dut]))) + 1e-12
            f = np.arange(spectra.shape[1]) * plan.sample_rate_hz / ref.size
            self.spec_ref.setData(f[1:], 20 * np.log10(spectra[0, 1:]))
            self.spec_dut.setData(f[1:], 20 * np.log10(spectra[1, 1:]))
            if ref.size == plan.period_samples:
                self.spec_lines.setData(plan.frequencies_hz, 20 * np.log10(spectra[0, plan.bins]))
            for name, x in (("reference", ref), ("dut", dut)):
                range_v = next(c.range_v for c in self.config.inputs if c.name == name)
                fill = int(100 * np.max(np.abs(x)) / range_v)
                bar = self.meters[name]
                bar.setValue(min(fill, 100))
                bar.setStyleSheet(
                    "QProgressBar::chunk {background: %s}"
                    % ("#c0392b" if fill >= 95 else "#27ae60")
                )
        estimate: PeriodEstimate | None = b.pop("estimate", None)
        if estimate is not None:
            self._draw_characteristic(estimate.results)

    def _draw_characteristic(self, results: Results) -> None:
        worst = min(results.lines, key=lambda ln: ln.coherence)
        self.coherence.setText(
            f"coherence >= {worst.coherence:.4f} (lowest at {worst.nominal_frequency_hz:g} Hz)"
        )
        f = np.log10([ln.frequency_hz for ln in results.lines])
        dev = np.array([ln.deviation_percent for ln in results.lines])
        u = np.array([100 * ln.relative_expanded_uncertainty for ln in results.lines])
        ph = np.array([ln.phase_deg for ln in results.lines])
        uph = np.array([ln.phase_expanded_uncertainty_deg for ln in results.lines])
        self.sens_curve.setData(10**f, dev)
        self.sens_err.setData(x=f, y=dev, height=2 * np.nan_to_num(u))
        self.phase_curve.setData(10**f, ph)
        self.phase_err.setData(x=f, y=ph, height=2 * np.nan_to_num(uph))

    # --- results and runs ---------------------------------------------------------------

    def show_results(self, results: Results, record: dict[str, Any]) -> None:
        self.results = results
        self._current_record = record
        r = results.reference
        value, u = fmt.round_gum(r.sensitivity_mv_per_ms2, r.expanded_uncertainty_mv_per_ms2)
        self.summary.setText(
            f"<b>Reference sensitivity at {r.frequency_hz:g} Hz: ({value} ± {u}) mV/(m/s²)</b> "
            f"({r.sensitivity_db:.2f} dB re 1 mV/(m/s²)), k = {r.coverage_factor:.2f}, "
            f"p = {100 * r.coverage_probability:.2f} %. Run {record.get('run_id')}, "
            f"{results.periods} periods, {record.get('mode')}."
        )
        self.table.setRowCount(len(results.lines))
        for row, ln in enumerate(results.lines):
            s, us = fmt.round_gum(ln.sensitivity_mv_per_ms2, ln.expanded_uncertainty_mv_per_ms2)
            p, up = fmt.round_gum(ln.phase_deg, ln.phase_expanded_uncertainty_deg)
            cells = [
                f"{ln.nominal_frequency_hz:g}",
                s,
                us,
                fmt.signed(ln.deviation_percent, 2),
                p,
                up,
                fmt.significant(100 * ln.relative_expanded_uncertainty),
                f"{ln.coverage_factor:.2f}",
                ln.iso_verdict,
                ln.tolerance_verdict or "",
            ]
            for column, text in enumerate(cells):
                self.table.setItem(row, column, QTableWidgetItem(text))
        self._draw_characteristic(results)
        self._draw_result_charts(results)
        self._fill_budget(results, record)

    def _draw_result_charts(self, results: Results) -> None:
        """Deviation and phase with their expanded-uncertainty bands (log frequency)."""
        f = np.array([ln.frequency_hz for ln in results.lines])
        for plot, values, half in (
            (
                self.result_mag,
                [ln.deviation_percent for ln in results.lines],
                [100 * ln.relative_expanded_uncertainty for ln in results.lines],
            ),
            (
                self.result_phase,
                [ln.phase_deg for ln in results.lines],
                [ln.phase_expanded_uncertainty_deg for ln in results.lines],
            ),
        ):
            plot.clear()
            v, u = np.array(values), np.nan_to_num(np.array(half))
            lower = plot.plot(f, v - u, pen=pg.mkPen("#9bb7e0"))
            upper = plot.plot(f, v + u, pen=pg.mkPen("#9bb7e0"))
            plot.addItem(pg.FillBetweenItem(lower, upper, brush=pg.mkBrush(155, 183, 224, 110)))
            plot.plot(f, v, pen=pg.mkPen("#1f3a68", width=2), symbol="o", symbolSize=5)

    def _fill_budget(self, results: Results, record: dict[str, Any]) -> None:
        """The stored budget at the reference frequency, with this run's type A."""
        budget = Budget.from_list(record.get("budget", []))
        line = next(
            ln for ln in results.lines if ln.nominal_frequency_hz == results.reference.frequency_hz
        )
        rows = [
            (
                "repeatability (type A, this run)",
                "",
                "normal (t)",
                f"{100 * line.relative_type_a:.3g} %",
            ),
        ]
        rows += [
            (
                c.name,
                f"{100 * c.value:.3g} %",
                str(c.distribution),
                f"{100 * c.standard_uncertainty:.3g} %",
            )
            for c in budget.at(line.frequency_hz, Quantity.MAGNITUDE)
        ]
        rows += [
            (
                "combined standard uncertainty",
                "",
                "",
                f"{100 * line.relative_standard_uncertainty:.3g} %",
            ),
            (
                f"expanded (k = {line.coverage_factor:.2f})",
                "",
                "",
                f"{fmt.significant(100 * line.relative_expanded_uncertainty)} %",
            ),
        ]
        self.budget.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c, text in enumerate(row):
                self.budget.setItem(r, c, QTableWidgetItem(text))

    def export_results(self) -> Path | None:
        """Copy the stored results of the shown run (CSV and JSON) beside the run folders."""
        if self.results is None:
            return None
        run_id = self._current_record.get("run_id")
        target = self.out / f"{run_id}-results"
        target.with_suffix(".csv").write_text(self.results.to_csv(), encoding="utf-8")
        target.with_suffix(".json").write_text(
            json.dumps(self.results.to_dict(), indent=2), encoding="utf-8"
        )
        self.messages.setText(f"exported {target}.csv and .json")
        return target

    def certificate_dialog(self) -> Path | None:
        """Ask for what the certificate needs beyond the run, then write and open the PDF."""
        if self.results is None:
            QMessageBox.information(self, "Certificate", "Open a complete run first (tab 4).")
            return None
        dialog = CertificateDialog(self, self.settings)
        if dialog.exec() != QDialog.DialogCode.Accepted:
            return None
        return self.issue_certificate(dialog.info())

    def issue_certificate(self, info: CertificateInfo) -> Path | None:
        """Write the certificate of the shown run into its folder; errors shown, not raised."""
        folder = self.out / str(self._current_record.get("run_id"))
        try:
            path = build(folder, info, folder / "certificate.pdf")
        except CertificateError as exc:
            QMessageBox.warning(self, "Certificate refused", str(exc))
            return None
        self.messages.setText(f"certificate written: {path}")
        self.summary.setText(self.summary.text() + f"<br/>Certificate: {path}")
        QDesktopServices.openUrl(QUrl.fromLocalFile(str(path.resolve())))
        return path

    def refresh_runs(self) -> None:
        self.runs.clear()
        if not self.out.exists():
            return
        for folder in sorted(self.out.iterdir(), reverse=True):
            if (folder / "results.json").exists():
                status = json.loads((folder / "results.json").read_text()).get("status", "?")
                self.runs.addItem(f"{folder.name}   {status}")

    def open_run(self, folder: Path) -> None:
        record = load_run(folder)
        if record.get("results"):
            self.show_results(Results.from_dict(record["results"]), record)
            self.tabs.setCurrentIndex(2)
        else:
            self.summary.setText(
                f"Run {folder.name}: {record['status']} ({record.get('abort_reason')})"
            )

    # --- closing ------------------------------------------------------------------------

    def closeEvent(self, event: Any) -> None:
        """Fade out and stop a running calibration first; never hang."""
        self.settings.setValue("geometry", self.saveGeometry())
        if self.procedure is not None and self.thread is not None:
            period = self.procedure.plan.period_s
            self.procedure.abort("window closed")
            if not self.thread.wait(int(1000 * (3 * period + 5))):
                self.procedure.emergency_stop()
                self.thread.wait(int(1000 * (period + 5)))
            QThread.msleep(0)
        self._pool.shutdown(wait=False, cancel_futures=True)
        event.accept()

    def wait_for_plans(self) -> None:
        """Block until the preset plans are optimised (tests, screenshots)."""
        for future in self._plans.values():
            future.result()
        self.validate()


class CertificateDialog(QDialog):
    """Customer, signatory and conditions for a certificate (remembered between sessions)."""

    FIELDS = (
        ("customer", "Customer"),
        ("customer_address", "Customer address"),
        ("authorised_by", "Authorised by"),
        ("mounting", "Mounting"),
        ("dut_model", "DUT model (empty: from the run)"),
        ("dut_type", "DUT type (empty: from the run)"),
        ("notes", "Notes"),
    )

    def __init__(self, parent: QWidget, settings: QSettings):
        super().__init__(parent)
        self.setWindowTitle("Certificate")
        self.settings = settings
        form = QFormLayout(self)
        self.edits: dict[str, QLineEdit] = {}
        for key, label in self.FIELDS:
            edit = QLineEdit(str(settings.value(f"certificate/{key}", "")))
            form.addRow(label, edit)
            self.edits[key] = edit
        self.temperature = QDoubleSpinBox(decimals=1, minimum=-50, maximum=100, suffix=" °C")
        self.temperature.setValue(float(settings.value("certificate/temperature_c", 23.0)))
        form.addRow("Ambient temperature", self.temperature)
        buttons = QDialogButtonBox(
            QDialogButtonBox.StandardButton.Ok | QDialogButtonBox.StandardButton.Cancel
        )
        buttons.accepted.connect(self.accept)
        buttons.rejected.connect(self.reject)
        form.addRow(buttons)

    def info(self) -> CertificateInfo:
        values = {key: edit.text().strip() or None for key, edit in self.edits.items()}
        for key, value in values.items():
            self.settings.setValue(f"certificate/{key}", value or "")
        self.settings.setValue("certificate/temperature_c", self.temperature.value())
        return CertificateInfo(
            customer=values["customer"],
            customer_address=values["customer_address"] or "",
            authorised_by=values["authorised_by"],
            mounting=values["mounting"],
            dut_model=values["dut_model"],
            dut_type=values["dut_type"],
            notes=values["notes"] or "",
            temperature_c=self.temperature.value(),
        )
