"""The calibration procedure (SPEC.md section 5), UI-agnostic.

preflight -> background (drive at 0 V: hum and noise per line) -> fade-in at a gentle
identification level, settle, the stand's response per line -> closed-loop equalisation
(crossfades between drives, settle on both channels, measure the table acceleration per line on
the reference channel, D_k <- D_k A_target/A_measured) -> acquisition of L periods or until a
type A target or a time bound, with live estimates -> fade-out -> 0 V.

It drives any `hardware.interfaces.Daq` (and amplifiers), emits typed events to a listener,
writes the run folder as it goes, imports nothing from a UI and prints nothing. The drive ends at
0 V on every path out of `run()`: success, abort, exception, lost hardware, Ctrl-C, SIGTERM.
"""

from __future__ import annotations

import cmath
import dataclasses
import logging
import math
import sys
import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from enum import StrEnum
from typing import Any

import numpy as np

from app.recording import DiskFullError, RecordingWriter, Truth, software_version
from app.records import STATUS_ABORTED, STATUS_COMPLETE, RunFolder
from app.stands import Stand
from app.verdict import Tolerances, tolerances_for, with_verdict
from dsp.calibration import AnalysisError, Results, compute_results
from dsp.crestfactor import synthesize
from dsp.hum import mains_hum_from_lines
from dsp.multisine import Line, Plan, fade_envelope
from dsp.sinefit import integer_cycle_block, sine_fit
from dsp.spectral import (
    MIN_PERIODS,
    Estimate,
    SpectralAccumulator,
    check_periods,
    period_spectrum,
    periods_agree,
)
from dsp.uncertainty import Budget, Component, Distribution
from hardware.errors import (
    AmplifierFaultError,
    DeviceLostError,
    HardwareError,
    HardwareTimeoutError,
    OverloadError,
)
from hardware.interfaces import DaqConfig

OVERLOAD_FRACTION = 0.995  # SPEC s.11: a sample within 0.5 % of a channel's range
log = logging.getLogger(__name__)
MODES = ("multisine", "stepped-sine")


class State(StrEnum):
    PREFLIGHT = "preflight"
    BACKGROUND = "background"
    IDENTIFYING = "identifying"
    EQUALISING = "equalising"
    ACQUIRING = "acquiring"
    FADING_OUT = "fading out"
    FINISHED = "finished"
    ABORTED = "aborted"


class ProcedureError(RuntimeError):
    """The run cannot go on; the message says what and what to do."""


class PreflightError(ProcedureError):
    """The plan or level asks for more than the stand may do: refused before anything moves."""


class Aborted(ProcedureError):
    """The run was stopped on request (operator, SIGTERM)."""


class DriveLimitError(ProcedureError):
    """A period of drive would exceed the stand's drive limit: refused, never played."""


class RunNotRecordedError(RuntimeError):
    """The run ended (drive at 0 V) but its status and results could not be stored."""


def limited_drive(period_v: np.ndarray, limit_v: float) -> np.ndarray:
    """The one gate every output period passes on its way to the DAQ (identification,
    equalisation, crossfades, stepped sine, fades, zeros): the period as float volts, or
    DriveLimitError when any |sample| exceeds `limit_v` (V) or is not finite."""
    x = np.asarray(period_v, dtype=float)
    peak = float(np.max(np.abs(x))) if x.size else 0.0
    if not math.isfinite(peak) or peak > limit_v:
        raise DriveLimitError(
            f"drive peak {peak:.4g} V exceeds the stand's drive limit {limit_v:g} V "
            "(limits.drive_peak_v, daq.output.range_v): refused before it was played; lower "
            "the level or the identification drive"
        )
    return x


# --- events ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class StateChanged:
    state: State
    message: str = ""


@dataclass(frozen=True)
class Progress:
    """Overall progress 0..1, the excitation time so far and an estimate of what remains (s)."""

    fraction: float
    elapsed_s: float
    remaining_s: float | None
    message: str = ""


@dataclass(frozen=True)
class PeriodBlock:
    """One period as read (volts, channels in DaqConfig order) and what was played."""

    index: int
    state: State
    channels: tuple[str, ...]
    samples: np.ndarray
    drive: np.ndarray


@dataclass(frozen=True)
class EqualisationStep:
    """Per-line relative amplitude error of the table acceleration after an iteration."""

    iteration: int
    errors: np.ndarray
    worst: float


@dataclass(frozen=True)
class PeriodEstimate:
    """The live estimate after another acquired period."""

    periods: int
    estimate: Estimate
    results: Results


@dataclass(frozen=True)
class WarningRaised:
    text: str


@dataclass(frozen=True)
class Finished:
    status: str
    abort_reason: str | None
    results: Results | None
    record: dict[str, Any]


Event = (
    StateChanged
    | Progress
    | PeriodBlock
    | EqualisationStep
    | PeriodEstimate
    | WarningRaised
    | Finished
)
Listener = Callable[[Event], None]


