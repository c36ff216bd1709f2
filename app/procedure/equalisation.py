"""Equalisation phase: closed loop on the table acceleration per line (SPEC s.5 step 4).

Safety from the computed drive (issue 25 point 7): every drive is checked before it is played
against the stand's limits through the latest response (app.procedure.preflight.check_drive);
a stored response is first played at `CHECK_LEVEL` of the level only, and trusted for the level
only when that reduced period agrees with it within the tolerance. The LPM's bursts
(app.procedure.record_run) check a stored response the same way (`stored_refusal`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from app.procedure.context import RunContext
from app.procedure.errors import PreflightError, ProcedureError
from app.procedure.events import EqualisationStep, State
from app.procedure.preflight import check_drive, limit_problems, predict_drive_peaks
from app.procedure.stand_io import Settled
from dsp.crestfactor import synthesize
from dsp.fades import fade_envelope, fade_in_samples
from dsp.multisine import Plan

if TYPE_CHECKING:
    from app.stand.config import Limits

CHECK_LEVEL = 0.2  # a stored response is first played at this fraction of the level


@dataclass(frozen=True)
class Equalised:
    """The stand's response at the final drive, the last settled periods, and whether the
    tolerance was met (then those two periods are the first acquired ones)."""

    response: np.ndarray
    settled: Settled
    converged: bool

    @property
    def reusable_blocks(self) -> list[np.ndarray]:
        """Periods settled at the final drive, to acquire without reading them again."""
        return list(self.settled.blocks) if self.converged else []


class Equalisation:
    """Crossfade to a drive, settle, measure the table acceleration per line on the reference
    channel, D_k <- D_k A_target/A_measured; at most `max_equalisation_iterations`."""

    def __init__(self, ctx: RunContext, noise: np.ndarray):
        self.ctx = ctx
        self.noise = noise  # per-period noise (V), rows (reference, DUT), the segment's lines

    def run(self, response: np.ndarray, *, give_up_above: float | None = None) -> Equalised | None:
        """Equalise from `response` ((m/s^2)/V per line). With `give_up_above` (a stored
        response being checked): None when the first step's worst line is off by more than
        that fraction, so the caller re-identifies the stand."""
        ctx, s = self.ctx, self.ctx.settings
        ctx.state(State.EQUALISING, f"closed loop, tolerance {100 * s.equalisation_tolerance:g} %")
        plan = ctx.io.segment.plan
        target = plan.amplitudes_ms2 * np.exp(1j * (plan.phases_rad - np.pi / 2))
        if give_up_above is not None:
            checked = self._check_stored(response, target, give_up_above)
            if checked is None:
                return None
            response = checked
        drive_lines = target / response
        worst = math.inf
        settled: Settled | None = None
        for iteration in range(1, s.max_equalisation_iterations + 1):
            drive = self._drive(drive_lines)
            check_drive(
                plan,
                drive_lines,
                response,
                ctx.stand.config.limits,
                f"equalisation step {iteration}",
            )
            ctx.io.crossfade(drive)
            settled = ctx.io.settle(self.noise)
            measured = settled.acceleration
            response = measured / drive_lines  # the stand's response at this level
            errors = np.abs(measured / target) - 1.0
            worst = float(np.max(np.abs(errors)))
            ctx.notes.equalisation.append(worst)
            ctx.emit(EqualisationStep(iteration, errors, worst))
            ctx.log(f"equalisation {iteration}: worst line {100 * worst:.2f} %")
            if worst <= s.equalisation_tolerance:
                return Equalised(response, settled, True)
            drive_lines = drive_lines * target / measured
        if settled is None:
            raise ProcedureError("equalisation: max_equalisation_iterations must be at least 1")
        ctx.warn(
            f"equalisation: worst line still {100 * worst:.2f} % off its target after "
            f"{s.max_equalisation_iterations} iterations (the calibration is a ratio "
            "and stays valid; the level is less exact)"
        )
        return Equalised(response, settled, False)

    def _drive(self, drive_lines: np.ndarray) -> np.ndarray:
        """One period of the drive (V) for the complex drive per line; PreflightError over the
        stand's drive limit."""
        plan, limit = self.ctx.io.segment.plan, self.ctx.io.drive_limit_v
        drive = synthesize(
            plan.bins, np.abs(drive_lines), np.angle(drive_lines) + np.pi / 2, plan.period_samples
        )
        peak = float(np.max(np.abs(drive)))
        if peak > limit:
            raise PreflightError(
                f"the level needs a {peak:.2f} V drive peak, over the stand's {limit:g} V "
                "limit: lower the level or raise the power amplifier's gain"
            )
        return drive

    def _check_stored(
        self, stored: np.ndarray, target: np.ndarray, tolerance: float
    ) -> np.ndarray | None:
        """Play the stored response's drive at CHECK_LEVEL of the level as a short check burst
        (`play_check_burst`; issue 34: it was a crossfade and a period, 4 s on the seed plan),
        or, when the lines need more than a period and for a stepped-sine line (a short burst
        near the exciter's suspension resonance would be read before its transient decayed),
        for one period after its crossfade, and compare. Agreeing within `tolerance` at every
        line: the stored response (it holds the exciter's compression at the level, which the
        reduced level does not). Disagreeing: None (the caller re-identifies; the error is
        noted), unless the drive the stored response asks for at level would take the table
        past a limit through the measured response (the stand changed: a gain knob turned
        up): then a fade-out and PreflightError naming the predicted displacement. The level
        is never played with it."""
        ctx = self.ctx
        plan = ctx.io.segment.plan
        limits = ctx.stand.config.limits
        at_level = target / stored
        reduced = CHECK_LEVEL * at_level
        check_drive(plan, reduced, stored, limits, "stored-response check period")
        self._drive(reduced)  # its peak within the drive limit
        fade = fade_in_samples(
            float(np.min(plan.frequencies_hz)),
            plan.sample_rate_hz,
            plan.period_samples,
            ctx.settings.fade_in_s,
        )
        measured = None  # the stepped sine's line: its crossfade and a settled block
        if not ctx.io.segment.one_line:  # issue 34: a short burst from 0 V
            measured = play_check_burst(ctx, reduced, fade, stored, self.noise[0])
        if measured is not None:
            error = float(np.max(np.abs(np.abs(measured / stored) - 1.0)))
            if error > tolerance:  # a real change, or a burst too short for a low level
                refusal = stored_refusal(plan, at_level, measured, limits, error)
                if refusal is not None:
                    raise refusal  # the burst ended at 0 V: nothing plays
                ctx.log(
                    f"stand response: the check burst read the stored one {100 * error:.1f} % "
                    "off: checked again over a period"
                )
                measured = None
        if measured is None:  # the lines need more than a period: the crossfade and a period
            ctx.io.crossfade(self._drive(reduced))
            reference, _ = ctx.io.period(State.EQUALISING)  # one period after the crossfade
            measured = ctx.io.to_acceleration(reference) / reduced
        error = float(np.max(np.abs(np.abs(measured / stored) - 1.0)))
        ctx.log(
            f"stand response: stored one checked at {100 * CHECK_LEVEL:g} % of the level: "
            f"worst line {100 * error:.2f} % off"
        )
        if error <= tolerance:
            return stored
        ctx.notes.equalisation.append(error)
        refusal = stored_refusal(plan, at_level, measured, limits, error)
        if refusal is not None:
            ctx.io.try_fade_out()  # from the reduced check level (a burst ended at 0 V)
            raise refusal
        return None


