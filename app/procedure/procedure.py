"""The calibration procedure (SPEC.md section 5): the phases in order, and every way out.

preflight -> background -> identification -> equalisation -> acquisition -> fade-out (or the
stepped-sine mode after the background), each a small object of its own module sharing one
`RunContext`. This module owns the run's outcome: the drive ends at 0 V and the power
amplifier off on every path out of `run()` (success, abort, exception, lost hardware, a full
disk, Ctrl-C, SIGTERM), the status and the run record.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import sys
from contextlib import nullcontext
from datetime import UTC, datetime
from typing import Any, Protocol

import numpy as np

from app.io.hdf5 import DiskFullError, RecordingWriter, Truth, software_version
from app.io.vocabulary import Mode, RunStatus
from app.procedure.acquisition import Acquisition
from app.procedure.background import Background, budget_with_background
from app.procedure.batch_live import live_members
from app.procedure.context import RunContext, RunNotes
from app.procedure.equalisation import Equalisation, Equalised
from app.procedure.errors import (
    REFUSED_BEFORE,
    Aborted,
    PreflightError,
    ProcedureError,
    RunNotRecordedError,
    advice,
    refused_after,
)
from app.procedure.events import Event, Finished, InputRanges, Listener, State
from app.procedure.identification import Identification
from app.procedure.preflight import PreflightReport, check_preflight
from app.procedure.ranging import RangePlan, run_resolution, with_resolution
from app.procedure.record_run import RecordRun
from app.procedure.request import RunIdentity
from app.procedure.settings import RunSettings
from app.procedure.stand_io import InputRangeOverload, StandIO
from app.procedure.stand_memory import StandMemory
from app.procedure.stepped import SteppedSine
from app.procedure.verdict import Tolerances, tolerances_for, with_verdict
from app.records.run_folder import RunFolder
from app.records.run_record import RunRecord, StandInfo
from app.records.run_start import CONFIG_NAME, BatchLink, RunStart
from app.stand.open import Stand
from app.stand.response import ResponseStore
from dsp.calibration import AnalysisError, ReferenceChain
from dsp.multisine import Plan
from dsp.spectral import RECORD_ESTIMATORS
from dsp.uncertainty import Budget
from hardware.errors import AmplifierFaultError, HardwareError, OverloadError
from hardware.interfaces import DaqConfig, DaqStatus

log = logging.getLogger(__name__)
run_log = logging.getLogger("accelcal.run")  # the lines of run.log, as they are written


def _plain(value: Any) -> dict[str, Any]:
    """A dataclass or mapping as a JSON-ready dict (as results.json has always held it)."""
    if value is None:
        return {}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return json.loads(json.dumps(value.__dict__, default=str))
    return json.loads(json.dumps(dict(value), default=str))


class BatchHooks(Protocol):
    """What a run of several DUTs (app.procedure.batch) adds to the run of its first DUT."""

    def config_stored(self, start: RunStart) -> None:
        """The first DUT's config.json is stored: store the other members' likewise."""

    def open_writers(self, procedure: Procedure) -> None:
        """The recording is open: open the other members' (`procedure.io.member_writers`)."""

    def member_ranges(self, procedure: Procedure, ranges: RangePlan) -> dict[str, float]:
        """Each DUT channel's +-range (V) from its own DUT's predicted peak ("dut": the
        run's own DUT channel's)."""

    def configured(self, procedure: Procedure, status: DaqStatus) -> None:
        """The DAQ is configured (`status`: its skews): each member's own channel delay."""


