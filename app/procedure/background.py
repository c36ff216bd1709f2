"""Background phase: periods with the drive at 0 V (noise and hum at every line), and the
budget terms they give once the lines have settled (SPEC s.5 step 2)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.procedure.context import RunContext
from app.procedure.events import State
from app.procedure.stand_io import Segment
from dsp.hum import mains_hum_from_lines
from dsp.multisine import Plan
from dsp.spectral import SpectralAccumulator
from dsp.uncertainty import Budget, Component, Distribution


@dataclass(frozen=True)
class BackgroundLevels:
    """Per line (V): the background amplitude of each channel and the per-period noise from
    the many non-excited bins around the line (well determined from one or two periods)."""

    reference: np.ndarray
    dut: np.ndarray
    reference_noise: np.ndarray
    dut_noise: np.ndarray

    def noise(self) -> np.ndarray:
        """Per-period noise, rows (reference, DUT): the settle test's scale."""
        return np.array([self.reference_noise, self.dut_noise])

    def to_dict(self) -> dict[str, list[float]]:
        return {
            "reference": self.reference.tolist(),
            "dut": self.dut.tolist(),
            "reference_noise": self.reference_noise.tolist(),
            "dut_noise": self.dut_noise.tolist(),
        }


class Background:
    """Start the output at 0 V, switch the power amplifier on, read the background."""

    def __init__(self, ctx: RunContext):
        self.ctx = ctx

    def run(self) -> BackgroundLevels:
        ctx, plan = self.ctx, self.ctx.plan
        ctx.state(State.BACKGROUND, "drive at 0 V: noise and hum at every line")
        ctx.io.begin(Segment(plan))
        ctx.io.enable_power()
        accumulator = SpectralAccumulator(plan.period_samples, plan.bins)
        for _ in range(max(1, ctx.settings.background_periods)):
            accumulator.add_period(*ctx.io.split_channels(ctx.io.read(State.BACKGROUND)))
        estimate = accumulator.estimate()
        levels = BackgroundLevels(
            estimate.reference_amplitude_v,
            estimate.dut_amplitude_v,
            estimate.reference_noise_v,
            estimate.dut_noise_v,
        )
        ctx.notes.background = levels.to_dict()
        return levels


def budget_with_background(
    budget: Budget,
    plan: Plan,
    background: BackgroundLevels,
    settled_lines: tuple[np.ndarray, np.ndarray],
    background_periods: int,
) -> Budget:
    """The stand's budget plus, per line, the background found with the drive at 0 V (hum,
    which a periodic average does not remove) relative to the settled line (SPEC s.5 step
    2): at a line on a mains harmonic the "mains hum at X Hz" components of dsp.hum
    (U-shaped, magnitude and phase; issue 13 point 3), elsewhere a rectangular bound on the
    background's bias, left out when negligible (< 1e-4)."""
    components = list(budget.components)
    ref_lines, dut_lines = settled_lines
    hum = mains_hum_from_lines(
        plan, background.reference, background.dut, ref_lines, dut_lines, max(1, background_periods)
    )
    components.extend(hum.components())
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = background.reference / np.abs(ref_lines) + background.dut / np.abs(dut_lines)
    for f, b, on_mains in zip(plan.frequencies_hz, bound, hum.affected, strict=True):
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
