"""The Setup & plan tab: the stand (file or simulated) and its reference standard, the
technician, the DUT (serial looked up in the records, or its TEDS), and the plan (preset or
typed lines in Hz, level in m/s^2 peak per line, periods, type A target in %, time bound in s,
estimator, mode and, for the stepped sine, its block in s) with the same preflight checks as
the CLI beside the fields. Start is enabled only when nothing fails; the tab builds the run
request the fields describe.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from PySide6.QtCore import QSettings, Qt, QTimer, Signal
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QMessageBox,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from app.gui import field_marks
from app.gui.actions import START, with_key
from app.gui.fixture_entry import FixtureEntry
from app.gui.form_area import FormArea
from app.gui.plan_cache import PlanCache
from app.gui.quantity_edit import QuantityEdit
from app.gui.reference_view import describe_reference
from app.gui.results_tab import wrapping_label
from app.gui.sensor_entry import SerialEntry
from app.gui.table_items import shown_unit
from app.gui.teds_entry import TedsEntry
from app.gui.templates import TemplatePicker
from app.io import quantities
from app.io.quantities import QuantityError
from app.io.vocabulary import Mode
from app.lines import parse_frequencies
from app.procedure.modes import DEFAULT_STEPPED_BLOCK_S
from app.procedure.options import EXACT_MAINS_HELP, RESONANCE_HELP, RunOptions, option
from app.procedure.request import RunRequest
from app.procedure.service import PlanPreview, PreparedRun, RunService
from app.procedure.stopping import DEFAULT_MAX_PERIODS, DEFAULT_MAX_TIME_S
from app.stand import config as stand_config
from app.stand.simulated import CATALOGUE
from dsp.estimators import DEFAULT_ESTIMATOR, Estimator, default_estimator, default_periods
from dsp.multisine import PRESETS, Plan

log = logging.getLogger(__name__)

OPTIMISING = "optimising the multisine phases ..."  # progress shown while the plan is made
FIELD_MIN_CHARS = 26  # the Stand and DUT fields' narrowest (average characters)


@dataclass
class WindowOptions:
    """How this window runs, from its command line: the runs root, paced in real time or not,
    the simulated stand's seed and faults (demonstrations and tests)."""

    out: Path
    paced: bool = True
    seed: int = 0
    faults: tuple = ()
    sim_hum: tuple = ()  # simulated stand: hum only while driven (accelcal gui --sim-hum)


@dataclass(frozen=True)
class PlanSettings:
    """The plan fields of the tab (Next sensor puts the first ones back; templates fill them).
    Zero means "not given" where the field says so."""

    nominal_mv_per_ms2: float  # 0: not given
    tolerance_percent: float
    preset: str
    frequencies: str  # the lines as typed (Hz); "": the preset's
    level_ms2: float  # peak per line
    periods: int
    target_percent: float  # type A target in %; 0: off
    max_time_s: int  # 0: not given (with a target: the default bound, stopping.py)
    estimator: str
    mode: str
    stepped_block_s: float = DEFAULT_STEPPED_BLOCK_S  # the stepped sine's block