class Procedure:
    """One calibration run of `plan` on `stand`; call `run()` once."""

    def __init__(
        self,
        stand: Stand,
        plan: Plan,
        settings: RunSettings,
        folder: RunFolder | None = None,
        listener: Listener | None = None,
        *,
        identity: RunIdentity | None = None,
        response_store: ResponseStore | None = None,
        tolerances: Tolerances | None = None,
    ):
        self.stand = stand
        self.plan = plan
        self.settings = settings
        self.folder = folder
        self.listener = listener
        self.identity = identity or RunIdentity()
        self.tolerances = tolerances  # None: the catalogue DUT's the identity names, if any
        self.io = StandIO(stand, plan, settings, self._emit, self._log, self._announce)
        self.notes = RunNotes(budget=stand.budget)
        self.ctx = RunContext(stand, plan, settings, self.io, self.notes, self._emit, self._log)
        self.memory = StandMemory(response_store, stand, plan, settings, self._log)
        self._ranges_text = ""  # the preflight's input ranges, told once the run starts
        self._preflight: PreflightReport | None = None  # computed once (`preflight_report`)
        self.batch_link: BatchLink | None = None  # one DUT of several (config.json "batch")
        self.batch: BatchHooks | None = None  # the other DUTs of the run
        # several DUTs: estimate the others live too, in each PeriodEstimate's `members` (a
        # face that draws them asks for it, the GUI's Run tab; off, the CLI's run costs none)
        self.batch_live = False

    # --- control (thread-safe) ------------------------------------------------------------

    def abort(self, reason: str = "stopped by the operator") -> None:
        """Ask the run to fade out and stop at the next period boundary."""
        self.io.abort(reason)

    def emergency_stop(self) -> None:
        """Zero the drive at once (no fade), from any thread; the run then ends aborted."""
        self.io.emergency_stop()

    # --- the run ---------------------------------------------------------------------------

    def preflight_report(self) -> PreflightReport:
        """The run's preflight (`check_preflight`), computed once per run: `run.prepare` checks
        it before the run folder exists and `run()` uses the same report (issue 34 point 6:
        each computation is a synthesis of the plan's motion and its fades, worker CPU that
        competes with the window for the GIL)."""
        if self._preflight is None:
            self._preflight = self._check_preflight()
        return self._preflight

    def _check_preflight(self) -> PreflightReport:
        return check_preflight(
            self.plan,
            self.stand.config,
            self.stand.chain,
            self.settings.dut_nominal_mv_per_ms2,
            offered_v=self.stand.input_ranges_v,
            per_line=self.settings.mode == Mode.STEPPED_SINE,
            # the lpm's fade-in (None: as the record run picks it), else a period's crossfade
            fade_in_s=(
                self.settings.fade_in_s
                if self.settings.estimator in RECORD_ESTIMATORS
                else self.plan.period_s
            ),
            fade_out_s=self.settings.fade_out_s,
        )

    def preflight(self) -> None:
        """The checks made before anything moves (`preflight_report`); PreflightError says
        what is refused. Logged (run.log) and applied (input ranges, the LPM's fade-in) at
        every call: the first may come before the run has its folder."""
        report = self.preflight_report()
        report.raise_if_refused()
        self._log(report.summary())
        for text in report.resolution_warnings:  # the measured amplitude decides: logged only
            self._log(text)
        self.notes.ranges = report.ranges
        self.notes.fade_in_s = report.fade_in_s
        self._ranges_text = report.ranges_text()
        if report.ranges is not None and self.settings.mode != Mode.STEPPED_SINE:
            ranges = report.ranges.run_ranges  # stepped sine: per line
            if self.batch is not None:  # several DUTs: each DUT channel's own (issue 36)
                ranges = {**ranges, **self.batch.member_ranges(self, report.ranges)}
            self.io.set_ranges(ranges)

    def run(self) -> Finished:
        """The whole run, to its end (complete or aborted): the drive at 0 V afterwards."""
        started = datetime.now(UTC)
        status, reason = RunStatus.COMPLETE, None
        io = self.io
        self._store_config()
        for override in self.identity.overrides:  # in run.log as in results.json
            self._log(f"override: {override.line()}")
        try:
            self.ctx.state(State.PREFLIGHT)
            self.preflight()
            if self._ranges_text:
                self._emit(InputRanges(self._ranges_text))
            self._configure()
            self._phases()
        except Aborted as exc:
            status, reason = RunStatus.ABORTED, str(exc)
            io.try_fade_out()
        except DiskFullError as exc:
            io.recording_full = True
            status, reason = RunStatus.ABORTED, f"disk full: {exc}"
            io.try_fade_out()
        except PreflightError as exc:
            status, reason = RunStatus.ABORTED, f"{REFUSED_BEFORE}{exc}"
            if io.peak_played_v > 0.0:  # a check burst played: the reason says what
                io.try_fade_out()
                reason = f"{refused_after(io.peak_played_v, io.excited_s)}{exc}"
        except (ProcedureError, AnalysisError) as exc:
            status, reason = RunStatus.ABORTED, str(exc)
            io.try_fade_out()
        except HardwareError as exc:
            if io.emergency:
                status, reason = RunStatus.ABORTED, "emergency stop"
            else:
                status, reason = RunStatus.ABORTED, f"{type(exc).__name__}: {exc}. {advice(exc)}"
                if io.power_failed or isinstance(exc, (AmplifierFaultError, OverloadError)):
                    io.try_fade_out()  # the DAQ still works: fade its drive out
        except KeyboardInterrupt:
            status, reason = RunStatus.ABORTED, "interrupted (Ctrl-C)"
        except Exception as exc:
            log.debug("run: internal error", exc_info=True)
            status, reason = RunStatus.ABORTED, f"internal error: {type(exc).__name__}: {exc}"
        finally:
            final_output = io.stop_drive()
            io.disable_power()
            if io.writer is not None:
                escaping = sys.exc_info()[0] is not None  # e.g. SystemExit: not complete
                for writer in (io.writer, *io.member_writers.values()):
                    writer.set_status(RunStatus.ABORTED if escaping else status, reason)
                    writer.close()
        if status == RunStatus.ABORTED:
            self.ctx.state(State.ABORTED, reason or "")
        else:
            self.ctx.state(State.FINISHED)
        return self._finish(started, status, reason, final_output)

    def _phases(self) -> None:
        """Background, then the mode's phases; results end in `self.notes`."""
        background = Background(self.ctx).run()
        if self.settings.mode == Mode.STEPPED_SINE:
            SteppedSine(self.ctx, background, self.memory.recall(), self.memory.describe).run()
            return
        if self.settings.estimator in RECORD_ESTIMATORS:  # lpm: bursts, one record each
            with live_members(self, record=True) or nullcontext() as members:
                RecordRun(self.ctx, background, self.memory, members).run()
            self.io.fade_out()
            return
        equalised = self._equalise(background.noise())
        self.ctx.state(State.ACQUIRING)
        budget = budget_with_background(
            self.stand.budget,
            self.plan,
            background,
            equalised.settled.lines,
            self.settings.background_periods,
            warn=self.ctx.warn,
        )
        budget = self._with_resolution(budget, equalised.settled.lines, background.noise())
        self.notes.budget = budget
        with live_members(self) or nullcontext() as members:
            Acquisition(self.ctx, budget, equalised.reusable_blocks, members).run()
        self.io.fade_out()

    def _equalise(self, noise: np.ndarray) -> Equalised:
        """Equalisation from the stand's stored response when there is one for this stand, DUT
        mass class and plan, checked by its first settled step; a gentle identification first
        when there is none, or when the stored one is off by more than
        `stored_response_tolerance` at any line."""
        equalisation = Equalisation(self.ctx, noise)
        stored = self.memory.recall()
        ranges = self.notes.ranges
        if stored is not None:
            equalised = equalisation.run(
                stored.response, give_up_above=self.settings.stored_response_tolerance
            )
            if equalised is not None:
                self.notes.stand_response = self.memory.describe(
                    stored, "stored", check_error=self.notes.equalisation[0]
                )
                return self._measured(equalised)
            error = self.notes.equalisation[-1]
            self._log(
                f"stand response: the stored one is off by {100 * error:.1f} % at its check "
                f"(> {100 * self.settings.stored_response_tolerance:g} %): re-identifying"
            )
            self.notes.stand_response = self.memory.describe(
                stored, "stored, disagreed: identified", check_error=error
            )
        else:
            self.notes.stand_response = self.memory.describe(None, "identified")
        try:
            response = Identification(self.ctx, noise).run()
            equalised = equalisation.run(response)
        except InputRangeOverload as exc:
            if ranges is None or self.io.ranges == {**self.io.ranges, **ranges.top_v}:
                raise
            # identification plays a fixed voltage whatever the level, and its level step may
            # overshoot: once more, on the stand file's ranges
            text = f"{exc}: identified again on the largest ranges"
            self._log(text)
            self._emit(InputRanges(text))
            self.io.reconfigure(ranges.top_v)
            response = Identification(self.ctx, noise).run()
            equalised = equalisation.run(response)
        assert equalised is not None  # no give_up_above: always an Equalised
        return self._measured(equalised)

    def _with_resolution(
        self, budget: Budget, lines: tuple[np.ndarray, np.ndarray], noise: np.ndarray
    ) -> Budget:
        """The budget with every line's resolution term (app.procedure.ranging) from its settled
        amplitude and the background's noise at the run's ranges; a line too few LSB above
        the converter's step is warned (blocking) and carries none."""
        resolution = run_resolution(
            self.plan,
            (np.abs(lines[0]), np.abs(lines[1])),
            noise,
            self.io.ranges,
            self.stand.config.converter,
        )
        budget, too_few = with_resolution(budget, resolution)
        for text in too_few:
            self.ctx.warn(text)
        if self.io.writer is not None:
            self.io.writer.set_resolution_warnings(too_few)
        return budget

    def _measured(self, equalised: Equalised) -> Equalised:
        """Note the response equalisation converged with, to keep when the run completes."""
        if equalised.converged:
            self.notes.measured_response = equalised.response
            self.notes.measured_response_error = self.notes.equalisation[-1]
        return equalised

    def _store_config(self) -> None:
        """config.json and stand.toml, before anything moves (RunNotRecordedError)."""
        if self.folder is None:
            return
        from app.stand.open import read_environment

        now = datetime.now(UTC).isoformat(timespec="seconds")
        environment = read_environment(self.stand.config, now)  # the sensor's, at run start
        try:
            start = RunStart(
                stand=self.stand.config.raw,
                stand_source=self.stand.config.source,
                plan=self.plan.to_dict(),
                settings=self.settings.__dict__,
                identity=self.identity.to_dict(),
                extra={"environment": environment} if environment is not None else {},
                batch=self.batch_link,
            )
            self.folder.write_text(CONFIG_NAME, start.to_json())
            if self.stand.config.text:
                self.folder.write_text("stand.toml", self.stand.config.text)
            if self.batch is not None:
                self.batch.config_stored(start)
        except OSError as exc:  # nothing has moved yet
            raise RunNotRecordedError(
                f"run {self.folder.run_id} not started, nothing moved: its configuration "
                f"could not be stored in {self.folder.path} ({exc.strerror or exc}); free "
                "disk space"
            ) from exc

    def _finish(
        self, started: datetime, status: RunStatus, reason: str | None, final_output: float | None
    ) -> Finished:
        """Verdict, run record, results.json: the Finished event."""
        results = self.notes.results if status == RunStatus.COMPLETE else None
        if results is not None:
            results = with_verdict(results, self._tolerances())
        if status == RunStatus.COMPLETE and self.notes.measured_response is not None:
            self.memory.keep(
                self.notes.measured_response,
                self.notes.measured_response_error or 0.0,
                self.folder.run_id if self.folder else None,
            )
        record = self._record(started, status, reason, final_output)
        if self.folder is None:
            record = record.with_results(results, None)
        else:
            self._log(f"{status}{': ' + reason if reason else ''}")
            try:
                record = self.folder.finish(record, results)
            except OSError as exc:
                raise RunNotRecordedError(
                    f"run {self.folder.run_id} {status}"
                    f"{' (' + reason + ')' if reason else ''}, drive at "
                    f"{'unknown' if final_output is None else f'{final_output:g} V'}; its "
                    f"results could not be stored ({exc.strerror or exc}): free disk space; "
                    f"the recording in {self.folder.path} is readable up to its last period"
                ) from exc
        finished = Finished(status, reason, results, record)
        self._emit(finished)
        return finished

    def _configure(self) -> None:
        """The DAQ at the plan's rate, the measuring amplifier, the recording."""
        plan = self.plan
        config = DaqConfig(
            plan.sample_rate_hz, plan.period_samples, self.stand.config.output, self.io.inputs
        )
        status = self.stand.daq.configure(config)
        if not math.isclose(status.actual_sample_rate_hz, plan.sample_rate_hz, rel_tol=1e-9):
            raise ProcedureError(
                f"the DAQ runs at {status.actual_sample_rate_hz:g} Hz instead of "
                f"{plan.sample_rate_hz:g} Hz: choose a sample rate the board can divide exactly"
            )
        if self.batch is not None:  # several DUTs: each channel's own delay (issue 36)
            self.batch.configured(self, status)
        amplifier = self.stand.measuring_amplifier
        if amplifier is not None:
            ref = self.stand.config.reference
            settings = amplifier.configure(
                self.stand.config.reference_amplifier_channel,
                sensitivity_mv_per_ms2=1.0,
                gain=ref.gain,
            )
            self.identity = dataclasses.replace(
                self.identity, measuring_amplifier={**settings.__dict__}
            )
            if not math.isclose(settings.gain, self.stand.chain.reference_gain, rel_tol=1e-6):
                raise ProcedureError(
                    f"measuring amplifier reads back gain {settings.gain:g}, the chain assumes "
                    f"{self.stand.chain.reference_gain:g}"
                )
        if self.folder is not None:
            self.io.writer = RecordingWriter(
                self.folder.recording,
                plan,
                self.stand.chain,
                self.stand.budget,
                with_drive=True,
                ranges_v=self.io.ranges,
                cmc=self.stand.config.cmc,
            )
            self._write_truth()
            if self.batch is not None:
                self.batch.open_writers(self)

    def use_chain(self, chain: ReferenceChain) -> None:
        """The run's reference chain from now on (a several-DUT run's first DUT: its own
        channel's skew, known once the DAQ is configured), for every part of the run."""
        stand = dataclasses.replace(self.stand, chain=chain)
        self.stand = self.io.stand = self.ctx.stand = stand

    def _write_truth(self) -> None:
        """The simulated stand's true DUT sensitivity and phase at every line (/truth), at the
        excitation's rms acceleration (the multisine's total, or one line's in stepped sine)."""
        writer = self.io.writer
        if writer is None or self.stand.truth is None:
            return
        plan, truth = self.plan, self.stand.truth
        rms = float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2))
        if self.settings.mode == Mode.STEPPED_SINE:  # one line at a time: its own rms
            values = np.array(
                [
                    truth(np.array([f]), a / np.sqrt(2))[0]
                    for f, a in zip(plan.frequencies_hz, plan.amplitudes_ms2, strict=True)
                ]
            )
        else:
            values = truth(plan.frequencies_hz, rms)
        dut = self.identity.dut
        writer.write_truth(
            Truth(
                plan.frequencies_hz,
                np.abs(values),
                np.degrees(np.angle(values)),
                {
                    "dut": str((dut.catalogue if dut else None) or ""),
                    "description": self.stand.description,
                    "level_ms2": float(self.identity.level_ms2 or 0.0),
                    "rms_ms2": rms,
                },
            )
        )

    def _tolerances(self) -> Tolerances:
        """The tolerances the request's DUT spec gave; else those of the simulated catalogue
        DUT the identity names, with the run's --tolerance."""
        if self.tolerances is not None:
            return self.tolerances
        dut = self.identity.dut
        return tolerances_for(
            dut.catalogue if dut else None,
            self.plan.reference_frequency_hz,
            self.settings.tolerance_percent,
        )

    def _record(
        self, started: datetime, status: RunStatus, reason: str | None, final_output: float | None
    ) -> RunRecord:
        """The run record without results (RunFolder.finish adds them and the raw data's
        hash)."""
        budget = self.notes.budget or self.stand.budget
        identity = self.identity
        config = self.stand.config
        return RunRecord(
            run_id=self.folder.run_id if self.folder else None,
            status=status,
            abort_reason=reason,
            mode=self.settings.mode,
            started_utc=started.isoformat(timespec="seconds"),
            finished_utc=datetime.now(UTC).isoformat(timespec="seconds"),
            excitation_time_s=self.io.excited_s,
            periods_read=self.io.periods_read,
            final_output_v=final_output,
            equalisation_worst=tuple(self.notes.equalisation),
            background_v=dict(self.notes.background),
            budget=tuple(budget.to_list()),
            reference_chain=self.stand.chain.to_dict(),
            software_version=software_version(),
            settings=dict(self.settings.__dict__),
            plan=self.plan.to_dict(),
            stand=StandInfo(
                self.stand.description,
                config.source,
                _plain(config.laboratory),
                _plain(config.reference),
            ),
            dut=identity.dut,
            level_ms2=identity.level_ms2,
            measuring_amplifier=identity.measuring_amplifier,
            stand_response=self.notes.stand_response,
            extra=dict(identity.extra),
            overrides=identity.overrides,
            technician=identity.technician,
        )

    # --- telling -----------------------------------------------------------------------------

    def _announce(self, state: State) -> None:
        self.ctx.state(state)

    def _log(self, line: str) -> None:
        run_log.info("%s", line)  # on stderr with --verbose
        if self.folder is not None:
            try:
                self.folder.log(line)
            except OSError as exc:  # a full disk must not hide what happened to the run
                log.warning("run.log: %s (%s)", line, exc)

    def _emit(self, event: Event) -> None:
        if self.listener is not None:
            self.listener(event)


__all__ = ["Procedure"]
