"""Mains hum at the lines and its share of the uncertainty (issue 13 point 3; SPEC.md s.3,
s.5 step 2, s.7).

A line on a mains harmonic (h f_mains within half a bin of the line, h = 1..plan.mains_harmonics,
SPEC s.3) carries the hum of both channels: hum is periodic with the period, so the periodic
average does not remove it and it biases H = Y/U. To first order, with Y = Y0 + h_y and
U = U0 + h_u (SPEC s.6: H = Y/U),

    H / H0 - 1 = h_y / Y0 - h_u / U0.

The hum's phase against the line is unknown (the mains is not locked to the sample clock), so
each term is a phasor of known length r = |hum| / |line| at a uniformly distributed angle: its
real part (the relative magnitude error) and its imaginary part (the phase error in rad) are
arcsine distributed with variance r^2 / 2 (U-shaped, u = a / sqrt 2, SPEC s.7). With the two
channels' hum independent, the relative standard uncertainty of the sensitivity is

    u_hum = sqrt((r_u^2 + r_y^2) / 2),

carried as one U-shaped component of half-width a = sqrt(r_u^2 + r_y^2) (magnitude, relative)
and one of a in degrees (phase).

Hum amplitude at the line bin, per channel:
- from drive-off background periods (SPEC s.5 step 2) when given: |mean_n X_n[m]| at the line
  bin over the background periods (peak-scaled DFT, dsp.spectral.period_spectrum); noise that
  survives the average is kept in it, a conservative bound;
- otherwise from the acquisition itself: the hum there cannot be told from the line, so the
  largest periodic content found at the non-excited mains-harmonic bins (the neighbouring
  harmonics, h = 1..mains_harmonics, or up to 2 mains_harmonics when none is free) stands in
  for it, and the line is flagged as not separable (`separable` False): a drive-off background
  or a line shifted off the mains harmonic (plan option shift_mains_lines) settles it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp.multisine import Plan
from dsp.spectral import period_spectrum
from dsp.uncertainty import Component, Distribution, Quantity

SOURCE_BACKGROUND = "background"
SOURCE_NEIGHBOURS = "neighbouring mains harmonics"


@dataclass(frozen=True)
class MainsHum:
    """Hum per line (arrays in plan order; zero at lines off the mains harmonics).

    `harmonic` is the mains harmonic a line sits on (0: none); hum amplitudes are peak-scaled
    DFT magnitudes in volts; `relative_uncertainty` is u_hum, the relative standard uncertainty
    of the sensitivity (and the phase's, in rad) that the hum causes (module docstring).
    """

    mains_frequency_hz: float
    nominal_frequencies_hz: np.ndarray
    frequencies_hz: np.ndarray  # actual line frequencies
    harmonic: np.ndarray
    reference_hum_v: np.ndarray
    dut_hum_v: np.ndarray
    reference_relative: np.ndarray  # r_u = |h_u| / |U0|
    dut_relative: np.ndarray  # r_y = |h_y| / |Y0|
    source: str
    background_periods: int = 0

    @property
    def affected(self) -> np.ndarray:
        """Lines on a mains harmonic (bool per line)."""
        return self.harmonic > 0

    @property
    def separable(self) -> bool:
        """True when the hum was measured at the line bins (drive-off background)."""
        return self.source == SOURCE_BACKGROUND

    @property
    def half_width(self) -> np.ndarray:
        """a = sqrt(r_u^2 + r_y^2), the U-shaped half-width per line (module docstring)."""
        return np.hypot(self.reference_relative, self.dut_relative)

    @property
    def relative_uncertainty(self) -> np.ndarray:
        """u_hum = a / sqrt 2 per line (SPEC s.7, U-shaped)."""
        return self.half_width / math.sqrt(2.0)

    def components(self) -> list[Component]:
        """Budget components "mains hum at X Hz" (magnitude, relative) and "mains hum (phase)
        at X Hz" (degrees) for every affected line, U-shaped, limited to that line."""
        out = []
        for k in np.flatnonzero(self.affected):
            f = float(self.nominal_frequencies_hz[k])
            a = float(self.half_width[k])
            if not math.isfinite(a):
                continue
            note = f"{self.harmonic[k]}. mains harmonic, hum from the {self.source}"
            common: dict[str, Any] = dict(
                distribution=Distribution.U_SHAPED,
                min_frequency_hz=float(self.frequencies_hz[k]),
                max_frequency_hz=float(self.frequencies_hz[k]),
                note=note,
            )
            out.append(Component(f"mains hum at {f:g} Hz", a, **common))
            out.append(
                Component(
                    f"mains hum (phase) at {f:g} Hz",
                    math.degrees(a),
                    quantity=Quantity.PHASE,
                    **common,
                )
            )
        return out

    def warnings(self) -> list[str]:
        """One warning per affected line, naming it, the hum and where it came from."""
        out = []
        for k in np.flatnonzero(self.affected):
            f = float(self.nominal_frequencies_hz[k])
            mains = self.harmonic[k] * self.mains_frequency_hz
            text = (
                f"line {f:g} Hz: mains hum at {mains:g} Hz: {100 * self.half_width[k]:.3g} % of "
                f"the line (reference {100 * self.reference_relative[k]:.3g} %, DUT "
                f"{100 * self.dut_relative[k]:.3g} %)"
            )
            if self.separable:
                text += (
                    f", measured in {self.background_periods} drive-off period(s); in the "
                    f"budget as 'mains hum at {f:g} Hz'"
                )
            else:
                text += (
                    ", not separable from the line (no drive-off background): estimated from "
                    f"the {SOURCE_NEIGHBOURS} and carried in the budget; record background "
                    "periods or shift the line off the mains harmonic (--shift-mains)"
                )
            out.append(text)
        return out


def mains_harmonic_of_lines(plan: Plan) -> np.ndarray:
    """The mains harmonic h (1..plan.mains_harmonics) each line's bin sits on, 0 for none
    (within half a bin, as the plan check of SPEC s.3)."""
    resolution = plan.sample_rate_hz / plan.period_samples
    out = np.zeros(len(plan.lines), dtype=int)
    for k, m in enumerate(plan.bins):
        for h in range(1, plan.mains_harmonics + 1):
            if abs(h * plan.mains_frequency_hz / resolution - m) < 0.5:
                out[k] = h
                break
    return out


def mains_hum(
    plan: Plan,
    acquisition: tuple[np.ndarray, np.ndarray],
    background: tuple[np.ndarray, np.ndarray] | None = None,
) -> MainsHum:
    """Hum at each line on a mains harmonic and its relative standard uncertainty.

    `acquisition` and `background` are (reference_v, dut_v) arrays of shape (periods, N) in
    volts: the analysed periods and, if recorded, periods with the drive at 0 V. Line amplitudes
    |U0|, |Y0| come from the acquisition's averaged spectrum (SPEC s.6, `periodic`).
    """
    n = plan.period_samples
    bins = np.asarray(plan.bins)
    harmonic = mains_harmonic_of_lines(plan)
    mean_acq = [_mean_spectrum(x, n) for x in acquisition]
    lines = [np.abs(s[bins]) for s in mean_acq]
    if background is not None and np.asarray(background[0]).size:
        mean_bg = [_mean_spectrum(x, n) for x in background]
        hum = [np.abs(s[bins]) for s in mean_bg]
        source, count = SOURCE_BACKGROUND, int(np.asarray(background[0]).reshape(-1, n).shape[0])
    else:
        free = _free_mains_bins(plan)
        hum = [
            np.full(bins.size, float(np.abs(s[free]).max()) if free.size else np.nan)
            for s in mean_acq
        ]
        source, count = SOURCE_NEIGHBOURS, 0
    affected = harmonic > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        r_u = np.where(affected, hum[0] / lines[0], 0.0)
        r_y = np.where(affected, hum[1] / lines[1], 0.0)
    return MainsHum(
        mains_frequency_hz=plan.mains_frequency_hz,
        nominal_frequencies_hz=np.asarray(plan.nominal_frequencies_hz, dtype=float),
        frequencies_hz=np.asarray(plan.frequencies_hz, dtype=float),
        harmonic=harmonic,
        reference_hum_v=np.where(affected, hum[0], 0.0),
        dut_hum_v=np.where(affected, hum[1], 0.0),
        reference_relative=r_u,
        dut_relative=r_y,
        source=source,
        background_periods=count,
    )


def mains_hum_from_lines(
    plan: Plan,
    background_reference_v: np.ndarray,
    background_dut_v: np.ndarray,
    line_reference_v: np.ndarray,
    line_dut_v: np.ndarray,
    background_periods: int,
) -> MainsHum:
    """As `mains_hum` from per-line amplitudes already at hand (volts, peak-scaled): the
    background's |mean X| at the line bins and the lines' |U0|, |Y0| (the procedure's
    background and settled periods, SPEC s.5)."""
    harmonic = mains_harmonic_of_lines(plan)
    affected = harmonic > 0
    hum_u = np.abs(np.asarray(background_reference_v))
    hum_y = np.abs(np.asarray(background_dut_v))
    with np.errstate(divide="ignore", invalid="ignore"):
        r_u = np.where(affected, hum_u / np.abs(line_reference_v), 0.0)
        r_y = np.where(affected, hum_y / np.abs(line_dut_v), 0.0)
    return MainsHum(
        mains_frequency_hz=plan.mains_frequency_hz,
        nominal_frequencies_hz=np.asarray(plan.nominal_frequencies_hz, dtype=float),
        frequencies_hz=np.asarray(plan.frequencies_hz, dtype=float),
        harmonic=harmonic,
        reference_hum_v=np.where(affected, hum_u, 0.0),
        dut_hum_v=np.where(affected, hum_y, 0.0),
        reference_relative=r_u,
        dut_relative=r_y,
        source=SOURCE_BACKGROUND,
        background_periods=int(background_periods),
    )


def _mean_spectrum(x: np.ndarray, n: int) -> np.ndarray:
    """Peak-scaled spectrum of the mean period (the periodic part; dsp.spectral)."""
    blocks = np.asarray(x, dtype=float).reshape(-1, n)
    return period_spectrum(blocks.mean(axis=0))


def _free_mains_bins(plan: Plan) -> np.ndarray:
    """Bins of mains harmonics that carry no line (h = 1..mains_harmonics, else up to twice)."""
    resolution = plan.sample_rate_hz / plan.period_samples
    lines = set(int(b) for b in plan.bins)
    nyquist = plan.period_samples // 2
    for top in (plan.mains_harmonics, 2 * max(plan.mains_harmonics, 1)):
        free = sorted(
            {
                round(h * plan.mains_frequency_hz / resolution)
                for h in range(1, top + 1)
                if 0 < round(h * plan.mains_frequency_hz / resolution) < nyquist
            }
            - lines
        )
        if free:
            return np.array(free, dtype=np.int64)
    return np.array([], dtype=np.int64)
