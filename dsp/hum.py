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

Hum amplitude at the line bin, per channel (issue 25 point 3):
- from drive-off background periods (SPEC s.5 step 2) when given: the coherent part only. Per
  period the DFT at the line bin holds hum plus noise; the noise power per period sigma^2
  comes from the neighbouring bins that carry neither a line nor a mains harmonic, and
  |hum|^2 = mean_n |X_n|^2 - sigma^2 (floored at 0): random noise is left to type A, not
  counted twice. The per-period size is used, not |mean_n X_n|: a hum whose phase drifts
  little per period does not average down over the L analysed periods, so it is carried at
  its full measured size (a fast-drifting one is then over-, never under-stated);
- otherwise from the acquisition itself: the hum there cannot be told from the line, so the
  largest periodic content found at the non-excited mains-harmonic bins (the neighbouring
  harmonics, h = 1..mains_harmonics, or up to 2 mains_harmonics when none is free) stands in
  for it, leaving out every bin that is a harmonic (2nd..10th) of a line: there the DUT's or
  the exciter's distortion sits (the 3rd harmonic of a 50 Hz line at 150 Hz is not hum). When
  every free mains bin is such a harmonic (a line on 50 Hz), the table motion is removed there
  first: |Y_j - H(f_j) U_j| with H interpolated from the lines cancels the exciter's harmonics
  (on both channels in the ratio H) and leaves the hum's effect on the ratio (carried as the
  combined half-width). The line is flagged as not separable (`separable` False): a
  drive-off background or a line shifted off the mains harmonic (plan option
  shift_mains_lines) settles it.

Hum while driven (issue 32 point 3; `DrivenHum`, `driven_hum`): hum that comes with the drive
(a power-amplifier ground loop) is invisible to the drive-off background. The default plans
move their lines one bin off the mains harmonics (dsp.multisine.mains_shifted_bins), so hum
at a mains harmonic falls on a free bin and leaks onto no line; hum a little off a bin leaks
onto the lines beside it, and dsp.tones locates it in the driven periods' averaged spectra
(in the motion-free residual Y - H U, so the exciter's own non-periodic motion, on both
channels in the ratio, is not taken for hum) and states what reaches each line. A line kept
on a mains harmonic (exact bins) is bounded by its departure from its neighbours' response.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp.mains import mains_harmonic_of_bin
from dsp.multisine import Plan
from dsp.spectral import period_spectrum
from dsp.tones import ON_LINE_BINS, line_leak
from dsp.uncertainty import Budget, Component, Distribution, Quantity

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
    bin_width_hz: float = 0.0  # the plan's resolution: a component applies within half of it

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
            line, half = float(self.frequencies_hz[k]), 0.5 * self.bin_width_hz
            common: dict[str, Any] = dict(
                distribution=Distribution.U_SHAPED,
                min_frequency_hz=max(line - half, 0.0),  # the line's bin, not an exact float
                max_frequency_hz=line + half,
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
            if not math.isfinite(float(self.half_width[k])):
                out.append(
                    f"line {f:g} Hz: mains hum at {mains:g} Hz: not separable from the line and "
                    "not estimated (every free mains-harmonic bin holds a line's harmonic); "
                    "record background periods or shift the line off the mains harmonic "
                    "(--shift-mains)"
                )
                continue
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
    return np.array(
        [
            mains_harmonic_of_bin(int(m), resolution, plan.mains_frequency_hz, plan.mains_harmonics)
            for m in plan.bins
        ],
        dtype=int,
    )


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
        hum = [coherent_hum(x, plan) for x in background]
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
        if source == SOURCE_NEIGHBOURS and not free.size:
            a = _motion_free_residual(plan, mean_acq) / lines[1]
            r_u = r_y = np.where(affected, a / math.sqrt(2.0), 0.0)
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
        bin_width_hz=plan.sample_rate_hz / n,
    )


def coherent_hum(background_v: np.ndarray, plan: Plan) -> np.ndarray:
    """Per line (V, peak): the coherent content at the line bin of drive-off periods,
    sqrt(max(0, mean_n |X_n|^2 - sigma^2)), sigma^2 the per-period noise power from the
    neighbouring bins (module docstring). `background_v` has shape (periods, N) or is flat."""
    n = plan.period_samples
    spectra = period_spectrum(np.asarray(background_v, dtype=float).reshape(-1, n))
    bins = np.asarray(plan.bins)
    power = np.mean(np.abs(spectra[:, bins]) ** 2, axis=0)
    noise = np.array([_noise_power(spectra, int(m), plan) for m in bins])
    return np.sqrt(np.maximum(power - noise, 0.0))


