"""Acquisition phase (multisine): L periods, or until a type A target within a time bound,
with a live estimate after every period."""

from __future__ import annotations

import dataclasses

import numpy as np

from app.procedure.batch_live import LiveMembers
from app.procedure.context import RunContext
from app.procedure.events import Progress, State
from app.procedure.stopping import Stop, StoppingRule, target_not_met
from dsp.calibration import Results
from dsp.hum import driven_hum
from dsp.lpm_record import hum_bins
from dsp.spectral import MIN_PERIODS, Estimate, SpectralAccumulator
from dsp.uncertainty import Budget


class Acquisition:
    """Accumulate the multisine's periods (first the ones settled at the final drive), publish
    results from MIN_PERIODS on, stop by the run's `StoppingRule`."""

    def __init__(
        self,
        ctx: RunContext,
        budget: Budget,
        reusable_blocks: list[np.ndarray],
        members: LiveMembers | None = None,
    ):
        self.ctx = ctx
        self.budget = budget
        self.pending = list(reusable_blocks)
        self.members = members  # a run of several DUTs: the others' live estimates

    def run(self) -> None:
        ctx, s, plan = self.ctx, self.ctx.settings, self.ctx.plan
        io = ctx.io
        accumulator = SpectralAccumulator(
            plan.period_samples, plan.bins, nonlinear_excluded_bins=hum_bins(plan)
        )
        if io.writer is not None:
            io.writer.set_settle_periods(io.periods_read - len(self.pending))
            io.writer.set_budget(self.budget)
        rule = StoppingRule(s.periods, s.target_type_a, s.max_acquisition_s)
        period_s = plan.period_s
        started = io.excited_s
        while True:
            block = self.pending.pop(0) if self.pending else io.read(State.ACQUIRING)
            accumulator.add_period(*io.split_channels(block))
            if self.members is not None:
                self.members.add(block)
            count = accumulator.periods
            if io.writer is not None:
                io.writer.set_acquired_periods(count)
            if count < MIN_PERIODS[s.estimator]:  # no honest type A yet (dsp.spectral)
                continue
            estimate = accumulator.estimate(s.estimator)
            others = self.members.estimates() if self.members is not None else ()
            results = ctx.publish(estimate, self.budget, others)
            acquired_s = io.excited_s - started
            worst_a = float(np.nanmax(estimate.relative_type_a))
            ctx.emit(
                Progress(
                    rule.fraction(count, worst_a),
                    acquired_s,
                    rule.remaining_s(count, period_s, acquired_s, worst_a),
                    f"period {count}, worst type A {100 * worst_a:.3f} %",
                    until_target=s.target_type_a is not None,
                )
            )
            stop = rule.decide(count, worst_a, acquired_s, period_s)
            if stop is None:
                continue
            results = self._with_driven_hum(accumulator, estimate, results)
            if stop is Stop.TARGET and s.target_type_a is not None:
                ctx.log(f"type A target {100 * s.target_type_a:g} % reached after {count} periods")
            elif stop is Stop.TIME_BOUND:
                report_target_not_met(ctx, rule, results, estimate, acquired_s)
            return

    def _with_driven_hum(
        self, accumulator: SpectralAccumulator, estimate: Estimate, results: Results
    ) -> Results:
        """The results with the hum measured in the driven periods (`with_driven_hum`)."""
        spectra = accumulator.mean_spectra()
        if spectra is None:
            return results
        budget, again = with_driven_hum(self.ctx, self.budget, spectra, estimate)
        self.budget = budget
        return again or results


def report_target_not_met(
    ctx: RunContext, rule: StoppingRule, results: Results, estimate: Estimate, acquired_s: float
) -> None:
    """A time bound ended the acquisition (`acquired_s` s) before the type A target: the
    report (app.procedure.stopping.TargetNotMet: the bound, the lines above the target with
    their measured type A) warned and added to the results, which state that type A."""
    report = target_not_met(
        rule,
        default_bound=ctx.settings.max_acquisition_default,
        acquired_s=acquired_s,
        periods=estimate.periods,
        labels=[f"{line.nominal_frequency_hz:g} Hz" for line in results.lines],
        type_a=np.asarray(estimate.relative_type_a, dtype=float).tolist(),
        stated=[line.stated for line in results.lines],
    )
    if report is None:
        return
    text = report.text()
    ctx.warn(text)
    ctx.notes.results = dataclasses.replace(results, warnings=(*results.warnings, text))


def with_driven_hum(
    ctx: RunContext,
    budget: Budget,
    spectra: tuple[np.ndarray, np.ndarray],
    estimate: Estimate,
) -> tuple[Budget, Results | None]:
    """The budget with the hum measured in the driven periods' averaged `spectra` (reference,
    DUT; complex, V; dsp.hum.driven_hum: the tones at the non-excited bins beside the lines),
    its warnings given to the run, and the results published again with it (issue 32 point
    3); the budget as it was and None when the hum reaches no line."""
    hum = driven_hum(ctx.plan, *spectra)
    if not hum.affected.any():
        return budget, None
    budget = hum.merged_into(budget)
    ctx.notes.budget = budget
    if ctx.io.writer is not None:
        ctx.io.writer.set_budget(budget)
    for text in hum.warnings():
        ctx.warn(text)
    return budget, ctx.publish(estimate, budget)