class SetupTab(QWidget):
    """The stand, DUT and plan fields, their checks and the run request they describe."""

    start_requested = Signal()  # the Start button
    said = Signal(str)  # a word for the operator (shown on the Run tab)

    def __init__(
        self,
        config: stand_config.StandConfig,
        stand_file: Path | None,
        records: Any,
        settings: QSettings,
        options: WindowOptions,
    ) -> None:
        super().__init__()
        self.config, self.stand_file, self.records = config, stand_file, records
        self.settings, self.options = settings, options
        self.running = False  # a run is going: Start stays disabled
        self.last_request: RunRequest | None = None  # the settings of the run just made
        self.service = RunService(stand_file, config=config)  # the stand file, loaded once
        self.preview: PlanPreview | None = None  # the plan that will run, as last checked
        # the last preview with what it was made of: Start and set_running validate again
        # with the same fields, and a preview of a 51.2 kS/s plan costs the GUI thread 0.5 s
        self._previewed: tuple[Any, RunOptions, Plan, PlanPreview] | None = None
        self.plans = PlanCache(RunService.unit_plan, self.service.preset_keys())
        # the two boxes scroll as one when the window is smaller than they need (a screen
        # smaller than the form): their rows never overlap (app.gui.form_area)
        self.form = QWidget()
        boxes = QHBoxLayout(self.form)
        boxes.addWidget(self._stand_box(), 2)
        boxes.addWidget(self._plan_box(), 3)
        self.form_area = FormArea(self.form)
        layout = QVBoxLayout(self)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(self.form_area)
        self.plan_defaults = self.plan_settings()
        self.field_marks = field_marks.install(self)  # bad input marked at its field
        self.serial_entry = SerialEntry(self, records, self.field_marks)
        self.fixture = FixtureEntry(self, records, self.field_marks)  # issue 36: its DUTs
        self.dut_form.addRow(self.fixture.widget)
        self.fixture.show_for(self)
        self.serial_entry.sensor_changed.connect(self.templates.show_for)
        self.mode.currentTextChanged.connect(self._mode_changed)
        self._mode_changed(self.mode.currentText())
        for widget in (self.preset, self.estimator, self.mode, self.dut):
            widget.currentTextChanged.connect(self.validate)
        for edit in self.quantity_fields():
            edit.edited.connect(self.validate)
        self.periods.valueChanged.connect(self.validate)
        self.frequencies.textChanged.connect(self.validate)
        self.exact_mains_bins.toggled.connect(self.validate)  # the plan's lines move

    def _stand_box(self) -> QGroupBox:
        stand = QGroupBox("Stand and DUT")
        form = QFormLayout(stand)
        form.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        # the stand's name wraps on a row of its own (beside the buttons it was cut at the
        # height of a button), the buttons under it
        self.stand_label = wrapping_label(f"{self.config.source} ({self.config.backend})")
        choose = QPushButton("Stand file ...")
        choose.clicked.connect(self.choose_stand)
        simulated = QPushButton("Simulated stand")
        simulated.clicked.connect(lambda: self.load_stand(None))
        stand_buttons = QHBoxLayout()
        stand_buttons.addWidget(choose)
        stand_buttons.addWidget(simulated)
        stand_buttons.addStretch(1)
        form.addRow("Stand", self.stand_label)
        form.addRow("", stand_buttons)
        self.reference_label = wrapping_label(describe_reference(self.config))
        self.reference_label.setTextFormat(Qt.TextFormat.RichText)
        form.addRow("Reference standard", self.reference_label)
        # empty until typed once, then the last entry (never the login name: a shared
        # account at the stand would sign for whoever is working)
        self.technician = QLineEdit(str(self.settings.value("technician", "") or ""))
        self.technician.setPlaceholderText("your name (remembered for next time)")
        self.technician.setToolTip(
            "who is working at the stand today: 'Prepared by' on the certificates"
        )
        self.technician.editingFinished.connect(
            lambda: self.settings.setValue("technician", self.technician.text().strip())
        )
        form.addRow("Technician", self.technician)
        self.dut = QComboBox()
        self.dut.addItems(list(CATALOGUE))
        self.dut.setCurrentText(str(self.settings.value("dut", "piezo")))
        self.dut.setToolTip("DUT of the simulated stand's catalogue")
        # never restored from the last session: another day's sensor is another serial
        self.dut_id = QLineEdit()
        self.dut_id.setPlaceholderText("serial number of the sensor on the stand")
        # quantity fields: a number in the row's unit, or with its unit (0.5g, 100 mV/g, 0.2 %),
        # read as the command line reads it (app.gui.quantity_edit)
        self.nominal = QuantityEdit(
            quantities.NOMINAL_SENSITIVITY, "nominal sensitivity", blank="not given"
        )
        self.tolerance = QuantityEdit(quantities.TOLERANCE, "tolerance", value=5.0, blank="none")
        form.addRow("DUT", self.dut)
        form.addRow("DUT serial", self.dut_id)
        self.teds = TedsEntry(self, self.records)
        form.addRow("", self.teds.button)
        form.addRow("Nominal sensitivity", self.nominal)
        form.addRow("Tolerance of the characteristic", self.tolerance)
        self.dut_form = form  # the fixture's positions go under it (`_show_fixture`)
        # a field narrower than this goes under its label (WrapLongRows) instead of being
        # squeezed beside it: the reference text, a serial and its note stay readable
        narrowest = FIELD_MIN_CHARS * self.fontMetrics().averageCharWidth()
        for field in (
            self.stand_label,
            self.reference_label,
            self.technician,
            self.dut,
            self.dut_id,
            self.teds.button,
            self.nominal,
            self.tolerance,
        ):
            field.setMinimumWidth(narrowest)
        return stand

    def _plan_box(self) -> QGroupBox:
        plan = QGroupBox("Plan")
        pform = QFormLayout(plan)
        pform.setRowWrapPolicy(QFormLayout.RowWrapPolicy.WrapLongRows)
        self.preset = QComboBox()
        self.preset.addItems(list(PRESETS))
        self.frequencies = QLineEdit()
        self.frequencies.setPlaceholderText("preset lines; or e.g. 10,12.5,...,1000 (Hz)")
        self.level = QuantityEdit(quantities.LEVEL, "level", value=5.0, suffix="m/s² peak per line")
        # one record of one period with the default estimator (lpm); the estimator's own
        # default follows it when it changes (_estimator_changed)
        self.periods = QSpinBox(
            minimum=1, maximum=10000, value=default_periods(DEFAULT_ESTIMATOR), suffix=" periods"
        )
        self.target = QuantityEdit(
            quantities.TARGET_UA,
            "type A target",
            blank="off: acquire the periods above",
            suffix="% type A target",
        )
        # 0: not given; with a type A target the run's default bound applies (its tooltip)
        self.max_time = QSpinBox(maximum=int(quantities.MAX_TIME.high), suffix=" s at most")
        self.max_time.setSpecialValueText(
            f"default ({DEFAULT_MAX_TIME_S:g} s with a target, or {DEFAULT_MAX_PERIODS} periods)"
        )
        self.estimator = QComboBox()
        self.estimator.addItems(list(option("estimator").choices))
        self.estimator.setCurrentText(DEFAULT_ESTIMATOR)
        self._estimator_shown = self.estimator.currentText()
        self.estimator.currentTextChanged.connect(self._estimator_changed)
        self.mode = QComboBox()
        self.mode.addItems(list(option("mode").choices))
        self.stepped_block = QuantityEdit(
            quantities.STEPPED_BLOCK,
            "stepped block",
            value=DEFAULT_STEPPED_BLOCK_S,
            suffix="s block (stepped sine)",
        )
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
        pform.addRow("Stepped block", self.stepped_block)
        # issue 32: lines on mains harmonics move one bin unless kept; the resonance search
        self.exact_mains_bins = QCheckBox("keep lines on exact mains harmonics")
        self.exact_mains_bins.setToolTip(EXACT_MAINS_HELP)
        self.resonance = QCheckBox("search the mounted resonance in the response")
        self.resonance.setToolTip(RESONANCE_HELP)
        pform.addRow("Mains", self.exact_mains_bins)
        pform.addRow("Resonance", self.resonance)
        self.peaks = QLabel()
        self.peaks.setWordWrap(True)
        self.peaks.setMinimumHeight(48)
        pform.addRow("Predicted", self.peaks)
        self.checks = QLabel()
        self.checks.setWordWrap(True)
        self.checks.setTextFormat(Qt.TextFormat.RichText)
        pform.addRow("Checks", self.checks)
        self.start_button = QPushButton("Start  (Ctrl+R)")
        self.start_button.clicked.connect(self.start_requested)
        pform.addRow(self.start_button)
        self._bind_help()
        return plan

    def _bind_help(self) -> None:
        """Each field's tooltip from the run options table (app.procedure.options): the same
        help, unit and bounds as `accelcal run --help` (a field's own tooltip stays)."""
        bindings = {
            "dut": self.dut,
            "dut_id": self.dut_id,
            "nominal_mv_per_ms2": self.nominal,
            "tolerance_percent": self.tolerance,
            "preset": self.preset,
            "frequencies_hz": self.frequencies,
            "level_ms2": self.level,
            "periods": self.periods,
            "target_type_a": self.target,
            "max_acquisition_s": self.max_time,
            "estimator": self.estimator,
            "mode": self.mode,
        }
        for name, widget in bindings.items():
            if not widget.toolTip():
                widget.setToolTip(option(name).full_help())
        # the block field's own tooltip says how it reads; the option's help says what it does
        spec = option("stepped_block_s")
        self.stepped_block.setToolTip(f"{spec.help}. {self.stepped_block.toolTip()}")

    # --- the size it needs ---------------------------------------------------------------

    def height_for(self, width: int) -> int:
        """The height (px) the tab needs at `width` (px) to show every row whole, unscrolled."""
        return self.form_area.height_for(width)

    def forget_sizes(self) -> None:
        """Drop the sizes cached before the window was first shown (`FormArea.forget_sizes`)."""
        self.form_area.forget_sizes()
        layout = self.layout()
        if layout is not None:
            layout.invalidate()
        self.updateGeometry()  # and the tab's own, cached by the tab widget's stack

    # --- the plan fields ----------------------------------------------------------------

    def plan_settings(self) -> PlanSettings:
        """The plan fields as they are now."""
        return PlanSettings(
            nominal_mv_per_ms2=self.nominal.value(),
            tolerance_percent=self.tolerance.value(),
            preset=self.preset.currentText(),
            frequencies=self.frequencies.text(),
            level_ms2=self.level.value(),
            periods=self.periods.value(),
            target_percent=self.target.value(),
            max_time_s=self.max_time.value(),
            estimator=self.estimator.currentText(),
            mode=self.mode.currentText(),
            stepped_block_s=self.stepped_block.value(),
        )

    def _estimator_changed(self, estimator: str) -> None:
        """The periods follow the estimator's default (1 with lpm, 8 with the averaging
        estimators) while they hold the previous estimator's default; a count typed stays."""
        previous, self._estimator_shown = self._estimator_shown, estimator
        if estimator and self.periods.value() == default_periods(previous):
            self.periods.setValue(default_periods(estimator))

    def apply_plan(self, plan: PlanSettings) -> None:
        """Put `plan` into the fields (and check them)."""
        self.nominal.setValue(plan.nominal_mv_per_ms2)
        self.tolerance.setValue(plan.tolerance_percent)
        self.preset.setCurrentText(plan.preset)
        self.frequencies.setText(plan.frequencies)
        self.level.setValue(plan.level_ms2)
        self.estimator.setCurrentText(plan.estimator)  # before the periods it would move
        self.periods.setValue(plan.periods)
        self.target.setValue(plan.target_percent)
        self.max_time.setValue(plan.max_time_s)
        self.mode.setCurrentText(plan.mode)
        self.stepped_block.setValue(plan.stepped_block_s)
        self.validate()

    def reset(self) -> None:
        """Nothing of the last sensor: no serial, no look-up, the plan as the tab opened."""
        self.dut_id.clear()
        self.serial_entry.reset()
        self.fixture.reset()
        self.apply_plan(self.plan_defaults)
        self.last_request = None
        self.field_marks.note(self.reference_label, None)
        self.dut_id.setFocus(Qt.FocusReason.ShortcutFocusReason)
        self.validate()

    def set_running(self, running: bool) -> None:
        """A run started or ended: Start follows."""
        self.running = running
        self.validate()

    def quantity_fields(self) -> tuple[QuantityEdit, ...]:
        """The fields that take a quantity (with its unit, or a bare number in the row's)."""
        return (self.nominal, self.tolerance, self.level, self.target, self.stepped_block)

    def field_errors(self) -> list[str]:
        """Why each refused quantity field is refused ("level: ..."), in form order (a field
        the mode does not use, disabled, refuses nothing)."""
        fields = (f for f in self.quantity_fields() if f.isEnabled())
        return [e for e in (f.error() for f in fields) if e is not None]

    def _mode_changed(self, mode: str) -> None:
        """The stepped sine's block is a field of that mode only; a stepped sine has no lpm
        (it analyses a multisine record): the estimator then goes to that mode's default."""
        self.stepped_block.setEnabled(mode == Mode.STEPPED_SINE)
        if self.estimator.currentText() == Estimator.LPM and default_estimator(mode) != "lpm":
            self.estimator.setCurrentText(default_estimator(mode))

    def custom_lines(self) -> tuple[float, ...] | None:
        """The typed line list (Hz), None for the preset's; ValueError says what is wrong."""
        text = self.frequencies.text().strip()
        return tuple(parse_frequencies(text)) if text else None

    def run_options(self, reference_override: str | None = None) -> RunOptions:
        """The run the fields describe as the run service's options (the same table as
        `accelcal run`'s): the catalogue DUT (simulated stand), the serial and, when its
        look-up found it on record, its specification; what the operator states over the
        record. The records in use are the window's own (`prepare` passes them). ValueError
        names a field that does not parse (a refused quantity field: QuantityError, never a
        run with a value the field does not show)."""
        for refused in self.field_errors():
            raise QuantityError("", refused)
        options = self.options
        return RunOptions(
            stand_file=self.stand_file,
            dut=self.dut.currentText(),
            dut_id=(self.dut_id.text().strip() or None) if not self.fixture.active else None,
            dut_spec=self.serial_entry.spec if not self.fixture.active else None,
            technician=self.technician.text().strip() or None,
            nominal_mv_per_ms2=self.nominal.value() or None,
            tolerance_percent=self.tolerance.value() or None,
            preset=self.preset.currentText(),
            frequencies_hz=self.custom_lines(),
            level_ms2=self.level.value(),
            periods=self.periods.value(),
            target_type_a=self.target.value() / 100 or None,
            max_acquisition_s=float(self.max_time.value()) or None,
            estimator=Estimator(self.estimator.currentText()),
            mode=Mode(self.mode.currentText()),
            stepped_block_s=self.block_s(),
            seed=options.seed,
            paced=options.paced,
            faults=options.faults,
            sim_hum=options.sim_hum,
            exact_mains_bins=self.exact_mains_bins.isChecked(),
            resonance=self.resonance.isChecked(),
            out=options.out,
            db=self.records.url,
            records=False,  # the window's records, when open, come as `lab` (prepare)
            reference_override=reference_override,
        )

    def block_s(self) -> float | None:
        """The stepped sine's block (s) the field sets; None in multisine (no block then)."""
        if self.mode.currentText() != Mode.STEPPED_SINE:
            return None
        return self.stepped_block.value()

    def prepare(self, *, reference_override: str | None = None, today: Any = None) -> PreparedRun:
        """The run the fields describe, resolved and gated by the run service as the CLI's:
        with the window's records open, their quick check and the reference standard's rule
        (`reference_override`: the reason typed; `today`: the window's date); the phases of
        the plan the preview checked. Refuses (a Refusal naming the field or the records)."""
        options = self.run_options(reference_override)
        return self.service.prepare(
            options,
            lab=self.records.lab,
            today=today,
            unit_plan=self.plans.ready(self.service.phase_key(options)),
        )

    def request(self) -> RunRequest:
        """The settings the fields describe (DUT resolved, no records read): what a template
        saves."""
        return self.service.draft(self.run_options(), stand_plan=False)

    # --- the stand ----------------------------------------------------------------------

    def choose_stand(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Stand configuration", "", "TOML (*.toml)")
        if path:
            self.load_stand(Path(path))

    def load_stand(self, path: Path | None) -> bool:
        """Switch to the stand of `path` (None: the simulated one); errors name the field."""
        if self.running:
            return False
        try:
            config = stand_config.load(path)
        except stand_config.ConfigError as exc:
            QMessageBox.warning(self, "Stand configuration", str(exc))
            self.said.emit(str(exc))
            return False
        self.config, self.stand_file = config, path
        self.service = RunService(path, config=config)
        self.stand_label.setText(f"{config.source} ({config.backend})")
        self.fixture.show_for(self)
        self.show_reference()
        self.settings.setValue("stand_file", str(path or ""))
        self.validate()
        return True

    def show_reference(self) -> None:
        """The reference standard the run will use: the stand file's, with its record."""
        self.reference_label.setText(describe_reference(self.config, self.records))

    # --- the checks ---------------------------------------------------------------------

    def validate(self) -> list[str]:
        """The preview of the plan that will run (the run service's: the stand file's [plan]
        applied) and its checks beside the fields; Start only when nothing fails."""
        problems: list[str] = self.field_errors()  # a refused quantity field: its reason
        problems += self.fixture.problems(self.mode.currentText())  # its DUTs, if any
        warnings: list[str] = []
        pending = ""  # work in progress (not an error): Start waits for it
        self.preview = None
        future = None
        try:
            options = self.run_options()
            key = self.service.phase_key(options)
            check = self.service.line_check(options)  # at once, before any optimisation
        except QuantityError:
            pass  # a refused field, said at the field (no plan checked until it reads)
        except ValueError as exc:  # the lines typed, or a DUT that cannot be resolved
            problems.append(f"lines: {exc}" if "lines" not in str(exc) else str(exc))
        else:
            problems += list(check.errors)
            warnings += [w for w in check.warnings if "mains" in w]
            if not problems:  # a new line list is optimised off this thread
                future = self.plans.ask(key)
        if future is None:
            self.peaks.setText("")
        elif not future.done():
            pending = OPTIMISING
            self.peaks.setText("")
            QTimer.singleShot(200, self, self.validate)  # look again when it may be ready
        else:
            error = future.exception()
            if error is not None:
                problems += list(getattr(error, "problems", None) or [str(error)])
                self.peaks.setText("")
            else:
                self.preview = self._preview(options, future.result())
                problems += list(self.preview.problems)
                self.peaks.setText(describe_preview(self.preview, self.config.limits))
        text = "".join(f"<div style='color:#c0392b'>✖ {shown_unit(p)}</div>" for p in problems)
        if pending:
            text += f"<div style='color:#2e4053'>⏳ {pending}</div>"
        elif not problems:
            text = "<div style='color:#1e8449'>✔ the plan can run</div>"
        text += "".join(f"<div style='color:#b9770e'>⚠ {shown_unit(w)}</div>" for w in warnings[:4])
        self.checks.setText(text)
        blocking = [*problems, pending] if pending else problems
        self.start_button.setEnabled(not blocking and not self.running)
        self.start_button.setToolTip(
            "; ".join(blocking) or with_key("Start the calibration", START)
        )
        self.field_marks.show_problems(problems)
        return blocking

    def _preview(self, options: RunOptions, plan: Plan) -> PlanPreview:
        """The run service's preview of `options` on `plan`, made again only when the stand,
        the fields or the plan changed."""
        last = self._previewed
        if last is not None and last[0] is self.service and last[1] == options and last[2] is plan:
            return last[3]
        preview = self.service.preview(options, plan)
        self._previewed = (self.service, options, plan, preview)
        return preview

    def wait_for_plans(self) -> None:
        """Block until the plans asked for are optimised (tests, screenshots)."""
        self.plans.wait()
        self.validate()

    def close_pools(self) -> None:
        """The plan and TEDS worker pools end (the window closes)."""
        self.plans.close()
        self.teds.close()
        self.fixture.close()


def describe_preview(preview: PlanPreview, limits: Any) -> str:
    """The previewed plan in one paragraph: its lines (Hz) and its predicted peaks against the
    stand's limits (m/s^2, mm/s, mm peak-to-peak), its crest factor, and the input ranges with
    each channel's fewest LSB per line (app.procedure.ranging)."""
    report, lines = preview.report, preview.lines_hz
    if report is None or not lines:
        return ""
    peaks = report.peaks
    return (
        f"{len(lines)} lines, {min(lines):g} to {max(lines):g} Hz; acceleration "
        f"{peaks.acceleration_ms2:.1f} m/s² (limit {limits.acceleration_peak_ms2:g}), velocity "
        f"{1e3 * peaks.velocity_m_per_s:.0f} mm/s (limit "
        f"{1e3 * limits.velocity_peak_m_per_s:g}), displacement "
        f"{1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p (limit "
        f"{1e3 * limits.displacement_peak_to_peak_m:g}); crest factor "
        f"{report.crest_factor:.2f}"
        + (f"; {report.ranges_text()}" if report.ranges is not None else "")
        + "".join(f"; {w}" for w in report.resolution_warnings)
    )