def stored_refusal(
    plan: Plan, at_level: np.ndarray, measured: np.ndarray, limits: Limits, error: float
) -> PreflightError | None:
    """The refusal of a stored response found off by `error` (a fraction) at its check at
    CHECK_LEVEL: when the drive it asks for at level (`at_level`, complex V per line) would
    take the table past a limit through the `measured` response ((m/s^2)/V per line), fades
    included; None when it would not (the caller re-identifies)."""
    peaks = predict_drive_peaks(plan, at_level, measured)
    problems = limit_problems(peaks, limits)
    if not problems:
        return None
    return PreflightError(
        f"stored stand response off by {100 * error:.0f} % at its check: its drive at "
        f"level would give a predicted displacement of "
        f"{1e3 * peaks.displacement_peak_to_peak_m:.2f} mm p-p ("
        + "; ".join(problems)
        + "): refused before it is played; the stand changed (power amplifier gain?): "
        "check it, then run without the stored response"
    )


CHECK_HOLD_SPACINGS = 0.5  # the hold: this many periods of the closest lines' beat
CHECK_HOLD_CYCLES = 2.0  # and at least this many cycles of the lowest line


CHECK_SIGMAS = 5.0  # the burst's noise at a line: at most the tolerance / this many sigmas


def noise_hold_samples(
    plan: Plan, reference_v: np.ndarray, noise_v: np.ndarray, tolerance: float
) -> int:
    """The hold (samples) that puts the burst's relative noise at every line under
    tolerance / CHECK_SIGMAS: a least-squares amplitude over n samples has the noise of a
    period's line (`noise_v`, V per period) times sqrt(N / n), and a fit of correlated lines
    (`check_burst_samples`) 1.3 times that; `reference_v` the reference channel's expected
    amplitude per line at the check level (V)."""
    relative = 1.3 * np.asarray(noise_v, float) / np.maximum(np.abs(reference_v), 1e-300)
    need = float(np.max(relative)) * CHECK_SIGMAS / tolerance
    return int(np.ceil(plan.period_samples * need**2))


