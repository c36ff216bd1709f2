"""The run service: one path for a calibration run, called the same way by every face (the CLI's
`run`, the GUI's Start, its headless --autorun). A face parses its input into `RunOptions`,
calls, and shows what comes back; it computes nothing of the run itself.

The service loads the stand file once; resolves the DUT, the reference standard (once, with any
override and its reason) and the plan (the stand file's [plan] applied before any phase is
computed); answers the preview with the plan that will run; passes the records' gate (the
chain's quick check) when the records are in use and writes the chain head into the seal;
runs; indexes the finished run through `app.records.db.runs.index_finished_run`, warnings
included; and returns a typed `RunOutcome`. Units: Hz, m/s^2 peak per line, mV/(m/s^2).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass
from datetime import date
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.io.vocabulary import Mode
from app.procedure.errors import PreflightError
from app.procedure.options import RunOptions
from app.procedure.outcome import ExitStatus, RunOutcome, exit_status
from app.procedure.planning import PlanRequest, build_plan, choose_period
from app.procedure.preflight import PreflightReport, check_preflight
from app.procedure.request import (
    DutChoice,
    RequestError,
    ResolvedDut,
    RunRequest,
    resolve_dut,
    resolve_request,
)
from app.procedure.run import (
    execute,
    plan_request,
    request_plan,
    start,
    with_exciter,
    with_stand_plan,
)
from app.stand import config as stand_config
from dsp.estimators import Estimator
from dsp.multisine import PRESETS, Plan, PlanCheck, PlanError, check_played_lines
from dsp.profiles import Profile
from dsp.spectral import check_periods

if TYPE_CHECKING:
    from collections.abc import Sequence

    from app.procedure import Finished, Listener, Procedure
    from app.procedure.batch import MemberChoice, OpenedBatch
    from app.procedure.sweep import Sweep
    from app.stand.config import StandConfig
    from app.stand.dut import DutSpec
    from app.stand.open import Stand

log = logging.getLogger(__name__)

UNIT_LEVEL_MS2 = 1.0  # the phases are optimised at 1 m/s^2 per line: they do not depend on it


@dataclass(frozen=True)
class PlanPreview:
    """The plan that will run, as the Setup tab shows it before Start: `plan` None when it is
    refused (`problems` say why), `report` the preflight on the stand (peaks, crest factor)."""

    plan: Plan | None
    report: PreflightReport | None
    problems: tuple[str, ...]
    warnings: tuple[str, ...]

    @property
    def lines_hz(self) -> tuple[float, ...]:
        """The lines that will be excited (nominal, Hz); () when refused."""
        return tuple(float(f) for f in self.plan.nominal_frequencies_hz) if self.plan else ()

    @property
    def ok(self) -> bool:
        return self.plan is not None and not self.problems


@dataclass(frozen=True)
class BatchOutcome:
    """A run of several DUTs as the faces show it: the batch, each member's outcome in the
    fixture's order, the exit status (the worst member's)."""

    batch_id: str
    folder: Path
    outcomes: tuple[tuple[MemberChoice, RunOutcome], ...]
    exit_status: ExitStatus


@dataclass(frozen=True)
class PreparedRun:
    """A run resolved and gated, not started: the request (a plain value), the stand file as
    loaded once, notes for the operator, and whether the records are in use (then it is
    indexed when it ends)."""

    options: RunOptions
    request: RunRequest
    config: StandConfig
    notes: tuple[str, ...]
    records: bool
    lab: Any = None  # the records already open (the GUI's Lab), else None: by options.db


def check_options(options: RunOptions) -> None:
    """Refuse (RequestError naming the option) combinations no stand may run: periods below
    the estimator's minimum, lpm outside multisine, a profile without its corner."""
    try:
        check_periods(options.estimator, options.periods_to_run)
    except ValueError as exc:
        raise RequestError(f"--{exc}") from None
    if options.estimator == Estimator.LPM and options.mode != "multisine":
        raise RequestError("--estimator lpm: analyses a multisine record; use --mode multisine")
    if options.profile != Profile.ACCELERATION and options.corner_hz is None:
        raise RequestError(f"--profile {options.profile}: needs --corner (Hz)")


def check_instruments_due(config: StandConfig, today: date) -> None:
    """Refuse a run with a stand instrument ([[instrument]]: DAQ, amplifiers, environment
    sensor) overdue for calibration today (PreflightError naming each and its due date)."""
    from app.stand.instruments import overdue

    late = overdue(config.instruments, today)
    if late:
        raise PreflightError(
            f"instrument ({config.source}): {'; '.join(late)}; recalibrate it or correct its "
            "calibration_due in the stand file's [[instrument]] entry"
        )