def _noise_power(spectra: np.ndarray, m: int, plan: Plan, reach: int = 8) -> float:
    """Mean |X|^2 per period over up to `reach` bins each side of bin m that carry no line and
    no mains harmonic (volts^2); 0 when there are none."""
    resolution = plan.sample_rate_hz / plan.period_samples
    busy = {int(b) for b in plan.bins}
    busy |= {
        round(h * plan.mains_frequency_hz / resolution)
        for h in range(1, 2 * max(plan.mains_harmonics, 1) + 1)
    }
    nyquist = plan.period_samples // 2
    near = [j for j in range(m - reach, m + reach + 1) if 0 < j < nyquist and j not in busy]
    if not near:
        return 0.0
    return float(np.mean(np.abs(spectra[:, near]) ** 2))


def mains_hum_from_lines(
    plan: Plan,
    background_reference_v: np.ndarray,
    background_dut_v: np.ndarray,
    line_reference_v: np.ndarray,
    line_dut_v: np.ndarray,
    background_periods: int,
    reference_noise_v: np.ndarray | None = None,
    dut_noise_v: np.ndarray | None = None,
) -> MainsHum:
    """As `mains_hum` from per-line amplitudes already at hand (volts, peak-scaled): the
    background's per-period rms |X_n| at the line bins, the per-period noise there (from the
    neighbouring bins; subtracted in power, so noise stays in type A) and the lines' |U0|,
    |Y0| (the procedure's background and settled periods, SPEC s.5)."""
    harmonic = mains_harmonic_of_lines(plan)
    affected = harmonic > 0
    hum_u = _debiased(background_reference_v, reference_noise_v)
    hum_y = _debiased(background_dut_v, dut_noise_v)
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
        bin_width_hz=plan.sample_rate_hz / plan.period_samples,
    )


def _debiased(amplitude_v: np.ndarray, noise_v: np.ndarray | None) -> np.ndarray:
    """sqrt(max(0, |a|^2 - noise^2)) per line; |a| when no noise is given (volts)."""
    a = np.abs(np.asarray(amplitude_v, dtype=float))
    if noise_v is None:
        return a
    return np.sqrt(np.maximum(a**2 - np.asarray(noise_v, dtype=float) ** 2, 0.0))


def _mean_spectrum(x: np.ndarray, n: int) -> np.ndarray:
    """Peak-scaled spectrum of the mean period (the periodic part; dsp.spectral)."""
    blocks = np.asarray(x, dtype=float).reshape(-1, n)
    return period_spectrum(blocks.mean(axis=0))


def _motion_free_residual(plan: Plan, spectra: list[np.ndarray]) -> float:
    """Largest |Y_j - H(f_j) U_j| (V, DUT channel) over the mains-harmonic bins that are line
    harmonics, H interpolated from the lines' Y/U (magnitude and unwrapped phase against
    frequency). Table motion (the exciter's harmonics) shows on both channels in the ratio H
    and cancels; what is left is the hum's effect on the ratio, h_y - H h_u (and any harmonic
    the DUT adds itself, kept: conservative). NaN when there is no such bin."""
    resolution = plan.sample_rate_hz / plan.period_samples
    nyquist = plan.period_samples // 2
    line_bins = {int(b) for b in plan.bins}
    top = 2 * max(plan.mains_harmonics, 1)
    candidates = sorted(
        {round(h * plan.mains_frequency_hz / resolution) for h in range(1, top + 1)} - line_bins
    )
    candidates = [j for j in candidates if 0 < j < nyquist]
    if not candidates:
        return math.nan
    u, y = spectra
    bins = np.asarray(plan.bins)
    ratio = y[bins] / u[bins]
    f = bins * resolution
    order = np.argsort(f)
    fj = np.asarray(candidates) * resolution
    magnitude = np.interp(fj, f[order], np.abs(ratio[order]))
    phase = np.interp(fj, f[order], np.unwrap(np.angle(ratio[order])))
    h = magnitude * np.exp(1j * phase)
    return float(np.max(np.abs(y[candidates] - h * u[candidates])))


LINE_HARMONICS = range(2, 11)  # a line's harmonics that are distortion, never hum


