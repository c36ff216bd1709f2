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

if TYPE_CHECKING:
    from app.stand.config import Limits
    from dsp.multisine import Plan

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
        """Play the stored response's drive at CHECK_LEVEL of the level for one period after
        its crossfade, and compare. Agreeing within `tolerance` at every line: the stored
        response (it holds the exciter's compression at the level, which the reduced period
        does not). Disagreeing: None (the caller re-identifies; the error is noted), unless the
        drive the stored response asks for at level would take the table past a limit through
        the measured response (the stand changed: a gain knob turned up): then a fade-out and
        PreflightError naming the predicted displacement. The level is never played with it."""
        ctx = self.ctx
        plan = ctx.io.segment.plan
        limits = ctx.stand.config.limits
        at_level = target / stored
        reduced = CHECK_LEVEL * at_level
        check_drive(plan, reduced, stored, limits, "stored-response check period")
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
            ctx.io.fade_out()  # from the reduced check level, before the refusal
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