def records_in_use(options: RunOptions, lab: Any = None) -> bool:
    """Whether a run of `options` uses the records: the records already open (`lab`), else as
    asked (`options.records`), else a sensor named or a records database found (--db,
    $ACCELCAL_DB or the default file: the answer `certificate` uses)."""
    if lab is not None:
        return True
    if options.records is not None:
        return options.records
    from app.records.db.engine import records_url

    return bool(options.sensor) or records_url(options.db) is not None


def records_gate(options: RunOptions, lab: Any = None) -> str | None:
    """The records' gate before a run: the chain's quick check on the records in use (`lab`
    when already open, else options.db). The chain head's hash for the seal; None when the
    records are not in use or cannot be opened (the run says so); ChainBroken when they fail
    the check."""
    if not records_in_use(options, lab):
        return None
    if lab is not None:
        from app.records.db.chain_check import quick_check

        return quick_check(lab.engine)
    from app.records.db.gate import records_quick_check

    return records_quick_check(options.db)


def index_run(folder: Path, *, db: str | None = None, lab: Any = None) -> str:
    """Index a finished run folder into the records (one function for every face:
    app.records.db.runs.index_finished_run); its report, warnings included, never raises."""
    from app.records.db.runs import index_finished_run

    return index_finished_run(folder, db, lab=lab)