def _free_mains_bins(plan: Plan) -> np.ndarray:
    """Bins of mains harmonics that carry no line and no line's harmonic (h = 1..
    mains_harmonics, else up to twice; module docstring)."""
    resolution = plan.sample_rate_hz / plan.period_samples
    nyquist = plan.period_samples // 2
    lines = {int(b) for b in plan.bins}
    lines |= {int(b) * h for b in plan.bins for h in LINE_HARMONICS}
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


NEGLIGIBLE_HUM = 1e-4  # relative: hum while driven below 0.01 % at a line is not stated
DRIVEN = "hum while driven"


@dataclass(frozen=True)
class DrivenHum:
    """Hum (any tone at non-excited bins) measured in the driven periods themselves, per line
    in plan order (issue 32 point 3). A drive-off background cannot see hum that comes with
    the drive (a power-amplifier ground loop); the averaged driven spectra can, at the bins
    beside the lines and at the free mains-harmonic bins. Table motion (the exciter's own
    non-periodic motion, a transient) is on both channels in the ratio H and cancels in it,
    so the tones are sought in the motion-free residual E = Y - H U (H interpolated from the
    lines): what is left is the hum's effect on the ratio, h_y - H h_u. `relative` is what
    the tones beside a line leak onto it (dsp.tones) over |Y| at the line, carried as a
    U-shaped half-width (phase unknown, as MainsHum); `tone_hz` the nearest tone (NaN:
    none); `separable` False where a tone is within dsp.tones.ON_LINE_BINS of the line."""

    nominal_frequencies_hz: np.ndarray
    frequencies_hz: np.ndarray
    tone_hz: np.ndarray
    relative: np.ndarray
    separable: np.ndarray
    bin_width_hz: float
    on_mains: np.ndarray | None = None  # lines kept on a mains harmonic (exact bins), bool

    @property
    def affected(self) -> np.ndarray:
        """Lines the hum while driven reaches (bool): not separable, or over NEGLIGIBLE_HUM."""
        return ~self.separable | (self.relative >= NEGLIGIBLE_HUM)

    def component_name(self, k: int | np.integer, phase: bool = False) -> str:
        f = float(self.nominal_frequencies_hz[k])
        return f"{DRIVEN}{' (phase)' if phase else ''} at {f:g} Hz"

    def components(self) -> list[Component]:
        """Per affected line: "hum while driven at X Hz" (relative) and its phase twin
        (degrees), U-shaped, limited to the line's bin."""
        out = []
        for k in np.flatnonzero(self.affected):
            a = float(self.relative[k])
            if not math.isfinite(a):
                continue
            line, half = float(self.frequencies_hz[k]), 0.5 * self.bin_width_hz
            common: dict[str, Any] = dict(
                distribution=Distribution.U_SHAPED,
                min_frequency_hz=max(line - half, 0.0),
                max_frequency_hz=line + half,
                note=f"tone at {self.tone_hz[k]:.4g} Hz beside the line, in the driven periods",
            )
            out.append(Component(self.component_name(k), a, **common))
            out.append(
                Component(
                    self.component_name(k, phase=True),
                    math.degrees(a),
                    quantity=Quantity.PHASE,
                    **common,
                )
            )
        return out

    def warnings(self) -> list[str]:
        """One warning per affected line, naming the line, the tone and its size."""
        out = []
        for k in np.flatnonzero(self.affected):
            f, tone = float(self.nominal_frequencies_hz[k]), float(self.tone_hz[k])
            size = f"{100 * self.relative[k]:.3g} % of the line"
            if self.on_mains is not None and self.on_mains[k] and not math.isfinite(tone):
                out.append(
                    f"line {f:g} Hz: kept on a mains harmonic (exact bins): {DRIVEN} at the "
                    "line cannot be told from it; bounded by the line's departure from its "
                    f"neighbours' response, {size}, in the budget as "
                    f"'{self.component_name(k)}'"
                )
                continue
            if not self.separable[k]:
                out.append(
                    f"line {f:g} Hz: {DRIVEN} at {tone:.4g} Hz, within {ON_LINE_BINS:g} bin of "
                    f"the line at {self.frequencies_hz[k]:g} Hz: not separable from it "
                    f"(estimated {size}); remove the hum, or change the period or the line"
                )
                continue
            out.append(
                f"line {f:g} Hz: {DRIVEN} at {tone:.4g} Hz beside the line: {size}, measured at "
                f"the non-excited bins of the driven periods; in the budget as "
                f"'{self.component_name(k)}'"
            )
        return out

    def merged_into(self, budget: Budget) -> Budget:
        """`budget` with these components; one of the same name already there is kept only
        when larger (a stored run's re-analysis carries the hum it measures)."""
        return merged(budget, self.components())


