"""Background phase: periods with the drive at 0 V (noise and hum at every line), and the
budget terms they give once the lines have settled (SPEC s.5 step 2): hum only, at the lines
on mains harmonics; random noise is in type A already (issue 25 point 3)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from app.procedure.context import RunContext
from app.procedure.events import State
from app.procedure.stand_io import Segment
from dsp.hum import mains_hum_from_lines
from dsp.multisine import Plan
from dsp.spectral import SpectralAccumulator, period_spectrum
from dsp.uncertainty import Budget


@dataclass(frozen=True)
class BackgroundLevels:
    """Per line (V): the background amplitude of each channel (|mean X|), the per-period noise
    from the many non-excited bins around the line (well determined from one or two periods)
    and the per-period rms |X_n| at the line (the hum's full size before it averages down;
    not stored, the run's budget is)."""

    reference: np.ndarray
    dut: np.ndarray
    reference_noise: np.ndarray
    dut_noise: np.ndarray
    reference_rms: np.ndarray | None = None
    dut_rms: np.ndarray | None = None

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
        bins = np.asarray(plan.bins)
        power = np.zeros((2, bins.size))
        count = max(1, ctx.settings.background_periods)
        for _ in range(count):
            reference, dut = ctx.io.split_channels(ctx.io.read(State.BACKGROUND))
            accumulator.add_period(reference, dut)
            power += [
                np.abs(period_spectrum(np.asarray(x, float))[bins]) ** 2 for x in (reference, dut)
            ]
        estimate = accumulator.estimate()
        rms = np.sqrt(power / count)
        levels = BackgroundLevels(
            estimate.reference_amplitude_v,
            estimate.dut_amplitude_v,
            estimate.reference_noise_v,
            estimate.dut_noise_v,
            rms[0],
            rms[1],
        )
        ctx.notes.background = levels.to_dict()
        return levels


def budget_with_background(
    budget: Budget,
    plan: Plan,
    background: BackgroundLevels,
    settled_lines: tuple[np.ndarray, np.ndarray],
    background_periods: int,
    warn: Callable[[str], None] | None = None,
) -> Budget:
    """The stand's budget plus, at every line on a mains harmonic, the "mains hum at X Hz"
    components of dsp.hum (U-shaped, magnitude and phase) relative to the settled line (SPEC
    s.5 step 2; issue 13 point 3). The hum is the coherent part only: its per-period size less
    the noise, so a hum that does not average down is carried at its full size and random
    noise, already in type A, is not counted twice (issue 25 point 3). Lines off the mains
    harmonics get no background term. `warn` is given each line's hum warning (dsp.hum: the
    "hum measured" row of app.records.warnings, printed on the certificate; issue 32)."""
    ref_lines, dut_lines = settled_lines
    hum = mains_hum_from_lines(
        plan,
        background.reference if background.reference_rms is None else background.reference_rms,
        background.dut if background.dut_rms is None else background.dut_rms,
        ref_lines,
        dut_lines,
        max(1, background_periods),
        reference_noise_v=background.reference_noise,
        dut_noise_v=background.dut_noise,
    )
    if warn is not None:
        for text in hum.warnings():
            warn(text)
    return Budget((*budget.components, *hum.components()))
