"""Identification phase: a gentle drive, settled, gives the stand's response per line."""

from __future__ import annotations

import numpy as np

from app.procedure.context import RunContext
from app.procedure.errors import ProcedureError
from app.procedure.events import State
from app.procedure.stand_io import Settled
from dsp.crestfactor import synthesize


class Identification:
    """Fade in at `identification_drive_v` per line, settle, and measure the table's response
    (m/s^2 per drive volt, complex, per line). The settle test also guards against a board
    whose output lags its input by a period: the fade itself is never taken for the response."""

    def __init__(self, ctx: RunContext, noise: np.ndarray):
        self.ctx = ctx
        self.noise = noise  # per-period noise (V), rows (reference, DUT), the segment's lines
        self.settled: Settled | None = None  # what identification settled at (after run())

    def run(self) -> np.ndarray:
        ctx = self.ctx
        ctx.state(State.IDENTIFYING, "gentle drive: measuring the stand's response per line")
        plan = ctx.io.segment.plan
        amplitude = np.full(len(plan.lines), ctx.settings.identification_drive_v)
        drive = synthesize(plan.bins, amplitude, plan.phases_rad, plan.period_samples)
        ctx.io.crossfade(drive, State.IDENTIFYING)
        self.settled = ctx.io.settle(self.noise, State.IDENTIFYING)
        measured = self.settled.acceleration
        drive_line = amplitude * np.exp(1j * (plan.phases_rad - np.pi / 2))
        response = measured / drive_line
        if np.any(np.abs(response) == 0) or not np.all(np.isfinite(response)):
            raise ProcedureError(
                "no motion on the reference channel at some lines during identification: check "
                "the power amplifier (enabled, gain) and the reference accelerometer"
            )
        return response