def merged(budget: Budget, components: list[Component]) -> Budget:
    """`budget` with `components`: a component of the same name is replaced when the new one
    is larger (the hum measured now), else kept; new names appended."""
    new = {c.name: c for c in components}
    kept = []
    for c in budget.components:
        fresh = new.get(c.name)
        if fresh is not None and fresh.value > c.value:
            continue
        new.pop(c.name, None)
        kept.append(c)
    return Budget((*kept, *new.values()))


def driven_hum(plan: Plan, reference: np.ndarray, dut: np.ndarray) -> DrivenHum:
    """Hum while driven from the driven periods' averaged spectra (complex, one-sided, V,
    peak-scaled: dsp.spectral.period_spectrum of the mean period) of both channels."""
    bins = np.asarray(plan.bins)
    u, y = np.asarray(reference), np.asarray(dut)
    every = np.arange(u.size)
    residual = y - _interpolated_ratio(plan, u, y, every) * u
    residual[bins] = y[bins]  # the lines: not free bins (dsp.tones leaves them out)
    leak = line_leak(residual, bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = leak.leak_v / np.abs(y[bins])
    resolution = plan.sample_rate_hz / plan.period_samples
    on_mains = mains_harmonic_of_lines(plan) > 0
    tone_bin = leak.tone_bin.copy()
    if on_mains.any():
        departure = _departure_from_neighbours(plan, u[bins], y[bins], on_mains)
        larger = on_mains & (departure > relative)
        relative = np.where(larger, departure, relative)
        tone_bin = np.where(larger, np.nan, tone_bin)
    return DrivenHum(
        nominal_frequencies_hz=np.asarray(plan.nominal_frequencies_hz, dtype=float),
        frequencies_hz=np.asarray(plan.frequencies_hz, dtype=float),
        tone_hz=tone_bin * resolution,
        relative=relative,
        separable=leak.separable,
        bin_width_hz=resolution,
        on_mains=on_mains,
    )


NEIGHBOUR_LINES = 2  # lines each side whose response bounds a line kept on a mains harmonic


def _departure_from_neighbours(
    plan: Plan, u: np.ndarray, y: np.ndarray, on_mains: np.ndarray
) -> np.ndarray:
    """Per line on a mains harmonic (`on_mains`), |H / H_fit - 1|: H = Y/U at the line
    against a quadratic in log f through up to NEIGHBOUR_LINES lines each side that are not
    on a mains harmonic (log |H| and unwrapped phase); hum while driven on the line's own bin
    shows as such a departure (a smooth response has none). 0 where too few neighbours."""
    out = np.zeros(on_mains.size)
    ratio = y / u
    log_f = np.log(np.asarray(plan.frequencies_hz, dtype=float))
    clean = np.flatnonzero(~on_mains)
    for k in np.flatnonzero(on_mains):
        below = [j for j in clean if log_f[j] < log_f[k]][-NEIGHBOUR_LINES:]
        above = [j for j in clean if log_f[j] > log_f[k]][:NEIGHBOUR_LINES]
        near = below + above
        if not below or not above or len(near) < 3:
            continue
        x = log_f[near]
        magnitude = np.polyval(np.polyfit(x, np.log(np.abs(ratio[near])), 2), log_f[k])
        angles = np.unwrap(np.angle(ratio[near]))
        phase = np.polyval(np.polyfit(x, angles, 2), log_f[k])
        fit = np.exp(magnitude + 1j * phase)
        out[k] = float(abs(ratio[k] / fit - 1.0))
    return out


def _interpolated_ratio(plan: Plan, u: np.ndarray, y: np.ndarray, bins: np.ndarray) -> np.ndarray:
    """H = Y/U of the lines interpolated at `bins` (magnitude and unwrapped phase against
    frequency; held beyond the first and last line)."""
    lines = np.asarray(plan.bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = y[lines] / u[lines]
    order = np.argsort(lines)
    magnitude = np.interp(bins, lines[order], np.abs(ratio[order]))
    phase = np.interp(bins, lines[order], np.unwrap(np.angle(ratio[order])))
    return magnitude * np.exp(1j * phase)


def driven_hum_of_periods(plan: Plan, acquisition: tuple[np.ndarray, np.ndarray]) -> DrivenHum:
    """As `driven_hum` from the analysed periods (reference_v, dut_v), shape (periods, N)."""
    n = plan.period_samples
    return driven_hum(plan, *(_mean_spectrum(x, n) for x in acquisition))
