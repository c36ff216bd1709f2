"""Stepped-sine mode: classic ISO 16063-21, one line at a time."""

from __future__ import annotations

import cmath
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
from app.procedure.stopping import StoppingRule
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
    estimators and results object as the multisine."""

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
                    equalised, estimate = self._line(k, active, noise, responses, start, rule)
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
        ctx.publish(estimate, budget)

    def _line(
        self,
        k: int,
        active: Plan,
        noise: np.ndarray,
        responses: list[tuple[float, complex]],
        start: complex | None,
        rule: StoppingRule,
    ) -> tuple[Equalised, Estimate]:
        """Line k (the one line of `active`) brought to its level and acquired: from `start`
        (a re-ranged line), the stored response, identification (the first line) or the
        response extrapolated from the last lines."""
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
            if rule.decide(count, type_a, io.excited_s - started, active.period_s):
                return equalised, estimate

    def _from_stored(self, k: int, noise: np.ndarray) -> Equalised | None:
        """Line k equalised from the stored response, or None (none, or off by more than
        `stored_response_tolerance` at its check: the caller identifies or extrapolates)."""
        if self.stored is None:
            return None
        ctx = self.ctx
        equalised = Equalisation(ctx, noise).run(
            self.stored.response[[k]], give_up_above=ctx.settings.stored_response_tolerance
        )
        if equalised is None:
            self.disagreed += 1
            ctx.log(
                f"stand response: stored one off by {100 * ctx.notes.equalisation[-1]:.1f} % "
                "at its check: this line from identification or the last lines"
            )
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
