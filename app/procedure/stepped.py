"""Stepped-sine mode: classic ISO 16063-21, one line at a time."""

from __future__ import annotations

import cmath
import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from app.io.vocabulary import Mode
from app.procedure.background import BackgroundLevels, budget_with_background
from app.procedure.context import RunContext
from app.procedure.equalisation import Equalisation, Equalised
from app.procedure.events import InputRanges, Progress, State
from app.procedure.identification import Identification
from app.procedure.ranging import measured_resolution, with_resolution
from app.procedure.stand_io import InputRangeOverload, Segment
from app.procedure.stopping import StoppingRule, target_not_met
from app.stand.response import StoredResponse
from dsp.multisine import Line, Plan
from dsp.sinefit import integer_cycle_block, sine_fit
from dsp.spectral import Estimate, SpectralAccumulator
from hardware.interfaces import DaqConfig

MAX_EXTRAPOLATED_CHANGE = 2.0  # the predicted response stays within x2 of the last line's
MIN_LINE_PERIODS = 2  # blocks per line before an estimate is made


class SteppedSine:
    """One line at a time in blocks of a whole number of cycles (>= `stepped_block_s`, whole
    mains cycles too): identification (first line) or the response extrapolated from the last
    lines, closed-loop level, settle, acquisition by the run's `StoppingRule` (its time bound
    shared out among the lines), fade-out; both channels by three-parameter sine fit. Same
    estimators and results object as the multisine.

    From a stored response (warm), the first line plays it at CHECK_LEVEL first and checks it
    (app.procedure.equalisation); once a line has agreed with its stored response, the next
    line starts from its own stored response times the ratio the last line measured to its
    stored one, at the level (its drive checked against the limits through that response, as
    every drive), and its first level step is its check: a warm line costs a crossfade and
    two settled blocks, as a cold line extrapolated in one step does, and no identification.
    A line off by more than the tolerance at that step counts as disagreed, and the next line
    is checked at CHECK_LEVEL again."""

    def __init__(
        self,
        ctx: RunContext,
        background: BackgroundLevels,
        stored: StoredResponse | None = None,
        describe: Callable[..., dict[str, Any]] | None = None,
    ):
        self.ctx = ctx
        self.background = background
        self.stored = stored  # the stand's stored response per line (this mode), if any
        self.describe = describe  # StandMemory.describe: the run record's note
        self.disagreed = 0  # lines whose stored response failed its check
        # measured / stored response at the last line that agreed with its stored response
        # (None: no line has yet; the next line from the store is checked at CHECK_LEVEL)
        self.agreed: complex | None = None

    def run(self) -> None:
        ctx, plan, s, io = self.ctx, self.ctx.plan, self.ctx.settings, self.ctx.io
        fs = plan.sample_rate_hz
        if io.writer is not None:
            io.writer.set_mode(Mode.STEPPED_SINE)
        estimates: list[Estimate] = []
        settled_ref: list[complex] = []
        settled_dut: list[complex] = []
        responses: list[tuple[float, complex]] = []  # (Hz, m/s^2 per drive volt) per line done
        per_line_bound = (
            None if s.max_acquisition_s is None else s.max_acquisition_s / len(plan.lines)
        )
        rule = StoppingRule(s.periods, s.target_type_a, per_line_bound)
        converged, worst_final = True, 0.0
        ranges = ctx.notes.ranges
        line_ranges: list[tuple[float, float]] = []  # (reference, DUT) +-V per line
        block_samples: list[int] = []
        acquired: list[tuple[float, int]] = []  # (s, blocks) each line's acquisition took
        dut_per_reference: float | None = None  # amplitude ratio (V/V) the last line measured
        for k, line in enumerate(plan.lines):
            n = integer_cycle_block(
                line.frequency_hz, fs, s.stepped_block_s, (plan.mains_frequency_hz,)
            )
            m = round(line.frequency_hz * n / fs)
            one = Line(line.nominal_frequency_hz, line.frequency_hz, m, line.amplitude_ms2, 0.0)
            active = Plan(fs, n, (one,), line.nominal_frequency_hz, plan.mains_frequency_hz, 0)
            # one line in a shorter block: more noise per bin than the plan's period
            noise = self.background.noise()[:, [k]] * np.sqrt(plan.period_samples / n)
            wanted: dict[str, float] | None = None
            if ranges is not None:  # this line's own input ranges (app.procedure.ranging)
                if k == 0:  # identification may play here: a fixed voltage, the top ranges
                    wanted = dict(ranges.top_v)
                elif dut_per_reference is None:
                    wanted = ranges.ranges_at(k)
                else:
                    wanted = ranges.from_ratio(k, dut_per_reference)
            start: complex | None = None  # the response a re-ranged line starts from
            overloaded = False  # once a range overloaded, this line stays on the largest
            while True:
                ctx.stand.daq.stop()
                if wanted is not None:
                    io.set_ranges(wanted)
                ctx.stand.daq.configure(DaqConfig(fs, n, ctx.stand.config.output, io.inputs))
                io.begin(Segment(active, one_line=True))
                ctx.log(
                    f"stepped sine: line {line.label}, blocks of {n} samples, ranges reference "
                    f"+-{io.ranges['reference']:g} V, DUT +-{io.ranges['dut']:g} V"
                )
                try:
                    equalised, estimate, took_s = self._line(
                        k, active, noise, responses, start, rule
                    )
                except InputRangeOverload as exc:
                    if ranges is None or overloaded or io.ranges == {**io.ranges, **ranges.top_v}:
                        raise
                    overloaded = True
                    # the level loop's first step overshot a range picked from a prediction:
                    # the line again on the stand file's ranges, re-ranged from what it measures
                    io.set_ranges(ranges.top_v)  # the check follows; the DAQ clipped below it
                    io.fade_out()
                    text = f"line {line.label}: {exc}: measured again on the largest ranges"
                    ctx.log(f"stepped sine: {text}")
                    ctx.emit(InputRanges(text))
                    wanted, start = dict(ranges.top_v), None
                    continue
                smaller = (
                    None
                    if ranges is None or start is not None or overloaded  # once at most
                    else ranges.re_ranged(
                        {
                            "reference": float(estimate.reference_amplitude_v[0]),
                            "dut": float(estimate.dut_amplitude_v[0]),
                        },
                        {"reference": io.ranges["reference"], "dut": io.ranges["dut"]},
                    )
                )
                if smaller is None:
                    break
                text = (
                    f"line {line.label} re-ranged to reference +-{smaller['reference']:g} V, "
                    f"DUT +-{smaller['dut']:g} V from its measured amplitudes (the converter's "
                    "resolution): measured again"
                )
                ctx.log(f"stepped sine: {text}")
                ctx.emit(InputRanges(text))
                io.fade_out()
                wanted, start = smaller, complex(equalised.response[0])
            line_ranges.append((io.ranges["reference"], io.ranges["dut"]))
            block_samples.append(n)
            acquired.append((took_s, estimate.periods))
            if estimate.reference_amplitude_v[0] > 0:
                dut_per_reference = float(
                    estimate.dut_amplitude_v[0] / estimate.reference_amplitude_v[0]
                )
            responses.append((line.frequency_hz, complex(equalised.response[0])))
            converged = converged and equalised.converged
            worst_final = max(worst_final, ctx.notes.equalisation[-1])
            settled_ref.append(equalised.settled.lines[0][0])
            settled_dut.append(equalised.settled.lines[1][0])
            estimates.append(estimate)
            io.fade_out()
            done = (k + 1) / len(plan.lines)
            ctx.emit(Progress(done, io.excited_s, None, f"line {line.label} done"))
        io.segment = Segment(plan)
        if converged:
            ctx.notes.measured_response = np.array([r for _, r in responses])
            ctx.notes.measured_response_error = worst_final
        if self.describe is not None:
            outcome = "identified" if self.stored is None else "stored"
            if self.disagreed:
                outcome = f"stored, disagreed at {self.disagreed} lines: identified there"
            ctx.notes.stand_response = self.describe(self.stored, outcome)
        settled = (np.array(settled_ref), np.array(settled_dut))
        budget = budget_with_background(
            ctx.stand.budget, plan, self.background, settled, s.background_periods, warn=ctx.warn
        )
        estimate = combine(estimates)
        resolution = measured_resolution(
            plan.frequencies_hz,
            (estimate.reference_amplitude_v, estimate.dut_amplitude_v),
            (estimate.reference_noise_v, estimate.dut_noise_v),
            block_samples,
            ([r for r, _ in line_ranges], [d for _, d in line_ranges]),
            ctx.stand.config.converter,
        )
        budget, too_few = with_resolution(budget, resolution)
        for text in too_few:
            ctx.warn(text)
        ctx.notes.budget = budget
        if ctx.io.writer is not None:
            ctx.io.writer.set_resolution_warnings(too_few)
        self._report_target(rule, estimate, acquired)
        ctx.publish(estimate, budget)

    def _report_target(
        self, rule: StoppingRule, estimate: Estimate, acquired: list[tuple[float, int]]
    ) -> None:
        """Lines the per-line time bound stopped above the type A target: the run's report
        (app.procedure.stopping.TargetNotMet, with the acquisition of the worst line)."""
        type_a = np.asarray(estimate.relative_type_a, dtype=float)
        if not np.any(np.isfinite(type_a)):
            return
        worst = int(np.nanargmax(type_a))
        report = target_not_met(
            rule,
            default_bound=self.ctx.settings.max_acquisition_default,
            acquired_s=acquired[worst][0],
            periods=acquired[worst][1],
            labels=[line.label for line in self.ctx.plan.lines],
            type_a=type_a.tolist(),
        )
        if report is not None:
            self.ctx.warn(dataclasses.replace(report, per_line=True).text())

    def _line(
        self,
        k: int,
        active: Plan,
        noise: np.ndarray,
        responses: list[tuple[float, complex]],
        start: complex | None,
        rule: StoppingRule,
    ) -> tuple[Equalised, Estimate, float]:
        """Line k (the one line of `active`) brought to its level and acquired: from `start`
        (a re-ranged line), the stored response, identification (the first line) or the
        response extrapolated from the last lines; with the acquisition's excitation (s)."""
        ctx, s, io = self.ctx, self.ctx.settings, self.ctx.io
        line = active.lines[0]
        fs, n = active.sample_rate_hz, active.period_samples
        equalised = None if start is not None else self._from_stored(k, noise)
        if equalised is None:
            if start is not None:
                response = np.array([start])
            elif not responses:
                response = Identification(ctx, noise).run()
            else:  # the level loop starts from the response extrapolated from the last lines
                response = np.array([extrapolated(responses, line.frequency_hz)])
            equalised = Equalisation(ctx, noise).run(response)
            assert equalised is not None  # no give_up_above: always an Equalised
        accumulator = SpectralAccumulator(n, list(active.bins), track_floor=False)
        started = io.excited_s
        pending = equalised.reusable_blocks  # settled at the final drive: reused
        while True:
            if pending:
                ref, dut = sine_fit(io.pair(pending.pop(0)), line.frequency_hz, fs)[:, None]
            else:
                ref, dut = io.period(State.ACQUIRING)
            accumulator.add_line_spectra(ref[None, :], dut[None, :])
            count = accumulator.periods
            if count < MIN_LINE_PERIODS:
                continue
            estimate = accumulator.estimate(s.estimator)
            type_a = float(estimate.relative_type_a[0])
            took_s = io.excited_s - started
            if rule.decide(count, type_a, took_s, active.period_s):
                return equalised, estimate, took_s

    def _from_stored(self, k: int, noise: np.ndarray) -> Equalised | None:
        """Line k equalised from the stored response, or None (none, or off by more than
        `stored_response_tolerance` at its check: the caller identifies or extrapolates).
        After a line that agreed with its stored response, at the level at once (the class's
        docstring); else checked at CHECK_LEVEL first."""
        if self.stored is None:
            return None
        ctx = self.ctx
        tolerance = ctx.settings.stored_response_tolerance
        stored = complex(self.stored.response[k])
        if self.agreed is not None:  # the stand as stored at the last line: no check burst
            steps = len(ctx.notes.equalisation)
            equalised = Equalisation(ctx, noise).run(np.array([stored * self.agreed]))
            assert equalised is not None  # no give_up_above: always an Equalised
            first_error = ctx.notes.equalisation[steps]  # the first level step: the check
            if first_error > tolerance:
                self.disagreed += 1
                self.agreed = None
                ctx.log(
                    f"stand response: stored one off by {100 * first_error:.1f} % at the "
                    "first level step: the next line is checked at the reduced level"
                )
            else:
                self.agreed = complex(equalised.response[0]) / stored
            return equalised
        equalised = Equalisation(ctx, noise).run(self.stored.response[[k]], give_up_above=tolerance)
        if equalised is None:
            self.disagreed += 1
            ctx.log(
                f"stand response: stored one off by {100 * ctx.notes.equalisation[-1]:.1f} % "
                "at its check: this line from identification or the last lines"
            )
            return None
        self.agreed = complex(equalised.response[0]) / stored
        return equalised


def extrapolated(responses: list[tuple[float, complex]], frequency_hz: float) -> complex:
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


def combine(estimates: list[Estimate]) -> Estimate:
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
