"""Multisine with the LPM estimator (issue 26 point 3): short bursts instead of settled periods.

A burst plays a zero period whose last `fade-in` samples fade the steady drive in (it then
continues the drive's own phase), reads whole periods of the steady drive as one record, and
fades out. The start-up transient the fade leaves is estimated by the LPM's transient term
(dsp.lpm_record), not waited out, so type A and the level check come from the first period.
Warm: the stand's stored response is checked first by a burst at CHECK_LEVEL (20 %) of the
level (issue 25 point 7, here since issue 34 made the LPM the default: a stored response that
is wrong is caught before the level is played); cold: a gentle identification burst at
`identification_drive_v` per line first (the same multisine, reduced level). A level
more than `equalisation_tolerance` off after the first period: the burst's own measurement
corrects the drive, and another burst follows. Periods join the record until the run's
stopping rule holds (periods, type A target, time bound). Units: V, m/s^2, s.
"""

from __future__ import annotations

import math

import numpy as np

from app.procedure.acquisition import report_target_not_met, with_driven_hum
from app.procedure.background import BackgroundLevels, budget_with_background
from app.procedure.batch_live import LiveMembers
from app.procedure.context import RunContext
from app.procedure.equalisation import CHECK_LEVEL, play_check_burst, stored_refusal
from app.procedure.errors import PreflightError, ProcedureError
from app.procedure.events import EqualisationStep, Progress, State
from app.procedure.preflight import check_drive, fade_in_for
from app.procedure.ranging import run_resolution, with_resolution
from app.procedure.stand_memory import StandMemory
from app.procedure.stopping import NO_PERIOD_LIMIT, Stop, StoppingRule
from app.stand.response import StoredResponse
from dsp.crestfactor import synthesize
from dsp.fades import FADE_IN_CYCLES as FADE_IN_CYCLES  # re-exported for its callers
from dsp.fades import fade_envelope, fade_in_samples
from dsp.lpm_live import LiveRecord
from dsp.lpm_record import RecordEstimate, record_estimate
from dsp.spectral import MIN_PERIODS, Estimate, period_spectrum
from dsp.uncertainty import Budget