@dataclass(frozen=True)
class RunSettings:
    """How to run: periods, targets, tolerances and bounds (units in the names)."""

    periods: int = 8
    target_type_a: float | None = None
    max_acquisition_s: float | None = None
    background_periods: int = 2
    fade_periods: int = 1
    settle_tolerance: float = 0.002
    max_settle_periods: int = 12
    equalisation_tolerance: float = 0.01
    max_equalisation_iterations: int = 8
    identification_drive_v: float = 1e-3
    estimator: str = "periodic"
    probability: float = 0.9545
    rule: str = "gum"
    tolerance_percent: float | None = None
    dut_nominal_mv_per_ms2: float | None = None
    plausible_ratio: float = 2.0
    mode: str = "multisine"
    stepped_block_s: float = 0.25

    def __post_init__(self) -> None:
        if self.target_type_a is None:
            check_periods(self.estimator, self.periods)  # issue 13 point 5: MIN_PERIODS
        if self.target_type_a is not None and not 0 < self.target_type_a < 1:
            raise ValueError("target type A: must be a fraction between 0 and 1 (0.002 = 0.2 %)")
        if self.max_acquisition_s is not None and not self.max_acquisition_s > 0:
            raise ValueError("max time: must be > 0 s")
        if not 0 < self.equalisation_tolerance < 0.5:
            raise ValueError("equalisation tolerance: must be between 0 and 0.5")
        if self.mode not in MODES:
            raise ValueError(f"mode: one of {', '.join(MODES)}, got {self.mode!r}")


