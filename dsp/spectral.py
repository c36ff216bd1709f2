"""Per-period spectra and the streaming estimators of SPEC.md section 6.

Spectra are scaled to peak amplitude: X[m] = (2/N) sum_i x(i) exp(-j 2 pi m i / N) (seed eq. 2
up to the factor 2 T_p / N), so a line A sin(2 pi m i/N + phi) gives X[m] = A exp(j(phi - pi/2)).
One period per segment, rectangular window: lines on bins have no leakage.

`SpectralAccumulator` takes one period (or a batch of periods) of both channels at a time and
keeps only running means and co-moments per bin (Welford/Chan updates), so its memory does not
grow with the number of periods and batches merge exactly in any order. At any time it gives:

- `periodic` (default, errors-in-variables): H = mean(Y_n) / mean(U_n); relative type A
  variance [s2_Y/|Y|^2 + s2_U/|U|^2 - 2 Re(s2_YU/(Y conj U))]/L, half on magnitude, half on phase.
- `h1`: H1 = sum conj(U_n) Y_n / sum |U_n|^2 (seed eq. 5-7 with averaged spectra); type A from
  the coherence as the least-squares residual of Y_n on U_n: one complex parameter fitted, so
  L - 1 complex residuals, var(H1)/|H1|^2 = (1 - g2) / (g2 (L - 1)) (Bendat & Piersol's
  (1 - g2)/(g2 L) with the small-sample L - 1), half on magnitude, half on phase; plus the
  bias term of H1 under reference-channel noise, E[H1] = H |U|^2/(|U|^2 + s2_U) (seed eq. 5-7
  with noisy U_n): its relative size s2_U/|U_bar|^2 is added in quadrature (H1 itself is left
  uncorrected so that it stays equal to scipy's csd/welch, SPEC s.6).
- `seed`: H_n = Y_n / U_n per period, |H| = mean |H_n| (seed eq. 8, 11), phase = circular mean
  of arg H_n (seed eq. 9, 12 taken on the circle), u_A = s(|H_n|)/sqrt(L)/mean (seed eq. 15-17
  as corrected in SPEC s.7), phase u_A = circular standard deviation / sqrt(L), its variance
  -2 ln R scaled by L/(L - 1) (the mean resultant length R is estimated from the same periods,
  as ddof = 1 does for s(|H_n|)).

Small samples (issue 13 point 5): a type A uncertainty is stated only from `MIN_PERIODS`
periods on (periodic and h1: 3, seed: 4); below that it is NaN, and `check_periods` refuses a
run planned with fewer. Degrees of freedom: 2 (L - 1) for the complex estimators (circular
noise at a DFT bin), L - 1 for `seed`; k then follows from Student's t (SPEC s.7).

Distortion (issue 13 point 4): periodic content at a harmonic bin is counted only where the
statistic T = |mean X|^2 / (s2_X / L) exceeds the F(2, 2 (L - 1)) quantile at a false-alarm
rate of `DISTORTION_FALSE_ALARM` per run, Sidak-corrected over the harmonic bins tested on the
channel: alpha_bin = 1 - (1 - alpha_run)^(1/n). With circular Gaussian noise and no periodic
content, |mean X|^2 / (sigma^2/L) ~ chi2(2)/2 and s2_X / sigma^2 ~ chi2(2 (L - 1))/(2 (L - 1)),
so T ~ F(2, 2 (L - 1)) exactly.

Coherence g2 = |sum conj(U)Y|^2 / (sum|U|^2 sum|Y|^2) per line. The noise floor per line is the
mean over nearby non-excited bins of the across-period variance (random noise only, since
periodic content stays in the mean); distortion per line is the periodic content at its 2nd..5th
harmonic bins (when those are not lines), counted where it stands clear of the averaged noise
and bias-corrected for it, relative to the line.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from dsp import nonlinear
from dsp.estimators import DEFAULT_ESTIMATOR as DEFAULT_ESTIMATOR
from dsp.estimators import ESTIMATORS as ESTIMATORS
from dsp.nonlinear import NonlinearEstimate
from dsp.quantiles import f2_quantile  # not scipy.special (issue 34): F(2, n) in closed form

HARMONICS = (2, 3, 4, 5)
FLOOR_HALF_WIDTH_BINS = 12
DISTORTION_FALSE_ALARM = 0.01  # probability per run that noise alone counts as distortion
MIN_PERIODS = {"periodic": 3, "h1": 3, "seed": 4, "lpm": 1}  # fewest periods with a stated type A
RECORD_ESTIMATORS = ("lpm",)  # from one record (dsp.lpm_record), not from this accumulator


def check_periods(estimator: str, periods: int) -> None:
    """Refuse a number of periods too small for an honest type A with `estimator`.

    ValueError naming "periods", the estimator and its minimum (`MIN_PERIODS`; issue 13
    point 5: below it the k = 2 coverage of the type A interval is not reached).
    """
    if estimator not in ESTIMATORS:
        raise ValueError(f"estimator: unknown {estimator!r}; choose one of {ESTIMATORS}")
    need = MIN_PERIODS[estimator]
    if int(periods) < need:
        raise ValueError(
            f"periods: the {estimator} estimator needs at least {need} periods for a type A "
            f"uncertainty that can be stated honestly, got {periods}"
        )


def detection_threshold(periods: int, tests: int, false_alarm: float = DISTORTION_FALSE_ALARM):
    """Threshold on T = |mean X|^2 / (s2_X / L) at one bin: the F(2, 2 (L - 1)) quantile at
    alpha_bin = 1 - (1 - false_alarm)^(1/tests) (Sidak over `tests` bins; module docstring)."""
    alpha = -np.expm1(np.log1p(-false_alarm) / max(int(tests), 1))
    return f2_quantile(2 * (periods - 1), 1.0 - alpha)


def period_spectrum(blocks: np.ndarray) -> np.ndarray:
    """Peak-scaled one-sided DFT (2/N) rfft of each period along the last axis (volts)."""
    n = blocks.shape[-1]
    return np.fft.rfft(blocks, axis=-1) * (2.0 / n)


def dft_at(
    blocks: np.ndarray, frequencies_hz: Sequence[float] | np.ndarray, sample_rate_hz: float
) -> np.ndarray:
    """Peak-scaled DFT of each block (last axis) evaluated at arbitrary frequencies in Hz.

    For lines off the block's bin grid (the seed's segment protocol); leakage is not removed.
    """
    n = blocks.shape[-1]
    phase = np.outer(np.asarray(frequencies_hz, dtype=float), np.arange(n)) / sample_rate_hz
    kernel = np.exp(-2j * np.pi * phase) * (2.0 / n)
    return blocks @ kernel.T


SETTLE_NOISE_SIGMAS = 6.0  # a noise-only difference exceeds 6 sigma with probability e^-18
SETTLE_INTERFERENCE_MARGIN = 1.5  # x a tone's measured change at the line (dsp.tones)


def periods_agree(
    previous: np.ndarray,
    current: np.ndarray,
    noise: np.ndarray,
    tolerance: float,
    interference: np.ndarray | None = None,
) -> bool:
    """Settle test (SPEC s.5 step 2): do two consecutive periods' complex line spectra agree
    at every line of every channel? Agreement: |current - previous| within `tolerance`
    (relative) of the line or within 6 standard deviations `noise` of one period's noise
    (same shape, volts); the difference of two noise-only periods has variance 2 noise^2.
    `interference` (V, same shape): what a tone beside the line changes there from one period
    to the next (hum a little off a bin, dsp.tones), allowed on top: it never settles."""
    return bool(np.all(settle_excess(previous, current, noise, tolerance, interference) <= 0))


def settle_excess(
    previous: np.ndarray,
    current: np.ndarray,
    noise: np.ndarray,
    tolerance: float,
    interference: np.ndarray | None = None,
) -> np.ndarray:
    """Per line and channel, how far (V) the change from `previous` exceeds what
    `periods_agree` allows (<= 0: agrees)."""
    current = np.asarray(current)
    allowed = np.maximum(tolerance * np.abs(current), SETTLE_NOISE_SIGMAS * np.asarray(noise))
    if interference is not None:
        allowed = allowed + SETTLE_INTERFERENCE_MARGIN * np.asarray(interference)
    return np.abs(current - np.asarray(previous)) - allowed


@dataclass(frozen=True)
class Estimate:
    """Per-line estimate after `periods` periods (arrays are per line, in plan order).

    `response` is H = Y/U in V/V; type A values are standard uncertainties: relative for the
    magnitude, radians for the phase, with `dof` degrees of freedom: 2 (L - 1) for the complex
    estimators, L - 1 for `seed` (NaN before L = 2).
    Amplitudes and noise are peak-scaled DFT magnitudes in volts; SNR is per period, in dB;
    distortion is the rss of harmonics 2..5 relative to the line (a ratio); `nonlinear` the
    DUT's distortion measured at the detection bins (dsp.nonlinear; when found, `response`
    is the best linear approximation and the type A carries the model's uncertainty).
    """

    estimator: str
    periods: int
    response: np.ndarray
    relative_type_a: np.ndarray
    phase_type_a_rad: np.ndarray
    dof: float | np.ndarray  # one value, or one per line (stepped sine)
    coherence: np.ndarray
    reference_amplitude_v: np.ndarray
    dut_amplitude_v: np.ndarray
    reference_noise_v: np.ndarray
    dut_noise_v: np.ndarray
    reference_distortion: np.ndarray
    dut_distortion: np.ndarray
    nonlinear: NonlinearEstimate | None = None  # the DUT's distortion, when it was measured

    @property
    def reference_snr_db(self) -> np.ndarray:
        return _snr_db(self.reference_amplitude_v, self.reference_noise_v)

    @property
    def dut_snr_db(self) -> np.ndarray:
        return _snr_db(self.dut_amplitude_v, self.dut_noise_v)


def _type_a_dof(estimator: str, periods: int) -> float:
    """Degrees of freedom of the type A estimate after `periods` periods.

    `periodic` and `h1` estimate their variance from complex spectra; noise at a DFT bin is
    circular (real and imaginary parts independent, of equal variance), so both parts estimate
    it: 2 (L - 1) degrees of freedom. `seed` takes the sample variance of |H_n|: L - 1.
    Checked by simulation: with L = 4, L - 1 gives 98-99 % coverage at k = 2 nominal.
    NaN below `MIN_PERIODS` (no type A is stated there).
    """
    if periods < MIN_PERIODS[estimator]:
        return float("nan")
    return float(periods - 1) if estimator == "seed" else float(2 * (periods - 1))


def _snr_db(amplitude: np.ndarray, noise: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore", invalid="ignore"):
        return 20.0 * np.log10(amplitude / noise)


class _Moments:
    """Running count, complex means and (co)moment sums of two spectra, mergeable (Chan et al.)."""

    def __init__(self, size: int):
        self.count = 0
        self.mean_u = np.zeros(size, complex)
        self.mean_y = np.zeros(size, complex)
        self.m2_u = np.zeros(size)  # sum |U_n - mean U|^2
        self.m2_y = np.zeros(size)
        self.c_yu = np.zeros(size, complex)  # sum (Y_n - mean Y) conj(U_n - mean U)

    def add(self, u: np.ndarray, y: np.ndarray) -> None:
        """Merge a batch: u, y of shape (periods, size)."""
        nb = u.shape[0]
        mean_u_b = u.mean(axis=0)
        mean_y_b = y.mean(axis=0)
        du = u - mean_u_b
        dy = y - mean_y_b
        m2_u_b = np.einsum("ij,ij->j", du.real, du.real) + np.einsum("ij,ij->j", du.imag, du.imag)
        m2_y_b = np.einsum("ij,ij->j", dy.real, dy.real) + np.einsum("ij,ij->j", dy.imag, dy.imag)
        c_yu_b = np.einsum("ij,ij->j", dy, du.conj())
        na = self.count
        n = na + nb
        delta_u = mean_u_b - self.mean_u
        delta_y = mean_y_b - self.mean_y
        weight = na * nb / n
        self.mean_u += delta_u * (nb / n)
        self.mean_y += delta_y * (nb / n)
        self.m2_u += m2_u_b + weight * (delta_u.real**2 + delta_u.imag**2)
        self.m2_y += m2_y_b + weight * (delta_y.real**2 + delta_y.imag**2)
        self.c_yu += c_yu_b + weight * delta_y * delta_u.conj()
        self.count = n


class _SeedMoments:
    """Running statistics of the per-period ratio H_n = Y_n / U_n (seed eq. 8-12, 15)."""

    def __init__(self, size: int):
        self.count = 0
        self.mean_abs = np.zeros(size)
        self.m2_abs = np.zeros(size)
        self.sum_unit = np.zeros(size, complex)  # sum exp(j arg H_n)

    def add(self, ratio: np.ndarray) -> None:
        magnitude = np.abs(ratio)
        nb = ratio.shape[0]
        mean_b = magnitude.mean(axis=0)
        m2_b = ((magnitude - mean_b) ** 2).sum(axis=0)
        n = self.count + nb
        delta = mean_b - self.mean_abs
        self.m2_abs += m2_b + delta**2 * self.count * nb / n
        self.mean_abs += delta * nb / n
        with np.errstate(invalid="ignore", divide="ignore"):
            self.sum_unit += (ratio / magnitude).sum(axis=0)
        self.count = n


class SpectralAccumulator:
    """Streaming per-line statistics of the reference (u) and DUT (y) channels.

    `bins` are the line bins of a period of `period_samples` samples. With `track_floor`
    (default) every rfft bin is tracked too, for the noise and distortion floor; memory is
    O(period_samples), independent of the number of periods.
    """

    def __init__(
        self,
        period_samples: int,
        bins: Sequence[int] | np.ndarray,
        *,
        track_floor: bool = True,
        nonlinear_excluded_bins: Iterable[int] | None = None,
    ):
        self.period_samples = int(period_samples)
        # issue 32 point 4: with the bins to leave out (mains harmonics), the periodic and h1
        # estimates measure the DUT's distortion at the detection bins of the mean period and
        # state the best linear approximation (dsp.nonlinear); None: not measured
        self.nonlinear_excluded = (
            None if nonlinear_excluded_bins is None else tuple(nonlinear_excluded_bins)
        )
        self.bins = np.asarray(bins, dtype=np.int64)
        if self.bins.ndim != 1 or self.bins.size == 0:
            raise ValueError("accumulator: needs at least one line bin")
        n_bins = self.period_samples // 2 + 1
        if track_floor and (self.bins.min() < 1 or self.bins.max() >= n_bins):
            raise ValueError(f"accumulator: line bins must lie in 1..{n_bins - 1}")
        self.track_floor = track_floor
        self._lines = _Moments(self.bins.size)
        self._seed = _SeedMoments(self.bins.size)
        self._bins = _Moments(n_bins) if track_floor else None
        if track_floor:
            self._floor_bins, self._harmonic_bins = _floor_layout(self.bins, self.period_samples)

    @property
    def periods(self) -> int:
        """Number of periods accumulated so far (L)."""
        return self._lines.count

    def mean_spectra(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The averaged spectra of every bin (reference, DUT; complex, V, peak-scaled), or
        None without `track_floor` or before a period."""
        if self._bins is None or self._bins.count == 0:
            return None
        return self._bins.mean_u.copy(), self._bins.mean_y.copy()

    def add_period(self, reference_v: np.ndarray, dut_v: np.ndarray) -> None:
        """Add one period (N samples in volts) of the reference and DUT channels."""
        self.add_periods(np.asarray(reference_v)[None, :], np.asarray(dut_v)[None, :])

    def add_periods(self, reference_v: np.ndarray, dut_v: np.ndarray) -> None:
        """Add a batch of periods, arrays of shape (periods, N) in volts."""
        reference_v = np.asarray(reference_v, dtype=float)
        dut_v = np.asarray(dut_v, dtype=float)
        expected = (reference_v.shape[0], self.period_samples)
        if reference_v.ndim != 2 or reference_v.shape != expected or dut_v.shape != expected:
            raise ValueError(
                f"accumulator: expected periods of {self.period_samples} samples for both "
                f"channels, got {reference_v.shape} and {dut_v.shape}"
            )
        if reference_v.shape[0] == 0:
            return
        spectrum_u = period_spectrum(reference_v)
        spectrum_y = period_spectrum(dut_v)
        if self._bins is not None:
            self._bins.add(spectrum_u, spectrum_y)
        self.add_line_spectra(spectrum_u[:, self.bins], spectrum_y[:, self.bins])

    def add_line_spectra(self, reference: np.ndarray, dut: np.ndarray) -> None:
        """Add complex line spectra directly, shape (periods, lines) (e.g. off-grid segments)."""
        reference = np.atleast_2d(np.asarray(reference, dtype=complex))
        dut = np.atleast_2d(np.asarray(dut, dtype=complex))
        if reference.shape != dut.shape or reference.shape[1] != self.bins.size:
            raise ValueError(
                f"accumulator: expected (periods, {self.bins.size}) line spectra, "
                f"got {reference.shape} and {dut.shape}"
            )
        self._lines.add(reference, dut)
        with np.errstate(divide="ignore", invalid="ignore"):
            self._seed.add(dut / reference)

    def estimate(self, estimator: str = "periodic") -> Estimate:
        """Current per-line estimate with the named estimator (`periodic`, `h1`, `seed`)."""
        if estimator in RECORD_ESTIMATORS:
            raise ValueError(f"estimator: {estimator} analyses one record (dsp.lpm_record)")
        if estimator not in ESTIMATORS:
            raise ValueError(f"estimator: unknown {estimator!r}; choose one of {ESTIMATORS}")
        m = self._lines
        count = m.count
        if count == 0:
            raise ValueError("accumulator: no period has been added yet")
        stated = count >= MIN_PERIODS[estimator]  # below: no honest type A (NaN)
        with np.errstate(divide="ignore", invalid="ignore"):
            sum_uu = count * np.abs(m.mean_u) ** 2 + m.m2_u
            sum_yy = count * np.abs(m.mean_y) ** 2 + m.m2_y
            sum_uy = count * m.mean_u.conj() * m.mean_y + m.c_yu
            coherence = np.abs(sum_uy) ** 2 / (sum_uu * sum_yy)
            coherence = np.minimum(coherence, 1.0)
            if estimator == "periodic":
                response = m.mean_y / m.mean_u
                if stated:
                    s2_u = m.m2_u / (count - 1)
                    s2_y = m.m2_y / (count - 1)
                    s2_yu = m.c_yu / (count - 1)
                    relative_var = (
                        s2_y / np.abs(m.mean_y) ** 2
                        + s2_u / np.abs(m.mean_u) ** 2
                        - 2.0 * np.real(s2_yu / (m.mean_y * m.mean_u.conj()))
                    ) / count
                    relative_var = np.maximum(relative_var, 0.0)
                    u_mag = u_phase = np.sqrt(relative_var / 2.0)
                else:
                    u_mag = u_phase = np.full(self.bins.size, np.nan)
            elif estimator == "h1":
                response = sum_uy / sum_uu
                if stated:
                    # residual variance of the fit, L - 1 complex dof (module docstring)
                    relative_var = np.maximum(1.0 - coherence, 0.0) / (coherence * (count - 1))
                    # bias of H1 under reference noise, s2_U/|U_bar|^2 (module docstring)
                    bias = (m.m2_u / (count - 1)) / np.abs(m.mean_u) ** 2
                    u_mag = np.sqrt(relative_var / 2.0 + bias**2)
                    u_phase = np.sqrt(relative_var / 2.0)
                else:
                    u_mag = u_phase = np.full(self.bins.size, np.nan)
            else:
                s = self._seed
                resultant = np.abs(s.sum_unit) / count
                response = s.mean_abs * np.exp(1j * np.angle(s.sum_unit))
                if stated:
                    u_mag = np.sqrt(s.m2_abs / (count - 1)) / np.sqrt(count) / s.mean_abs
                    # circular variance -2 ln R, scaled L/(L - 1) like ddof = 1 (docstring)
                    circular_var = -2.0 * np.log(np.minimum(resultant, 1.0)) * count / (count - 1)
                    circular_sd = np.sqrt(circular_var)
                    u_phase = circular_sd / np.sqrt(count)
                else:
                    u_mag = u_phase = np.full(self.bins.size, np.nan)
        found = None
        dof: float | np.ndarray = _type_a_dof(estimator, count)
        if stated and estimator in ("periodic", "h1"):
            found = self._nonlinear(response)
            if found is not None and found.found:
                carried = nonlinear.carry(response, u_mag, u_phase, dof, found)
                response, u_mag, u_phase = (
                    carried.response,
                    carried.magnitude_u,
                    carried.phase_u_rad,
                )
                dof = carried.dof
        noise_u, noise_y, dist_u, dist_y = self._floor()
        return Estimate(
            estimator=estimator,
            periods=count,
            response=response,
            relative_type_a=np.asarray(u_mag, dtype=float),
            phase_type_a_rad=np.asarray(u_phase, dtype=float),
            dof=dof,
            coherence=coherence,
            reference_amplitude_v=np.abs(m.mean_u),
            dut_amplitude_v=np.abs(m.mean_y),
            reference_noise_v=noise_u,
            dut_noise_v=noise_y,
            reference_distortion=dist_u,
            dut_distortion=dist_y,
            nonlinear=found,
        )

    def _nonlinear(self, response: np.ndarray) -> NonlinearEstimate | None:
        """The DUT's distortion at the detection bins of the mean period (when asked for)."""
        if self.nonlinear_excluded is None or self._bins is None:
            return None
        b, n = self._bins, self.period_samples
        reference = np.fft.irfft(b.mean_u, n) * (n / 2.0)
        try:
            return nonlinear.estimate(
                b.mean_y,
                b.mean_u,
                self.bins,
                b.mean_u[self.bins],
                response,
                reference,
                excluded_bins=self.nonlinear_excluded,
            )
        except ValueError:  # no signal at the lines: dsp.calibration names the dead channel
            return None

    def _floor(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per-line noise (V, peak-scaled, per period) and harmonic distortion (ratio)."""
        m = self._lines
        count = m.count
        nan = np.full(self.bins.size, np.nan)
        if self._bins is None:
            if count < 2:
                return nan, nan.copy(), nan.copy(), nan.copy()
            return (
                np.sqrt(m.m2_u / (count - 1)),
                np.sqrt(m.m2_y / (count - 1)),
                nan,
                nan.copy(),
            )
        b = self._bins
        results = []
        tests = sum(idx.size for idx in self._harmonic_bins)  # harmonic bins tested per channel
        threshold = detection_threshold(count, tests) if count >= 2 else np.nan
        for mean, m2 in ((b.mean_u, b.m2_u), (b.mean_y, b.m2_y)):
            if count >= 2:
                noise_power = m2 / (count - 1)
            else:  # one period: noise and distortion cannot be told apart; conservative
                noise_power = np.abs(mean) ** 2
            floor = np.array([noise_power[idx].mean() for idx in self._floor_bins])
            power = np.abs(mean) ** 2
            if count >= 2:
                # periodic content only where T = power / (s2 / L) exceeds the F(2, 2(L-1))
                # threshold at 1 % false alarms per run (module docstring), bias-corrected
                averaged_noise = noise_power / count
                with np.errstate(divide="ignore", invalid="ignore"):
                    detected = power > threshold * averaged_noise
                periodic = np.where(detected, power - averaged_noise, 0.0)
            else:
                periodic = power
            line_power = np.abs(mean[self.bins]) ** 2
            harmonic_power = np.array([periodic[idx].sum() for idx in self._harmonic_bins])
            with np.errstate(divide="ignore", invalid="ignore"):
                distortion = np.sqrt(harmonic_power / line_power)
            results.append((np.sqrt(floor), distortion))
        (noise_u, dist_u), (noise_y, dist_y) = results
        return noise_u, noise_y, dist_u, dist_y


def _floor_layout(
    bins: np.ndarray, period_samples: int
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """For each line: nearby non-excited bins (for the floor) and its free harmonic bins."""
    n_bins = period_samples // 2 + 1
    line_set = set(int(b) for b in bins)

    def fold(b: int) -> int:
        b %= period_samples
        return period_samples - b if b > period_samples // 2 else b

    harmonic_set = {fold(h * int(b)) for b in bins for h in HARMONICS}
    # vectorised: a Python loop over every bin held the GIL for tens of ms at the start of a
    # live run (the GUI's longest stall, issue 34.6)
    all_bins = np.arange(n_bins, dtype=np.int64)
    excluded = np.fromiter(line_set | harmonic_set | {0}, dtype=np.int64)
    free = all_bins[~np.isin(all_bins, excluded)]
    if free.size == 0:
        lines = np.fromiter(line_set, dtype=np.int64)
        free = all_bins[1:][~np.isin(all_bins[1:], lines)]
    floor_bins = []
    for b in bins:
        # `free` is sorted: the bins within the half-width are one slice
        lo = int(np.searchsorted(free, b - FLOOR_HALF_WIDTH_BINS, side="left"))
        hi = int(np.searchsorted(free, b + FLOOR_HALF_WIDTH_BINS, side="right"))
        near = free[lo:hi]
        if near.size < 4:
            near = free[np.argsort(np.abs(free - b))[: min(2 * FLOOR_HALF_WIDTH_BINS, free.size)]]
        floor_bins.append(near)
    harmonic_bins = []
    for b in bins:
        own = sorted({fold(h * int(b)) for h in HARMONICS} - line_set - {0})
        harmonic_bins.append(np.array(own, dtype=np.int64))
    return floor_bins, harmonic_bins