# one period: reference, DUT, the drive as played, the drive as recorded (V)
Period = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class RecordRun:
    """The LPM run's phases after the background; results end in the context's notes."""

    def __init__(
        self,
        ctx: RunContext,
        background: BackgroundLevels,
        memory: StandMemory,
        members: LiveMembers | None = None,
    ):
        self.ctx = ctx
        self.background = background
        self.memory = memory
        self.members = members  # a run of several DUTs: the others' live estimates
        self.block: np.ndarray | None = None  # the last period as read (every channel)
        plan = ctx.plan
        fade_s = ctx.notes.fade_in_s  # as the run's preflight picked and checked it
        if fade_s is None:  # no preflight made (a phase run on its own): picked here
            target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
            fade_s = fade_in_for(plan, target, ctx.stand.config.limits, ctx.settings.fade_in_s)
        self.fade = fade_in_samples(
            float(np.min(plan.frequencies_hz)), plan.sample_rate_hz, plan.period_samples, fade_s
        )

    # --- one burst ------------------------------------------------------------------------

    def _lead(self, drive: np.ndarray, state: State) -> None:
        """The zero period ending in the fade-in; then the steady drive is queued."""
        io, n = self.ctx.io, self.ctx.plan.period_samples
        lead = np.zeros(n)
        lead[n - self.fade :] = drive[n - self.fade :] * fade_envelope(self.fade, 1, "in")
        io.write(lead)
        io.in_transition = True
        try:
            while io.queue:  # a zero period a fade-out left queued plays first, then the lead
                io.read(state)
        except BaseException:
            io.drive = drive  # the fade is written: a fade-out starts from the steady drive
            raise
        finally:
            io.in_transition = False
        io.drive = drive
        io.write(drive)

    def _record(self, blocks: list[Period]) -> RecordEstimate:
        ref = np.array([b[0] for b in blocks])
        dut = np.array([b[1] for b in blocks])
        drive = np.array([b[2] for b in blocks])
        return record_estimate(ref, dut, self.ctx.plan, drive_blocks=drive)

    def _read(self, state: State) -> Period:
        """One period: reference, DUT, the drive as played and as recorded (V)."""
        io = self.ctx.io
        block = self.block = io.read(state)
        ref, dut = io.split_channels(block)
        index = io.channel_index
        recorded = block[index["drive"]] if "drive" in index else io.played  # as the writer's
        return ref, dut, io.played, recorded

    def _response(self, record: RecordEstimate) -> np.ndarray:
        """The stand's response per line, (m/s^2) per drive V (complex), from the record."""
        per_drive = record.lpm.reference_per_drive
        assert per_drive is not None  # the record was estimated with its drive
        response = self.ctx.io.to_acceleration(per_drive)
        if np.any(np.abs(response) == 0) or not np.all(np.isfinite(response)):
            raise ProcedureError(
                "no motion on the reference channel at some lines: check the power amplifier "
                "(enabled, gain) and the reference accelerometer"
            )
        return response

    # --- phases -----------------------------------------------------------------------------

    def identify(self) -> np.ndarray:
        """Gentle burst: one period of the multisine at `identification_drive_v` per line."""
        ctx, plan = self.ctx, self.ctx.plan
        ctx.state(State.IDENTIFYING, "gentle burst: the stand's response per line (lpm)")
        amplitude = np.full(len(plan.lines), ctx.settings.identification_drive_v)
        drive = synthesize(plan.bins, amplitude, plan.phases_rad, plan.period_samples)
        self._lead(drive, State.IDENTIFYING)
        record = self._record([self._read(State.IDENTIFYING)])
        ctx.io.fade_out()
        return self._response(record)

    def _check_burst(self, drive_lines: np.ndarray, stored: StoredResponse) -> np.ndarray:
        """The stand's response ((m/s^2)/V per line) from a check burst of `drive_lines`
        (complex V per line): short when it fits in a period (equalisation.play_check_burst);
        one period read as an LPM record when it does not, or when the short burst disagrees
        with `stored` by more than the tolerance without a refusal (a burst too short for a
        low level reads noise as a change: the period confirms or refutes it)."""
        ctx, plan = self.ctx, self.ctx.plan
        measured = play_check_burst(
            ctx, drive_lines, self.fade, stored.response, self.background.noise()[0]
        )
        if measured is not None:
            error = float(np.max(np.abs(np.abs(measured / stored.response) - 1.0)))
            if error <= ctx.settings.stored_response_tolerance:
                return measured
            at_level = drive_lines / CHECK_LEVEL
            refusal = stored_refusal(plan, at_level, measured, ctx.stand.config.limits, error)
            if refusal is not None:
                ctx.notes.equalisation.append(error)
                raise refusal  # the burst ended at 0 V: nothing plays
            ctx.log(
                f"stand response: the check burst read the stored one {100 * error:.1f} % "
                "off: checked again over a period (lpm)"
            )
        drive = synthesize(
            plan.bins, np.abs(drive_lines), np.angle(drive_lines) + np.pi / 2, plan.period_samples
        )
        self._lead(drive, State.EQUALISING)
        record = self._record([self._read(State.EQUALISING)])
        ctx.io.fade_out()
        return self._response(record)

    def check_stored(self, stored: StoredResponse) -> np.ndarray:
        """Issue 25 point 7 in the LPM's bursts (issue 34: the default estimator): a stored
        response is first played at CHECK_LEVEL of the level, one burst (fade-in, one period
        read as a record, fade-out), and the stand's response measured from it. Agreeing within
        `stored_response_tolerance` at every line: the stored response (it holds the exciter's
        compression at the level). Disagreeing: the measured one (the burst identified the
        stand), unless the level's drive asked of the stored response would take the table
        past a limit through the measured one: PreflightError, the level never played."""
        ctx, plan, s = self.ctx, self.ctx.plan, self.ctx.settings
        limits = ctx.stand.config.limits
        target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
        at_level = target / stored.response
        reduced = CHECK_LEVEL * at_level
        check_drive(plan, reduced, stored.response, limits, "stored-response check burst")
        ctx.state(
            State.EQUALISING,
            f"check burst at {100 * CHECK_LEVEL:g} % of the level: the stored response (lpm)",
        )
        measured = self._check_burst(reduced, stored)
        error = float(np.max(np.abs(np.abs(measured / stored.response) - 1.0)))
        ctx.log(
            f"stand response: stored one checked at {100 * CHECK_LEVEL:g} % of the level: "
            f"worst line {100 * error:.2f} % off (lpm, one period)"
        )
        if error <= s.stored_response_tolerance:
            ctx.notes.stand_response = self.memory.describe(stored, "stored", check_error=error)
            return stored.response
        ctx.notes.equalisation.append(error)
        refusal = stored_refusal(plan, at_level, measured, limits, error)
        if refusal is not None:
            raise refusal
        ctx.log(
            f"stand response: the stored one is off by {100 * error:.1f} % "
            f"(> {100 * s.stored_response_tolerance:g} %): the check burst re-identified it"
        )
        ctx.notes.stand_response = self.memory.describe(
            stored, "stored, disagreed: identified", check_error=error
        )
        return measured

    def run(self) -> None:
        """The stand's response (a stored one checked by a burst at CHECK_LEVEL, else a gentle
        identification burst), then bursts until the level holds; the last burst acquires until
        the stopping rule; fades out."""
        ctx, s = self.ctx, self.ctx.settings
        stored = self.memory.recall()
        if stored is not None:
            response = self.check_stored(stored)
        else:
            response = self.identify()
            self.ctx.notes.stand_response = self.memory.describe(None, "identified")
        plan = ctx.plan
        target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
        for iteration in range(1, s.max_equalisation_iterations + 1):
            drive_lines = target / response
            check_drive(
                plan, drive_lines, response, ctx.stand.config.limits, f"level burst {iteration}"
            )
            drive = synthesize(
                plan.bins,
                np.abs(drive_lines),
                np.angle(drive_lines) + np.pi / 2,
                plan.period_samples,
            )
            peak = float(np.max(np.abs(drive)))
            if peak > ctx.io.drive_limit_v:
                raise PreflightError(
                    f"the level needs a {peak:.2f} V drive peak, over the stand's "
                    f"{ctx.io.drive_limit_v:g} V limit: lower the level or raise the power "
                    "amplifier's gain"
                )
            ctx.state(State.EQUALISING, f"burst {iteration}: fade-in, level check (lpm)")
            self._lead(drive, State.EQUALISING)
            first = self._read(State.ACQUIRING)
            record = self._record([first])
            measured = self._response(record)
            errors = np.abs(measured / response) - 1.0  # table level against its target
            worst = float(np.max(np.abs(errors)))
            ctx.notes.equalisation.append(worst)
            ctx.emit(EqualisationStep(iteration, errors, worst))
            ctx.log(f"level check {iteration}: worst line {100 * worst:.2f} % (lpm, one period)")
            response = measured
            converged = worst <= s.equalisation_tolerance
            last = iteration == s.max_equalisation_iterations
            if converged or last:
                if not converged:
                    ctx.warn(
                        f"equalisation: worst line still {100 * worst:.2f} % off its target "
                        f"after {iteration} bursts (the calibration is a ratio and stays valid; "
                        "the level is less exact)"
                    )
                else:
                    ctx.notes.measured_response = measured
                    ctx.notes.measured_response_error = worst
                self.acquire(first, record)
                return
            ctx.io.fade_out()

    def acquire(self, first: Period, record: RecordEstimate) -> None:
        """Periods join the record (after `first`) until the stopping rule; results after each."""
        ctx, s, io = self.ctx, self.ctx.settings, self.ctx.io
        ctx.state(State.ACQUIRING, "one record: lpm")
        plan = ctx.plan
        budget = budget_with_background(
            ctx.stand.budget,
            plan,
            self.background,
            (record.estimate.reference_amplitude_v, record.estimate.dut_amplitude_v),
            s.background_periods,
            warn=ctx.warn,
        )
        resolution = run_resolution(
            plan,
            (record.estimate.reference_amplitude_v, record.estimate.dut_amplitude_v),
            self.background.noise(),
            io.ranges,
            ctx.stand.config.converter,
        )
        budget, too_few = with_resolution(budget, resolution)
        for text in too_few:
            ctx.warn(text)
        ctx.notes.budget = budget
        if io.writer is not None:
            io.writer.set_settle_periods(io.periods_read - 1)
            io.writer.set_budget(budget)
            io.writer.set_resolution_warnings(too_few)
        rule = StoppingRule(
            s.periods, s.target_type_a, s.max_acquisition_s, min_periods=MIN_PERIODS[s.estimator]
        )
        with LiveRecord(plan, target=s.target_type_a) as live:
            live.add(*first)
            self._members_add(first)
            self._acquire(rule, live, record.estimate, budget)

    def _acquire(
        self, rule: StoppingRule, live: LiveRecord, estimate: Estimate | None, budget: Budget
    ) -> None:
        """The acquisition loop: a period joins `live` (holding the first) until the rule
        stops it. The rule asks for the type A of the whole record so far; a record over
        dsp.lpm_record.WHOLE_RECORD_PERIODS is estimated at checkpoints only (dsp.lpm_live),
        between them the type A is not known (the progress states the last one measured)."""
        ctx, s, io = self.ctx, self.ctx.settings, self.ctx.io
        period_s = ctx.plan.period_s
        started = io.excited_s - period_s  # the first period is acquired already
        live.last = last_period(rule, period_s, io.excited_s - started)
        last: tuple[int, float] = (1, math.inf)  # the last estimate: periods, worst type A
        while True:
            count = live.count
            if io.writer is not None:
                io.writer.set_acquired_periods(count)
            acquired_s = io.excited_s - started
            if estimate is not None:
                others = self.members.estimates() if self.members is not None else ()
                results = ctx.publish(estimate, budget, others)
                worst_a = float(np.nanmax(estimate.relative_type_a))
                last = (count, worst_a)
                live.measured(worst_a)
                if self.members is not None:  # their records on the same checkpoints
                    self.members.follow(worst_a, live.last)
                shown, text = worst_a, f"record of {count} period(s), worst type A"
                text += f" {100 * worst_a:.3f} %"
                stop = rule.decide(count, worst_a, acquired_s, period_s)
            else:  # between checkpoints: the type A at the pace measured, for the progress
                shown = last[1] * math.sqrt(last[0] / count)
                text = (
                    f"record of {count} period(s), worst type A {100 * last[1]:.3f} % at "
                    f"{last[0]} (next estimate at {live.checkpoint})"
                )
                stop = rule.decide(count, math.inf, acquired_s, period_s)
            ctx.emit(
                Progress(
                    rule.fraction(count, shown),
                    acquired_s,
                    rule.remaining_s(count, period_s, acquired_s, shown),
                    text,
                    until_target=s.target_type_a is not None,
                )
            )
            if stop is not None:
                if estimate is None:  # stopped off a checkpoint: the record's estimate now
                    estimate = live.estimate().estimate
                    results = ctx.publish(estimate, budget)
                spectra = tuple(period_spectrum(x) for x in live.mean_periods())
                budget, again = with_driven_hum(ctx, budget, (spectra[0], spectra[1]), estimate)
                results = again or results
                if stop is Stop.TARGET and s.target_type_a is not None:
                    ctx.log(f"type A target {100 * s.target_type_a:g} % reached, {count} period(s)")
                elif stop is Stop.TIME_BOUND:
                    report_target_not_met(ctx, rule, results, estimate, acquired_s)
                return
            period = self._read(State.ACQUIRING)
            live.add(*period)
            self._members_add(period)
            estimate = live.estimate().estimate if live.due else None

    def _members_add(self, period: Period) -> None:
        """The other DUTs of a run of several: the period just read joins their records."""
        if self.members is not None and self.block is not None:
            self.members.add(self.block, period[2], period[3])


def last_period(rule: StoppingRule, period_s: float, first_s: float) -> int | None:
    """The period after which `rule` stops whatever the type A: its period limit, or the last
    period within its time bound (`first_s` s of acquisition counted after the first period,
    `period_s` s for each further one); None when neither bounds it. A bound that is a whole
    number of periods is a tie the acquisition's own sums of seconds decide either way: the
    earlier period is taken (a run that then goes on one more is estimated off its checkpoint,
    dsp.lpm_live.LiveRecord.estimate, once)."""
    last = rule.period_limit if rule.period_limit < NO_PERIOD_LIMIT else None
    bound = rule.max_time_s
    if bound is not None:
        count = 1
        while count < NO_PERIOD_LIMIT and not (first_s + count * period_s > bound):
            count += 1
        if count > 1 and math.isclose(first_s + (count - 1) * period_s, bound, rel_tol=1e-9):
            count -= 1
        last = count if last is None else min(last, count)
    return last