@dataclass
class _Run:
    """Mutable bookkeeping of one run."""

    periods_read: int = 0
    excited_s: float = 0.0
    warnings: list[str] = field(default_factory=list)
    equalisation: list[float] = field(default_factory=list)
    background: dict[str, list[float]] = field(default_factory=dict)
    results: Results | None = None


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
        identity: dict[str, Any] | None = None,
    ):
        self.stand = stand
        self.plan = plan
        self._active = plan  # what is being played: the plan, or one stepped-sine line
        self._line_index: int | None = None
        self._reusable_blocks: list[np.ndarray] = []
        self._budget_used: Budget = stand.budget
        self._settled_blocks: list[np.ndarray] = []
        self.settings = settings
        self.folder = folder
        self.listener = listener
        self.identity = identity or {}
        self._abort_reason: str | None = None
        self._emergency = False
        self._in_transition = False  # a fade or crossfade period is playing: let it finish
        self._abort_lock = threading.Lock()
        self._writer: RecordingWriter | None = None
        self._drive = np.zeros(plan.period_samples)  # the steady drive (what a fade-out fades)
        self._played = self._drive  # the period the output plays now
        self._queue: deque[np.ndarray] = deque()  # written, not played yet: each plays in turn
        self._run = _Run()
        config = stand.config
        self._inputs = config.inputs
        self._channel_index = {c.name: i for i, c in enumerate(self._inputs)}
        self._ranges = {c.name: c.range_v for c in self._inputs}
        self._drive_limit_v = min(config.limits.drive_peak_v, config.output.range_v)
        self._recording_full = False  # the disk is full: no more periods are appended
        self._power_on = False  # the power amplifier's output was enabled by this run
        self._power_failed = False  # the power amplifier failed: no more polling

    # --- control (thread-safe) ------------------------------------------------------------

    def abort(self, reason: str = "stopped by the operator") -> None:
        """Ask the run to fade out and stop at the next period boundary."""
        with self._abort_lock:
            if self._abort_reason is None:
                self._abort_reason = reason

    def emergency_stop(self) -> None:
        """Zero the drive at once (no fade), from any thread; the run then ends aborted."""
        with self._abort_lock:
            self._emergency = True
            self._abort_reason = "emergency stop"
        try:
            self.stand.daq.stop()
        except Exception:  # the run's own `finally` stops again
            pass

    # --- the run ---------------------------------------------------------------------------

    def run(self) -> Finished:
        started = datetime.now(UTC)
        status, reason = STATUS_COMPLETE, None
        if self.folder is not None:
            try:
                self.folder.write_json(
                    "config.json",
                    {
                        "stand": self.stand.config.raw,
                        "stand_source": self.stand.config.source,
                        "plan": self.plan.to_dict(),
                        "settings": self.settings.__dict__,
                        "identity": self.identity,
                    },
                )
                if self.stand.config.text:
                    self.folder.write_text("stand.toml", self.stand.config.text)
            except OSError as exc:  # nothing has moved yet
                raise RunNotRecordedError(
                    f"run {self.folder.run_id} not started, nothing moved: its configuration "
                    f"could not be stored in {self.folder.path} ({exc.strerror or exc}); free "
                    "disk space"
                ) from exc
        try:
            self._state(State.PREFLIGHT)
            self._preflight()
            self._configure()
            self._background()
            if self.settings.mode == "stepped-sine":
                self._stepped()
            else:
                self._identify()
                self._equalise()
                self._acquire()
                self._fade_out()
        except Aborted as exc:
            status, reason = STATUS_ABORTED, str(exc)
            self._try_fade_out()
        except DiskFullError as exc:
            self._recording_full = True
            status, reason = STATUS_ABORTED, f"disk full: {exc}"
            self._try_fade_out()
        except PreflightError as exc:
            status, reason = STATUS_ABORTED, f"refused before anything moved: {exc}"
        except (ProcedureError, AnalysisError) as exc:
            status, reason = STATUS_ABORTED, str(exc)
            self._try_fade_out()
        except HardwareError as exc:
            if self._emergency:
                status, reason = STATUS_ABORTED, "emergency stop"
            else:
                status, reason = STATUS_ABORTED, f"{type(exc).__name__}: {exc}. {_advice(exc)}"
                if self._power_failed or isinstance(exc, (AmplifierFaultError, OverloadError)):
                    self._try_fade_out()  # the DAQ still works: fade its drive out
        except KeyboardInterrupt:
            status, reason = STATUS_ABORTED, "interrupted (Ctrl-C)"
        except Exception as exc:
            status, reason = STATUS_ABORTED, f"internal error: {type(exc).__name__}: {exc}"
        finally:
            final_output = self._stop_drive()
            self._disable_power()
            if self._writer is not None:
                escaping = sys.exc_info()[0] is not None  # e.g. SystemExit: not complete
                self._writer.set_status(STATUS_ABORTED if escaping else status, reason)
                self._writer.close()
        if status == STATUS_ABORTED:
            self._state(State.ABORTED, reason or "")
        else:
            self._state(State.FINISHED)
        results = self._run.results if status == STATUS_COMPLETE else None
        if results is not None:
            results = with_verdict(results, self._tolerances())
        record = self._record(started, status, reason, final_output)
        if results is not None:
            record["verdict"] = results.verdict
            record["verdict_reasons"] = list(results.verdict_reasons)
        if self.folder is not None:
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

    # --- steps -----------------------------------------------------------------------------

    def preflight(self) -> None:
        """The checks made before anything moves; PreflightError says what is refused."""
        self._preflight()

    def _preflight(self) -> None:
        plan, limits = self.plan, self.stand.config.limits
        peaks = plan.predicted_peaks()
        problems = []
        if peaks.displacement_peak_to_peak_m > limits.displacement_peak_to_peak_m:
            problems.append(
                f"displacement {1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p exceeds the "
                f"exciter's {1e3 * limits.displacement_peak_to_peak_m:g} mm (lower the level at "
                "low frequencies)"
            )
        if peaks.velocity_m_per_s > limits.velocity_peak_m_per_s:
            problems.append(
                f"velocity {peaks.velocity_m_per_s:.3g} m/s exceeds "
                f"{limits.velocity_peak_m_per_s:g} m/s"
            )
        if peaks.acceleration_ms2 > limits.acceleration_peak_ms2:
            problems.append(
                f"acceleration {peaks.acceleration_ms2:.1f} m/s^2 exceeds "
                f"{limits.acceleration_peak_ms2:g} m/s^2"
            )
        ref_s, _ = self.stand.chain.sensitivity_at(plan.frequencies_hz)
        reference_peak = (
            peaks.acceleration_ms2 * float(ref_s.max()) * 1e-3 * self.stand.chain.reference_gain
        )
        if reference_peak > OVERLOAD_FRACTION * self._ranges["reference"] / 1.2:
            problems.append(
                f"reference channel: predicted peak {reference_peak:.3g} V is too close to its "
                f"+-{self._ranges['reference']:g} V range (raise the range or lower the level)"
            )
        nominal = self.settings.dut_nominal_mv_per_ms2
        if nominal is not None:  # the DUT's own response is unknown: its nominal stands in
            dut_peak = peaks.acceleration_ms2 * nominal * 1e-3 * self.stand.chain.dut_gain
            if dut_peak > OVERLOAD_FRACTION * self._ranges["dut"] / 1.2:
                problems.append(
                    f"DUT channel: predicted peak {dut_peak:.3g} V (nominal {nominal:g} "
                    f"mV/(m/s^2)) is too close to its +-{self._ranges['dut']:g} V range "
                    "(raise the range or lower the level)"
                )
        if problems:
            raise PreflightError("; ".join(problems))
        self._log(
            f"preflight: peaks {peaks.acceleration_ms2:.1f} m/s^2, "
            f"{1e3 * peaks.velocity_m_per_s:.1f} mm/s, "
            f"{1e3 * peaks.displacement_peak_to_peak_m:.3f} mm p-p; crest factor "
            f"{plan.crest_factor():.2f}"
        )

    def _configure(self) -> None:
        plan = self.plan
        config = DaqConfig(
            plan.sample_rate_hz, plan.period_samples, self.stand.config.output, self._inputs
        )
        status = self.stand.daq.configure(config)
        if not math.isclose(status.actual_sample_rate_hz, plan.sample_rate_hz, rel_tol=1e-9):
            raise ProcedureError(
                f"the DAQ runs at {status.actual_sample_rate_hz:g} Hz instead of "
                f"{plan.sample_rate_hz:g} Hz: choose a sample rate the board can divide exactly"
            )
        amplifier = self.stand.measuring_amplifier
        if amplifier is not None:
            ref = self.stand.config.reference
            settings = amplifier.configure(
                self.stand.config.reference_amplifier_channel,
                sensitivity_mv_per_ms2=1.0,
                gain=ref.gain,
            )
            self.identity["measuring_amplifier"] = {
                **settings.__dict__,
            }
            if not math.isclose(settings.gain, self.stand.chain.reference_gain, rel_tol=1e-6):
                raise ProcedureError(
                    f"measuring amplifier reads back gain {settings.gain:g}, the chain assumes "
                    f"{self.stand.chain.reference_gain:g}"
                )
        if self.folder is not None:
            self._writer = RecordingWriter(
                self.folder.recording,
                plan,
                self.stand.chain,
                self.stand.budget,
                with_drive=True,
                ranges_v=self._ranges,
            )
            self._write_truth()

    def _write_truth(self) -> None:
        """The simulated stand's true DUT sensitivity and phase at every line (/truth), at the
        excitation's rms acceleration (the multisine's total, or one line's in stepped sine)."""
        if self._writer is None or self.stand.truth is None:
            return
        plan, truth = self.plan, self.stand.truth
        rms = float(np.sqrt(np.sum(plan.amplitudes_ms2**2) / 2))
        if self.settings.mode == "stepped-sine":  # one line at a time: its own rms
            values = np.array(
                [
                    truth(np.array([f]), a / np.sqrt(2))[0]
                    for f, a in zip(plan.frequencies_hz, plan.amplitudes_ms2, strict=True)
                ]
            )
        else:
            values = truth(plan.frequencies_hz, rms)
        dut = self.identity.get("dut") or {}
        self._writer.write_truth(
            Truth(
                plan.frequencies_hz,
                np.abs(values),
                np.degrees(np.angle(values)),
                {
                    "dut": str(dut.get("catalogue") or ""),
                    "description": self.stand.description,
                    "level_ms2": float(self.identity.get("level_ms2") or 0.0),
                    "rms_ms2": rms,
                },
            )
        )

    def _tolerances(self) -> Tolerances:
        """The DUT model's tolerances (simulated catalogue DUT) and the run's --tolerance."""
        dut = self.identity.get("dut") or {}
        return tolerances_for(
            dut.get("catalogue"), self.plan.reference_frequency_hz, self.settings.tolerance_percent
        )

    def _background(self) -> None:
        self._state(State.BACKGROUND, "drive at 0 V: noise and hum at every line")
        zeros = np.zeros(self.plan.period_samples)
        self._start(zeros)
        self._enable_power()
        self._drive = self._played = zeros
        self._queue.clear()
        accumulator = SpectralAccumulator(self.plan.period_samples, self.plan.bins)
        for _ in range(max(1, self.settings.background_periods)):
            _, block = self._period(State.BACKGROUND, return_block=True)
            accumulator.add_period(
                block[self._channel_index["reference"]], block[self._channel_index["dut"]]
            )
        background = accumulator.estimate()
        self._background_v = {
            "reference": background.reference_amplitude_v,
            "dut": background.dut_amplitude_v,
            # per-period noise at each line from the many non-excited bins around it: a
            # well-determined figure even from one or two periods (the settle test's scale)
            "reference_noise": background.reference_noise_v,
            "dut_noise": background.dut_noise_v,
        }
        self._run.background = {k: v.tolist() for k, v in self._background_v.items()}

    def _identify(self) -> None:
        """Fade in at a gentle level, settle, and measure the table's response per line. The
        settle test also guards against a board whose output lags its input by a period: the
        fade itself is never taken for the response."""
        self._state(State.IDENTIFYING, "gentle drive: measuring the stand's response per line")
        plan = self._active
        amplitude = np.full(len(plan.lines), self.settings.identification_drive_v)
        drive = synthesize(plan.bins, amplitude, plan.phases_rad, plan.period_samples)
        self._crossfade(drive, State.IDENTIFYING)
        measured = self._settled_acceleration(State.IDENTIFYING)
        drive_line = amplitude * np.exp(1j * (plan.phases_rad - np.pi / 2))
        self._response = measured / drive_line  # m/s^2 per drive volt, complex, per line
        if np.any(np.abs(self._response) == 0) or not np.all(np.isfinite(self._response)):
            raise ProcedureError(
                "no motion on the reference channel at some lines during identification: check "
                "the power amplifier (enabled, gain) and the reference accelerometer"
            )

    def _equalise(self) -> None:
        self._state(
            State.EQUALISING,
            f"closed loop, tolerance {100 * self.settings.equalisation_tolerance:g} %",
        )
        plan = self._active
        target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
        drive_lines = target / self._response
        limit = min(self.stand.config.limits.drive_peak_v, self.stand.config.output.range_v)
        worst = math.inf
        for iteration in range(1, self.settings.max_equalisation_iterations + 1):
            drive = synthesize(
                plan.bins,
                np.abs(drive_lines),
                np.angle(drive_lines) + np.pi / 2,
                plan.period_samples,
            )
            peak = float(np.max(np.abs(drive)))
            if peak > limit:
                raise PreflightError(
                    f"the level needs a {peak:.2f} V drive peak, over the stand's {limit:g} V "
                    "limit: lower the level or raise the power amplifier's gain"
                )
            self._crossfade(drive)
            measured = self._settled_acceleration()
            self._response = measured / drive_lines  # the stand's response at this level
            errors = np.abs(measured / target) - 1.0
            worst = float(np.max(np.abs(errors)))
            self._run.equalisation.append(worst)
            self._emit(EqualisationStep(iteration, errors, worst))
            self._log(f"equalisation {iteration}: worst line {100 * worst:.2f} %")
            if worst <= self.settings.equalisation_tolerance:
                # settled at the final drive: these two periods are the first acquired ones
                self._reusable_blocks = list(self._settled_blocks)
                return
            drive_lines = drive_lines * target / measured
        self._warn(
            f"equalisation: worst line still {100 * worst:.2f} % off its target after "
            f"{self.settings.max_equalisation_iterations} iterations (the calibration is a ratio "
            "and stays valid; the level is less exact)"
        )

    def _acquire(self) -> None:
        s, plan = self.settings, self.plan
        self._state(State.ACQUIRING)
        accumulator = SpectralAccumulator(plan.period_samples, plan.bins)
        budget = self._budget_with_background()
        self._budget_used = budget
        pending = list(self._reusable_blocks)
        if self._writer is not None:
            self._writer.set_settle_periods(self._run.periods_read - len(pending))
            self._writer.set_budget(budget)
        period_s = plan.period_s
        limit_periods = s.periods if s.target_type_a is None else 10**6
        started = self._run.excited_s
        while True:
            if pending:
                block = pending.pop(0)
            else:
                _, block = self._period(State.ACQUIRING, return_block=True)
            ref, dut = block[self._channel_index["reference"]], block[self._channel_index["dut"]]
            accumulator.add_period(ref, dut)
            count = accumulator.periods
            if self._writer is not None:
                self._writer.set_acquired_periods(count)
            if count < MIN_PERIODS[s.estimator]:  # no honest type A yet (dsp.spectral)
                continue
            estimate = accumulator.estimate(s.estimator)
            results = self._publish(estimate, budget)
            acquired_s = self._run.excited_s - started
            worst_a = float(np.nanmax(estimate.relative_type_a))
            remaining = None if s.target_type_a is not None else (limit_periods - count) * period_s
            self._emit(
                Progress(
                    min(1.0, count / limit_periods)
                    if s.target_type_a is None
                    else min(1.0, (s.target_type_a / worst_a) ** 2),
                    acquired_s,
                    remaining,
                    f"period {count}, worst type A {100 * worst_a:.3f} %",
                )
            )
            if count >= limit_periods:
                return
            if s.target_type_a is not None and worst_a <= s.target_type_a and count >= 3:
                self._log(
                    f"type A target {100 * s.target_type_a:g} % reached after {count} periods"
                )
                return
            if s.max_acquisition_s is not None and acquired_s + period_s > s.max_acquisition_s:
                if s.target_type_a is not None:
                    text = (
                        f"time bound {s.max_acquisition_s:g} s reached before the type A target: "
                        f"worst line {100 * worst_a:.3f} % > {100 * s.target_type_a:g} %"
                    )
                    self._warn(text)
                    self._run.results = dataclasses.replace(
                        results, warnings=(*results.warnings, text)
                    )
                return

    def _stepped(self) -> None:
        """Classic ISO 16063-21 stepped sine: one line at a time in blocks of a whole number of
        cycles (>= `stepped_block_s`), gentle identification, closed-loop level, settle,
        acquisition, fade-out; both channels by three-parameter sine fit. Same estimators and
        results object as the multisine."""
        plan, s = self.plan, self.settings
        fs = plan.sample_rate_hz
        if self._writer is not None:
            self._writer.set_mode("stepped-sine")
        estimates, settled_ref, settled_dut = [], [], []
        responses: list[tuple[float, complex]] = []  # (Hz, m/s^2 per drive volt) per line done
        per_line_bound = (
            None if s.max_acquisition_s is None else s.max_acquisition_s / len(plan.lines)
        )
        for k, line in enumerate(plan.lines):
            n = integer_cycle_block(
                line.frequency_hz, fs, s.stepped_block_s, (plan.mains_frequency_hz,)
            )
            m = round(line.frequency_hz * n / fs)
            one = Line(line.nominal_frequency_hz, line.frequency_hz, m, line.amplitude_ms2, 0.0)
            active = Plan(fs, n, (one,), line.nominal_frequency_hz, plan.mains_frequency_hz, 0)
            self.stand.daq.stop()
            self.stand.daq.configure(DaqConfig(fs, n, self.stand.config.output, self._inputs))
            self._active, self._line_index = active, k
            self._drive = self._played = np.zeros(n)
            self._queue.clear()
            self._start(self._drive)
            self._log(f"stepped sine: line {line.label}, blocks of {n} samples")
            self._reusable_blocks = []
            if k == 0:
                self._identify()
            else:  # the level loop starts from the response extrapolated from the last lines
                self._response = np.array([_extrapolated(responses, line.frequency_hz)])
            self._equalise()
            responses.append((line.frequency_hz, complex(self._response[0])))
            settled_ref.append(self._settled_lines[0][0])
            settled_dut.append(self._settled_lines[1][0])
            accumulator = SpectralAccumulator(n, [m], track_floor=False)
            started = self._run.excited_s
            pending = list(self._reusable_blocks)  # settled at the final drive: reused
            while True:
                if pending:
                    block = pending.pop(0)
                    pair = block[[self._channel_index["reference"], self._channel_index["dut"]]]
                    ref, dut = sine_fit(pair, line.frequency_hz, fs)[:, None]
                else:
                    ref, dut = self._period(State.ACQUIRING)
                accumulator.add_line_spectra(ref[None, :], dut[None, :])
                count = accumulator.periods
                if count < 2:
                    continue
                estimate = accumulator.estimate(s.estimator)
                type_a = float(estimate.relative_type_a[0])
                if s.target_type_a is None and count >= s.periods:
                    break
                if s.target_type_a is not None and type_a <= s.target_type_a and count >= 3:
                    break
                elapsed = self._run.excited_s - started
                if per_line_bound is not None and elapsed + active.period_s > per_line_bound:
                    break
            estimates.append(estimate)
            self._fade_out()
            done = (k + 1) / len(plan.lines)
            self._emit(Progress(done, self._run.excited_s, None, f"line {line.label} done"))
        self._active, self._line_index = plan, None
        combined = _combine(estimates)
        self._settled_lines = (np.array(settled_ref), np.array(settled_dut))
        self._budget_used = self._budget_with_background()
        self._publish(combined, self._budget_used)

    def _publish(self, estimate: Estimate, budget: Budget) -> Results:
        """Results of an estimate over the whole plan: checked, kept and sent to listeners."""
        s = self.settings
        results = compute_results(
            estimate,
            self.plan,
            self.stand.chain,
            budget,
            probability=s.probability,
            rule=s.rule,
            tolerance_percent=s.tolerance_percent,
            extra_warnings=tuple(self._run.warnings),
        )
        self._check_plausible(results)
        self._run.results = results
        self._emit(PeriodEstimate(estimate.periods, estimate, results))
        return results

    def _fade_out(self) -> None:
        """Raised-cosine fade of the steady drive over `fade_periods` periods, then 0 V; reads
        until every faded period has played (a drive queued before it plays first)."""
        self._state(State.FADING_OUT)
        envelope = fade_envelope(self._active.period_samples, self.settings.fade_periods, "out")
        n = self._active.period_samples
        for k in range(self.settings.fade_periods):
            self._write(self._drive * envelope[k * n : (k + 1) * n])
        self._drive = np.zeros(n)
        self._write(self._drive)
        self._in_transition = True
        try:
            while len(self._queue) > 1:  # the zero period stays queued; stop() plays it
                self._period(State.FADING_OUT)
        finally:
            self._in_transition = False

    # --- helpers ---------------------------------------------------------------------------

    def _crossfade(self, new_drive: np.ndarray, state: State = State.EQUALISING) -> None:
        """One period moving smoothly from the current drive to `new_drive`, which then plays.
        An abort meanwhile lets the crossfade play, then fades out from `new_drive`: the drive
        never steps at a period boundary."""
        ramp = fade_envelope(self._active.period_samples, 1, "in")
        self._write(self._drive * (1.0 - ramp) + new_drive * ramp)
        self._in_transition = True
        try:
            self._period(state)
        except BaseException:
            # the crossfade is written (played or queued): a fade-out starts where it ends
            self._drive = new_drive
            raise
        finally:
            self._in_transition = False
        self._drive = new_drive
        self._write(new_drive)

    def _settled_acceleration(self, state: State = State.EQUALISING) -> np.ndarray:
        """Read periods until two consecutive ones agree at every line on both channels (the
        DUT can carry a transient of its own, e.g. a piezo's 0.5 Hz high-pass); the table
        acceleration per line (complex, m/s^2) from the reference channel, averaged over the
        two. Agreement: within `settle_tolerance` of the line or 6 noise standard deviations."""
        s = self.settings
        noise = np.array([self._background_v["reference_noise"], self._background_v["dut_noise"]])
        if self._line_index is not None:  # one line, a shorter block: more noise per bin
            scale = np.sqrt(self.plan.period_samples / self._active.period_samples)
            noise = noise[:, [self._line_index]] * scale
        previous = previous_block = None
        for _ in range(s.max_settle_periods):
            (ref, dut), block = self._period(state, return_block=True)
            lines = np.array([ref, dut])
            if previous is not None and periods_agree(previous, lines, noise, s.settle_tolerance):
                self._settled_lines = (ref, dut)
                self._settled_blocks = [previous_block, block]
                return self._to_acceleration((ref + previous[0]) / 2)
            previous, previous_block = lines, block
        raise ProcedureError(
            f"the table did not settle within {s.max_settle_periods} periods (consecutive "
            "periods still differ): check for a loose mount, a resonance or an unstable amplifier"
        )

    def _to_acceleration(self, reference_lines: np.ndarray) -> np.ndarray:
        chain = self.stand.chain
        magnitude, phase = chain.sensitivity_at(self._active.frequencies_hz)
        volts_per_ms2 = magnitude * 1e-3 * chain.reference_gain * np.exp(1j * np.radians(phase))
        return reference_lines / volts_per_ms2

    def _write(self, drive: np.ndarray) -> None:
        """Queue one period of drive: it plays after those written before it (Daq protocol)."""
        self.stand.daq.write_period(limited_drive(drive, self._drive_limit_v))
        self._queue.append(drive)

    def _start(self, drive: np.ndarray) -> None:
        """Start the DAQ output with `drive` (through the same drive-limit gate)."""
        self.stand.daq.start(limited_drive(drive, self._drive_limit_v))

    def _enable_power(self) -> None:
        """Switch the power amplifier's output on (the DAQ already plays 0 V); it refuses
        while its interlock is open or it reports a fault (AmplifierFaultError)."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or self._power_on:
            return
        self._power_on = True  # from here, every exit path switches it off
        amplifier.set_output_enabled(True)
        self._log("power amplifier: output on")

    def _poll_power(self) -> None:
        """The power amplifier's fault and interlock state, once per period: an over-current,
        an open interlock (over-travel) or a lost session ends the run (HardwareError)."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or not self._power_on or self._power_failed:
            return
        try:
            fault = amplifier.fault()
            if fault is not None:
                raise AmplifierFaultError(f"power amplifier reports a fault: {fault}")
            if not amplifier.interlock_closed():
                raise AmplifierFaultError(
                    "power amplifier interlock open (exciter over-travel or cover open)"
                )
        except HardwareError:
            self._power_failed = True
            raise

    def _disable_power(self) -> None:
        """Switch the power amplifier's output off after the drive is at 0 V (every exit
        path); a failure is logged, never raised over the run's own outcome."""
        amplifier = self.stand.power_amplifier
        if amplifier is None or not self._power_on:
            return
        try:
            amplifier.set_output_enabled(False)
            self._power_on = False
            self._log("power amplifier: output off")
        except Exception as exc:
            log.error("power amplifier: output could not be switched off: %s", exc)
            self._log(f"power amplifier: output could not be switched off: {exc}")

    def _period(self, state: State, *, return_block: bool = False) -> Any:
        """Read one period, check it, record it; line spectra of (reference, DUT)."""
        with self._abort_lock:
            reason = self._abort_reason
        if reason is not None and (self._emergency or not self._in_transition):
            raise Aborted(reason)  # a fade or crossfade already written plays to its end
        active = self._active
        block = self.stand.daq.read_period(timeout_s=active.period_s * 2 + 5.0)
        if self._queue:
            self._played = self._queue.popleft()
        played = self._played
        self._run.periods_read += 1
        if np.any(played != 0):
            self._run.excited_s += active.period_s
        self._poll_power()  # first: a tripped amplifier explains what the channels show
        self._check_block(block)
        if self._writer is not None and not self._recording_full:
            drive = (
                block[self._channel_index["drive"]] if "drive" in self._channel_index else played
            )
            self._writer.append(
                block[self._channel_index["reference"]], block[self._channel_index["dut"]], drive
            )
        amplifier = self.stand.measuring_amplifier
        if amplifier is not None and amplifier.overloaded(
            self.stand.config.reference_amplifier_channel
        ):
            raise OverloadError(
                "measuring amplifier reports an overload on the reference channel",
                channel="reference",
            )
        self._emit(
            PeriodBlock(self._run.periods_read, state, tuple(self._channel_index), block, played)
        )
        pair = block[[self._channel_index["reference"], self._channel_index["dut"]]]
        if self._line_index is None:
            lines = period_spectrum(pair)[:, active.bins]
        else:  # stepped sine: IEEE 1057 three-parameter fit of both channels
            lines = sine_fit(pair, active.frequencies_hz[0], active.sample_rate_hz)[:, None]
        if return_block:
            return (lines[0], lines[1]), block
        return lines[0], lines[1]

    def _check_block(self, block: np.ndarray) -> None:
        for name, index in self._channel_index.items():
            x = block[index]
            if not np.all(np.isfinite(x)):
                raise ProcedureError(
                    f"{name} channel: NaN or inf samples from the DAQ; check the driver and cabling"
                )
            if name == "drive":
                continue
            limit = OVERLOAD_FRACTION * self._ranges[name]
            over = int(np.count_nonzero(np.abs(x) >= limit))
            if over:
                raise OverloadError(
                    f"{name} channel: {over} sample(s) at its +-{self._ranges[name]:g} V range "
                    "limit",
                    channel=name,
                )

    def _check_plausible(self, results: Results) -> None:
        nominal = self.settings.dut_nominal_mv_per_ms2
        if nominal is None:
            return
        measured = results.reference.sensitivity_mv_per_ms2
        ratio = measured / nominal
        if not 1 / self.settings.plausible_ratio <= ratio <= self.settings.plausible_ratio:
            raise ProcedureError(
                f"implausible DUT sensitivity {measured:.4g} mV/(m/s^2) against its nominal "
                f"{nominal:g}: channels swapped, wrong DUT channel gain, or wrong DUT"
            )

    def _budget_with_background(self) -> Budget:
        """The stand's budget plus, per line, the background found with the drive at 0 V (hum,
        which a periodic average does not remove) relative to the settled line (SPEC s.5 step
        2): at a line on a mains harmonic the "mains hum at X Hz" components of dsp.hum
        (U-shaped, magnitude and phase; issue 13 point 3), elsewhere a rectangular bound on the
        background's bias, left out when negligible (< 1e-4)."""
        components = list(self.stand.budget.components)
        ref_lines, dut_lines = self._settled_lines
        hum = mains_hum_from_lines(
            self.plan,
            self._background_v["reference"],
            self._background_v["dut"],
            ref_lines,
            dut_lines,
            max(1, self.settings.background_periods),
        )
        components.extend(hum.components())
        with np.errstate(divide="ignore", invalid="ignore"):
            bound = self._background_v["reference"] / np.abs(ref_lines) + self._background_v[
                "dut"
            ] / np.abs(dut_lines)
        for f, b, on_mains in zip(self.plan.frequencies_hz, bound, hum.affected, strict=True):
            if not on_mains and np.isfinite(b) and b >= 1e-4:
                components.append(
                    Component(
                        f"background (hum, noise) at {f:g} Hz",
                        float(b),
                        Distribution.RECTANGULAR,
                        min_frequency_hz=float(f),
                        max_frequency_hz=float(f),
                        note="measured with the drive at 0 V",
                    )
                )
        return Budget(tuple(components))

    def _try_fade_out(self) -> None:
        if self._emergency:
            return
        try:
            if np.any(self._drive != 0):
                self._fade_out()
        except Exception:
            pass

    def _stop_drive(self) -> float | None:
        """Stop with the output at 0 V, whatever happened; the output voltage as reported."""
        try:
            self.stand.daq.stop()
        except DeviceLostError:
            pass  # a lost device has reset its output
        return self.stand.daq.output_v

    def _record(
        self, started: datetime, status: str, reason: str | None, final_output: float | None
    ) -> dict[str, Any]:
        return {
            "run_id": self.folder.run_id if self.folder else None,
            "status": status,
            "abort_reason": reason,
            "mode": self.settings.mode,
            "started_utc": started.isoformat(timespec="seconds"),
            "finished_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            "excitation_time_s": self._run.excited_s,
            "periods_read": self._run.periods_read,
            "final_output_v": final_output,
            "equalisation_worst": self._run.equalisation,
            "background_v": self._run.background,
            "budget": self._budget_used.to_list(),
            "reference_chain": self.stand.chain.to_dict(),
            "software_version": software_version(),
            "settings": self.settings.__dict__,
            "plan": self.plan.to_dict(),
            "stand": {
                "description": self.stand.description,
                "source": self.stand.config.source,
                "laboratory": self.stand.config.laboratory,
                "reference": self.stand.config.reference.__dict__,
            },
            **self.identity,
        }

    def _state(self, state: State, message: str = "") -> None:
        self._log(f"state: {state}{' - ' + message if message else ''}")
        self._emit(StateChanged(state, message))

    def _warn(self, text: str) -> None:
        self._run.warnings.append(text)
        self._log(f"warning: {text}")
        self._emit(WarningRaised(text))

    def _log(self, line: str) -> None:
        if self.folder is not None:
            try:
                self.folder.log(line)
            except OSError as exc:  # a full disk must not hide what happened to the run
                log.warning("run.log: %s (%s)", line, exc)

    def _emit(self, event: Event) -> None:
        if self.listener is not None:
            self.listener(event)