def check_burst_samples(plan: Plan, fade: int, min_hold: int = 0) -> tuple[int, int, int] | None:
    """A check burst's fade-in, hold and fade-out (samples) for `plan`: fades of half the
    LPM's fade-in `fade` (at CHECK_LEVEL the offset a short fade leaves is a fifth of the
    level's), a hold of CHECK_HOLD_SPACINGS / the closest lines' spacing (their regressors
    then correlate by at most sinc(pi / 2) = 0.64: a variance 1.7 times an orthogonal fit's,
    far inside the tolerance at a check's signal-to-noise ratio; a disagreement is confirmed
    over a period), at least CHECK_HOLD_CYCLES cycles of the lowest line and `min_hold`
    (`noise_hold_samples`); None when that is longer than a period (a whole period is read)."""
    f = np.sort(np.asarray(plan.frequencies_hz, float))
    spacing = float(np.min(np.diff(f))) if f.size > 1 else float(f[0])
    hold_s = max(CHECK_HOLD_SPACINGS / spacing, CHECK_HOLD_CYCLES / float(f[0]))
    hold = max(int(np.ceil(hold_s * plan.sample_rate_hz)), min_hold)
    ramp = max(2, fade // 2)
    if 3 * ramp + hold > plan.period_samples:
        return None
    return ramp, hold, ramp


def burst_envelope(period_samples: int, rise: int, hold: int, fall: int) -> np.ndarray:
    """One period's gain: a raised-cosine rise over `rise` samples from exactly 0, `hold`
    samples of 1, a raised-cosine fall to exactly 0 over `fall`, zeros to the period's end."""
    envelope = np.zeros(period_samples)
    envelope[:rise] = fade_envelope(rise, 1, "in")
    envelope[rise : rise + hold] = 1.0
    envelope[rise + hold : rise + hold + fall] = fade_envelope(fall, 1, "out")
    return envelope


def burst_response(
    plan: Plan,
    drive_lines: np.ndarray,
    envelope: np.ndarray,
    reference: np.ndarray,
    window: slice = slice(None),
) -> np.ndarray:
    """The reference channel's volts per drive volt at every line (complex) from a burst:
    reference(i) ~ sum_k Re(G_k) s_k(i) + Im(G_k) q_k(i), s_k = e(i) Re(D_k z_k(i)) and
    q_k = e(i) Re(j D_k z_k(i)), z_k = exp(j 2 pi m_k i / N), e the burst's envelope, by
    least squares (quasi-static: the envelope changes slowly against the stand's response,
    whose short transients are left in the residual)."""
    n = plan.period_samples
    i = np.arange(envelope.size)[window]
    e = envelope[window][:, None]
    rotor = np.exp(2j * np.pi * np.outer(i, np.asarray(plan.bins, float)) / n) * drive_lines
    columns = np.hstack([(rotor * e).real, (1j * rotor * e).real])
    solution, *_ = np.linalg.lstsq(columns, reference[window], rcond=None)
    k = len(plan.bins)
    return solution[:k] + 1j * solution[k:]


def play_check_burst(
    ctx: RunContext,
    drive_lines: np.ndarray,
    fade: int,
    stored: np.ndarray,
    reference_noise_v: np.ndarray,
) -> np.ndarray | None:
    """The stand's response ((m/s^2)/V per line, complex) from a short check burst of
    `drive_lines` (complex V per line), played from 0 V: a raised-cosine fade-in of `fade`
    samples, the hold of `check_burst_samples` (long enough for the reference channel's noise,
    `reference_noise_v` per line per period, against the amplitude the `stored` response
    predicts), a fade-out to exactly 0 V, within one written period that is read before
    anything else is written; the reference channel fitted by least squares
    (`burst_response`). None when the burst does not fit in a period."""
    io, plan = ctx.io, ctx.io.segment.plan
    expected_ms2 = np.asarray(stored, complex) * np.asarray(drive_lines, complex)
    volts = np.abs(expected_ms2 / io.to_acceleration(np.ones(len(plan.bins), complex)))
    tolerance = ctx.settings.stored_response_tolerance
    min_hold = noise_hold_samples(plan, volts, reference_noise_v, tolerance)
    lengths = check_burst_samples(plan, fade, min_hold)
    if lengths is None:
        return None
    n = plan.period_samples
    drive = synthesize(plan.bins, np.abs(drive_lines), np.angle(drive_lines) + np.pi / 2, n)
    envelope = burst_envelope(n, *lengths)
    io.write(drive * envelope)
    io.in_transition = True
    try:
        while io.queue:  # a zero period queued before plays first, then the burst
            block = io.read(State.EQUALISING)
    finally:
        io.in_transition = False
    io.drive = np.zeros(n)  # the burst ended at exactly 0 V
    reference, _ = io.split_channels(block)
    rise, hold, _ = lengths
    window = slice(rise, rise + hold)  # the hold: the ramps' transients are not modelled
    per_drive = burst_response(plan, drive_lines, envelope, reference, window)
    response = io.to_acceleration(per_drive)
    if np.any(np.abs(response) == 0) or not np.all(np.isfinite(response)):
        raise ProcedureError(
            "no motion on the reference channel at some lines: check the power amplifier "
            "(enabled, gain) and the reference accelerometer"
        )
    return response
