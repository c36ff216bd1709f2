"""A "true stand" for a non-circular coverage benchmark (issue 25 point 6).

The simulated stand of sim/stand.py draws its systematic deviations from the same budget the
analysis states, so coverage measured on it cannot find a missing or undersized term. Here the
stand's deviations come from its own model, with distributions, sizes and frequency laws the
analysis does not know: reference certificate and its frequency dependence, gains, DAQ gain and
linearity, mounting and a transverse motion growing faster than the stand file says, a
temperature offset, an anti-alias filter phase mismatch proportional to frequency, the error
of the stated skew, amplifier and reference phase. The stand file states its own budget
(sim/stand.toml); bench/coverage_true.py measures whether it covers this truth.

The deviations act on the measured ratio DUT/reference as a smooth complex factor T(f) =
(1 + delta(f)) exp(j phi(f)); `TrueStand.apply` puts it on the recorded DUT channel in the
frequency domain (the recording is periodic in its period, so this is the steady-state LTI
filter exactly). Units: relative (fraction) magnitude, degrees phase, Hz, seconds.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

__all__ = ["TrueStand"]


@dataclass(frozen=True)
class TrueStand:
    """One stand realisation's true deviations (drawn per seed by `draw`)."""

    reference_calibration: float  # relative
    reference_frequency_slope: float  # relative at 5 kHz, linear from 2 kHz
    amplifier_gain: float
    daq_gain: float
    daq_linearity: float
    reference_linearity: float
    mounting: float  # relative below 2 kHz, grows as (f / 2 kHz)^1.2 above
    transverse: float  # relative below 2 kHz, grows as (f / 2 kHz)^1.5 above
    temperature: float
    residual: float
    reference_phase_deg: float
    antialias_deg_per_khz: float  # phase mismatch of the channels' filters, proportional to f
    amplifier_phase_deg: float
    skew_error_s: float  # actual minus stated skew

    @classmethod
    def draw(cls, seed: int, *, scale: float = 1.0) -> TrueStand:
        """A realisation from the true stand's own distributions (not the stand file's).
        `scale` multiplies every deviation (1: the stand as modelled)."""
        rng = np.random.default_rng([seed, 25])

        def arcsine(a: float) -> float:
            return a * math.sin(rng.uniform(0.0, 2.0 * math.pi))

        values = dict(
            reference_calibration=rng.normal(0.0, 0.0023),
            reference_frequency_slope=rng.uniform(-0.0025, 0.0025),
            amplifier_gain=rng.triangular(-0.0028, 0.0, 0.0028),
            daq_gain=rng.normal(0.0, 0.0006) + rng.normal(0.0, 0.0006),
            daq_linearity=rng.uniform(-0.0004, 0.0004),
            reference_linearity=rng.uniform(-0.0004, 0.0004),
            mounting=rng.triangular(-0.0024, 0.0, 0.0024),
            transverse=arcsine(0.0025),  # the DUT's transverse axis at a random angle
            temperature=rng.normal(0.0, 0.00045),
            residual=rng.uniform(-0.0008, 0.0008),
            reference_phase_deg=rng.normal(0.0, 0.23),
            antialias_deg_per_khz=rng.uniform(-0.045, 0.045),
            amplifier_phase_deg=rng.uniform(-0.09, 0.09),
            skew_error_s=rng.uniform(-0.9e-7, 0.9e-7),
        )
        return cls(**{k: float(v) * scale for k, v in values.items()})

    def without(self, *names: str) -> TrueStand:
        """The same stand with the named deviations at zero."""
        return dataclasses.replace(self, **{n: 0.0 for n in names})

    def magnitude_error(self, frequency_hz: np.ndarray) -> np.ndarray:
        """delta(f): the relative error of the measured sensitivity, per frequency."""
        f = np.asarray(frequency_hz, dtype=float)
        above = np.maximum(f / 2000.0, 1.0)
        ramp = np.clip((f - 2000.0) / 3000.0, 0.0, None)
        return (
            self.reference_calibration
            + self.reference_frequency_slope * ramp
            + self.amplifier_gain
            + self.daq_gain
            + self.daq_linearity
            + self.reference_linearity
            + self.mounting * above**1.2
            + self.transverse * above**1.5
            + self.temperature
            + self.residual
        )

    def phase_error_deg(self, frequency_hz: np.ndarray) -> np.ndarray:
        """phi(f): the error of the measured phase (degrees), per frequency."""
        f = np.asarray(frequency_hz, dtype=float)
        return (
            self.reference_phase_deg
            + self.antialias_deg_per_khz * f / 1000.0
            + self.amplifier_phase_deg
            + 360.0 * f * self.skew_error_s
        )

    def factor(self, frequency_hz: np.ndarray) -> np.ndarray:
        """T(f) = (1 + delta(f)) exp(j phi(f)), complex."""
        return (1.0 + self.magnitude_error(frequency_hz)) * np.exp(
            1j * np.radians(self.phase_error_deg(frequency_hz))
        )

    def apply(self, dut_v: np.ndarray, sample_rate_hz: float) -> np.ndarray:
        """The DUT channel as this stand would have recorded it: T(f) applied at every DFT bin
        of the whole record (volts in, volts out; the record is a whole number of periods)."""
        x = np.asarray(dut_v, dtype=float)
        spectrum = np.fft.rfft(x)
        f = np.fft.rfftfreq(x.size, 1.0 / sample_rate_hz)
        factor = self.factor(f)
        factor[0] = 1.0 + self.magnitude_error(np.array([0.0]))[0]  # DC: magnitude only
        return np.fft.irfft(spectrum * factor, n=x.size)