class RunService:
    """The run service on one stand: the stand file (None: the simulated stand) loaded once
    when the service is made."""

    def __init__(self, stand_file: Path | None = None, *, config: StandConfig | None = None):
        self.stand_file = stand_file
        self.config: StandConfig = config if config is not None else stand_config.load(stand_file)

    # --- resolving ----------------------------------------------------------------------

    def choice(
        self,
        options: RunOptions,
        *,
        records: bool = False,
        lab: Any = None,
        today: date | None = None,
        operator: str | None = None,
    ) -> DutChoice:
        """How `options` name the DUT and its reference, for app.procedure.request."""
        return DutChoice(
            stand_file=self.stand_file,
            dut=options.dut,
            dut_id=options.dut_id,
            sensor=options.sensor,
            db=options.db,
            records=records,
            teds=options.teds,
            seed=options.seed,
            nominal_mv_per_ms2=options.nominal_mv_per_ms2,
            tolerance_percent=options.tolerance_percent,
            level_ms2=options.level_ms2,
            preset=options.preset,
            dut_mass_g=options.dut_mass_g,
            reference_override=options.reference_override,
            spec=options.dut_spec,
            lab=lab,
            operator=operator,
            today=today,
        )

    def dut_settings(self, spec: DutSpec) -> ResolvedDut:
        """What a DUT of `spec` (a sensor on record, its TEDS) sets for a run on this stand:
        serial, nominal, tolerance, level, preset (a face fills its fields with them)."""
        certificate = self.config.raw.get("certificate") or {}
        return resolve_dut(DutChoice(spec=spec), self.config.backend, certificate)

    def run_fields(self, options: RunOptions) -> RunRequest:
        """The request's run settings from `options` (the DUT and reference come after)."""
        return RunRequest(
            stand_file=self.stand_file,
            frequencies_hz=options.frequencies_hz,
            periods=options.periods_to_run,
            target_type_a=options.target_type_a,
            max_acquisition_s=options.max_acquisition_s,
            estimator=options.estimator,
            mode=options.mode,
            stepped_block_s=options.stepped_block_s,
            paced=options.paced,
            faults=options.faults,
            sim_hum=options.sim_hum,
            exact_mains_bins=options.exact_mains_bins,
            out=options.out,
            stored_response=options.stored_response,
            sample_rate_hz=options.sample_rate_hz,
            period_samples=options.period_samples,
            reference_frequency_hz=options.reference_frequency_hz,
            profile=options.profile,
            corner_hz=options.corner_hz,
            exciter=options.exciter,
            fade_in_s=options.fade_in_s,
            technician=options.technician,
            resonance=options.resonance,
        )

    def draft(self, options: RunOptions, *, stand_plan: bool = True) -> RunRequest:
        """The request `options` describe without the records (DUT resolved from what the
        options carry; the stand file's [plan] applied unless `stand_plan` is False): what the
        preview shows."""
        choice = self.choice(options)
        resolved = resolve_dut(
            choice, self.config.backend, self.config.raw.get("certificate") or {}
        )
        request = dataclasses.replace(
            self.run_fields(options),
            dut=options.dut,
            dut_id=resolved.dut_id,
            preset=resolved.preset,
            level_ms2=resolved.level_ms2,
            tolerance_percent=resolved.tolerance_percent,
            nominal_mv_per_ms2=resolved.nominal_mv_per_ms2,
            seed=options.seed,
            dut_mass_g=options.dut_mass_g,
            dut_spec=resolved.spec,
        )
        return with_stand_plan(request, self.config.plan) if stand_plan else request

    # --- the plan -----------------------------------------------------------------------

    def phase_key(self, options: RunOptions) -> PlanRequest:
        """What the multisine's phases depend on: the lines, rate, period and reference of the
        plan that will run (the stand file's [plan] applied), at 1 m/s^2 flat. A face caches
        `unit_plan(key)` by it (a custom plan not yet in the phase store is optimised once,
        about a second)."""
        wanted = plan_request(self.draft(options), UNIT_LEVEL_MS2)
        return dataclasses.replace(wanted, profile=Profile.ACCELERATION, corner_hz=None)

    def line_check(self, options: RunOptions) -> PlanCheck:
        """The quick checks of the lines that will run (ms, before any phase is optimised):
        every line on a bin below 0.45 fs, no two on one bin, the reference among them, the
        mains and harmonic warnings (dsp.multisine.check_lines)."""
        key = self.phase_key(options)
        preset = PRESETS[key.preset]
        lines = key.frequencies_hz or tuple(preset.nominal_frequencies_hz)
        rate = key.sample_rate_hz or preset.sample_rate_hz
        reference = key.reference_frequency_hz or preset.reference_frequency_hz
        period = key.period_samples
        if period is None and key.frequencies_hz is None and key.sample_rate_hz is None:
            period = preset.period_samples
        elif period is None:
            try:
                period = choose_period(lines, rate, preset.period_samples)
            except PlanError as exc:
                return PlanCheck(exc.problems, ())
        check, _ = check_played_lines(  # the lines as they will be played (make_plan's)
            lines,
            rate,
            period,
            reference,
            mains_frequency_hz=key.mains_frequency_hz,
            shift_mains_lines=key.shift_mains_lines,
        )
        return check

    def preset_keys(self) -> list[PlanRequest]:
        """The phase keys of every preset on this stand (a face optimises them at once)."""
        return [self.phase_key(RunOptions(preset=name)) for name in PRESETS]

    @staticmethod
    def unit_plan(key: PlanRequest) -> Plan:
        """The plan of `key` with its optimised phases (PlanError when refused); slow: call it
        off a GUI thread."""
        return build_plan(key)

    def preview(self, options: RunOptions, unit_plan: Plan | None = None) -> PlanPreview:
        """The plan that will run for `options` and its preflight on this stand, with the
        phases of `unit_plan` (the plan of `phase_key(options)`; None: optimised here)."""
        try:
            request = self.draft(options)
            config = with_exciter(self.config, options.exciter)
            if unit_plan is None:
                unit_plan = self.unit_plan(self.phase_key(options))
            request = dataclasses.replace(request, phases_rad=_phases(unit_plan))
            stroke = config.limits.displacement_peak_to_peak_m if request.custom_plan else None
            plan = request_plan(request, stroke)
        except PlanError as exc:
            return PlanPreview(None, None, exc.problems, ())
        except ValueError as exc:  # a refusal naming the field (DUT, exciter, profile)
            return PlanPreview(None, None, (str(exc),), ())
        try:
            chain = config.reference_chain()
        except stand_config.ConfigError:
            chain = None  # the simulated stand's chain comes with the stand when it opens
        report = check_preflight(
            plan,
            config,
            chain,
            request.nominal_mv_per_ms2,
            per_line=request.mode == Mode.STEPPED_SINE,
            fade_in_s=(request.fade_in_s if request.estimator == Estimator.LPM else plan.period_s),
        )
        return PlanPreview(plan, report, report.problems, tuple(plan.warnings))

    # --- the run ------------------------------------------------------------------------

    def prepare(
        self,
        options: RunOptions,
        *,
        lab: Any = None,
        today: date | None = None,
        operator: str | None = None,
        unit_plan: Plan | None = None,
    ) -> PreparedRun:
        """Resolve and gate a run, not start it: the options checked; with the records in use
        (`lab` already open, else options.db) the chain's quick check (ChainBroken) and the
        reference standard's rule (ReferenceRefusal, overridable with a reason in
        options.reference_override); the DUT resolved; the phases of `unit_plan` when it is
        the plan of these lines (else optimised when the run starts)."""
        check_options(options)
        check_instruments_due(self.config, today or date.today())
        records = records_in_use(options, lab)
        head = records_gate(options, lab)
        choice = self.choice(options, records=records, lab=lab, today=today, operator=operator)
        request, notes = resolve_request(choice, self.config, self.run_fields(options))
        request = with_stand_plan(request, self.config.plan)
        if unit_plan is not None and self._fits(request, unit_plan):
            request = dataclasses.replace(request, phases_rad=_phases(unit_plan))
        request = dataclasses.replace(request, records_chain_head=head)
        return PreparedRun(options, request, self.config, notes, records, lab)

    def start(
        self, prepared: PreparedRun, listener: Listener | None = None
    ) -> tuple[Procedure, Stand]:
        """Open the stand and give the run its folder: the procedure (to `run()` on a worker
        thread) and the stand (to close afterwards)."""
        return start(prepared.request, listener, config=prepared.config)

    def run(self, prepared: PreparedRun, listener: Listener | None = None) -> RunOutcome:
        """Run to the end (signals handled on the main thread) and finish (`finish`)."""
        return self.finish(prepared, execute(prepared.request, listener, config=prepared.config))

    def finish(self, prepared: PreparedRun, finished: Finished) -> RunOutcome:
        """The outcome of a finished run: indexed into the records when they are in use."""
        record = finished.record
        folder = Path(prepared.request.out) / str(record.run_id) if record.run_id else None
        note = None
        if prepared.records and folder is not None:
            note = index_run(folder, db=prepared.options.db, lab=prepared.lab)
        return RunOutcome(
            record=record,
            results=finished.results,
            folder=folder,
            index_note=note,
            exit_status=exit_status(record, fail_exit=prepared.options.fail_exit),
            notes=prepared.notes,
        )

    def run_batch(
        self,
        prepared: PreparedRun,
        members: Sequence[MemberChoice],
        listener: Listener | None = None,
    ) -> BatchOutcome:
        """Several DUTs in one run on the stand's fixture (app.procedure.batch): each member's
        outcome (indexed into the records as that sensor's calibration when they are in use)
        and the batch's exit status (the worst member's)."""
        from app.procedure.batch import execute_batch

        finished = execute_batch(prepared.request, members, listener, config=prepared.config)
        outcomes = tuple((member, self.finish(prepared, one)) for member, one in finished.members)
        status = max((o.exit_status for _, o in outcomes), default=ExitStatus.OK)
        return BatchOutcome(finished.batch_id, finished.folder, outcomes, status)

    def start_batch(
        self,
        prepared: PreparedRun,
        members: Sequence[MemberChoice],
        listener: Listener | None = None,
    ) -> OpenedBatch:
        """Open a batch (app.procedure.batch.open_batch) for a face that runs it on a worker
        thread of its own (the GUI): `procedure.run()`, close the stand, `end(finished)`, then
        `finish` each member's Finished (indexed as in `run_batch`)."""
        from app.procedure.batch import open_batch

        return open_batch(prepared.request, members, listener, config=prepared.config)

    def sweep(
        self, prepared: PreparedRun, levels: list[float], listener: Listener | None = None
    ) -> tuple[Sweep, ExitStatus]:
        """A run per level (app.procedure.sweep) and the sweep's exit status: 3 when a run did
        not complete, 4 with --fail-exit when one's verdict is FAIL, else 0."""
        from app.procedure.sweep import run_sweep

        sweep = run_sweep(prepared.request, levels, listener, config=prepared.config)
        if not sweep.complete:
            return sweep, ExitStatus.ABORTED
        statuses = [exit_status(r.record, fail_exit=prepared.options.fail_exit) for r in sweep.runs]
        return sweep, max(statuses, default=ExitStatus.OK)

    @staticmethod
    def _fits(request: RunRequest, unit_plan: Plan) -> bool:
        """Whether `unit_plan`'s phases are for the lines (Hz) and rate the request will run."""
        wanted = plan_request(request, UNIT_LEVEL_MS2)
        preset = PRESETS[wanted.preset]
        lines = wanted.frequencies_hz or tuple(preset.nominal_frequencies_hz)
        rate = wanted.sample_rate_hz or preset.sample_rate_hz
        have = tuple(line.nominal_frequency_hz for line in unit_plan.lines)
        return have == tuple(lines) and unit_plan.sample_rate_hz == rate


def _phases(plan: Plan) -> tuple[float, ...]:
    return tuple(float(p) for p in plan.phases_rad)


__all__ = [
    "BatchOutcome",
    "PlanPreview",
    "PreflightError",
    "PreparedRun",
    "RunOptions",
    "RunOutcome",
    "RunService",
    "check_options",
    "index_run",
    "records_gate",
    "records_in_use",
]
