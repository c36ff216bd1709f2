"""Equalisation phase: closed loop on the table acceleration per line (SPEC s.5 step 4)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from app.procedure.context import RunContext
from app.procedure.errors import PreflightError, ProcedureError
from app.procedure.events import EqualisationStep, State
from app.procedure.stand_io import Settled
from dsp.crestfactor import synthesize


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
        drive_lines = target / response
        limit = ctx.io.drive_limit_v
        worst = math.inf
        settled: Settled | None = None
        for iteration in range(1, s.max_equalisation_iterations + 1):
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
            if iteration == 1 and give_up_above is not None and worst > give_up_above:
                return None
            drive_lines = drive_lines * target / measured
        if settled is None:
            raise ProcedureError("equalisation: max_equalisation_iterations must be at least 1")
        ctx.warn(
            f"equalisation: worst line still {100 * worst:.2f} % off its target after "
            f"{s.max_equalisation_iterations} iterations (the calibration is a ratio "
            "and stays valid; the level is less exact)"
        )
        return Equalised(response, settled, False)