MAX_EXTRAPOLATED_CHANGE = 2.0  # the predicted response stays within x2 of the last line's


def _extrapolated(responses: list[tuple[float, complex]], frequency_hz: float) -> complex:
    """The stand's response (drive to table acceleration) at `frequency_hz`, extrapolated in
    log-log magnitude and in phase from the last two lines measured (the last one alone if
    only one), its change bounded to `MAX_EXTRAPOLATED_CHANGE` in magnitude: a guess the
    closed loop then corrects, so one level step per line is often enough."""
    f1, r1 = responses[-1]
    if len(responses) < 2:
        return r1
    f2, r2 = responses[-2]
    exponent = math.log(frequency_hz / f1) / math.log(f1 / f2)
    ratio = r1 / r2
    gain = min(max(abs(ratio) ** exponent, 1 / MAX_EXTRAPOLATED_CHANGE), MAX_EXTRAPOLATED_CHANGE)
    return r1 * gain * cmath.exp(1j * exponent * cmath.phase(ratio))


def _combine(estimates: list[Estimate]) -> Estimate:
    """One estimate from per-line ones (stepped sine): arrays concatenated, dof per line."""

    def cat(name: str) -> np.ndarray:
        return np.concatenate([np.atleast_1d(getattr(e, name)) for e in estimates])

    return Estimate(
        estimator=estimates[0].estimator,
        periods=min(e.periods for e in estimates),
        response=cat("response"),
        relative_type_a=cat("relative_type_a"),
        phase_type_a_rad=cat("phase_type_a_rad"),
        dof=np.array([e.dof for e in estimates]),
        coherence=cat("coherence"),
        reference_amplitude_v=cat("reference_amplitude_v"),
        dut_amplitude_v=cat("dut_amplitude_v"),
        reference_noise_v=cat("reference_noise_v"),
        dut_noise_v=cat("dut_noise_v"),
        reference_distortion=cat("reference_distortion"),
        dut_distortion=cat("dut_distortion"),
    )


def _advice(exc: HardwareError) -> str:
    """What the operator should do about a hardware error."""
    if isinstance(exc, OverloadError):
        return "Lower the level or raise the channel's range, then run again"
    if isinstance(exc, AmplifierFaultError):
        return (
            "Check the power amplifier (interlock, temperature, over-travel), reset it, run again"
        )
    if isinstance(exc, DeviceLostError):
        return "Reconnect the device (cable, power), then run again; the data so far is kept"
    if isinstance(exc, HardwareTimeoutError):
        return "Check that the instrument is on, connected and configured; then run again"
    return "Check the hardware, then run again"


__all__ = [
    "Aborted",
    "DriveLimitError",
    "EqualisationStep",
    "Finished",
    "PeriodBlock",
    "PeriodEstimate",
    "PreflightError",
    "Procedure",
    "ProcedureError",
    "Progress",
    "RunNotRecordedError",
    "RunSettings",
    "State",
    "StateChanged",
    "WarningRaised",
    "limited_drive",
]
