"""Local polynomial method (LPM), errors-in-variables with the drive as reference (issue 26).

One analysed record (a whole number of periods of a multisine whose drive r is periodic over
the record; any fade-in lies before it) gives, per excited line l at record bin k_l, the
sensitivity ratio H = DUT/reference, its type A uncertainty and the start-up transient.
Clean-room from the equations of Pintelon & Schoukens, "System Identification: a frequency
domain approach", 2nd ed. (Wiley/IEEE 2012), ch. 7 (nonparametric FRF measurement, local
polynomial method), and Pintelon et al., "Estimation of nonparametric noise and FRF models for
multivariable systems, Part I: theory", MSSP 24 (2010) 573-595; the relations are written out
here (no toolbox code used):

  (1) for each output z in {y (DUT), u (reference)}, at every DFT bin k of the record
      Z(k) = G_zr(k) R(k) + T_z(k) + V_z(k),
      G_zr the FRF from the drive, T_z the transient (leakage) term, smooth in k, V_z noise.
  (2) R is periodic over the record, so R(k) = 0 at every bin that is not a line: there
      Z(k_l + r) = T_z(k_l + r) + V_z(k_l + r), and T_z(k_l + r) = sum_s t_s r^s, s = 0..order.
  (3) Fitting (2) by least squares on the window W_l (the `bins` nearest non-excited bins,
      skipping other lines, DC, Nyquist and excluded bins such as mains harmonics) gives the
      transient at the line, T_z(k_l) = w_l^T Z(W_l) (w_l the interpolation weights), and the
      residuals E (|W_l| x 2). With q = |W_l| - (order + 1) complex degrees of freedom,
      C = E^T conj(E) / q estimates the 2x2 noise covariance of (V_y, V_u) (P&S's sample
      noise covariance of the LPM residuals).
  (4) Z_hat(k_l) = Z(k_l) - T_z(k_l); its error V(k_l) - w_l^T V(W_l) has covariance
      C (1 + |w_l|^2). H = Y_hat/U_hat = G_yr/G_ur (the ratio of the FRFs w.r.t. the drive);
      its relative error d = e_y/Y_hat - e_u/U_hat has variance
      s2 = (1 + |w_l|^2) [C_yy/|Y|^2 + C_uu/|U|^2 - 2 Re(C_yu/(Y conj U))]
      when the window holds noise only. Table motion common to both channels (the exciter's
      distortion products, amplifier noise) is not: at the line it moves both channels by
      H_l and cancels, at a window bin by H(k), so with H sloping it would leak into C. The
      "1" term is therefore taken from the residuals of Y(k) - H(k) U(k), H(k) interpolated
      between the lines (the line's own noise), the |w_l|^2 term from the residuals with H_l
      (what the transient interpolation carries to the line), each bin weighted by its
      |w_i|^2 and corrected for its leverage h_ii (sum |w_i|^2 |a^T e_i|^2 / (1 - h_ii),
      unbiased for white noise; the leak grows with the distance from the line, where the
      weights are small, so a plain |w_l|^2 C doubled it in a synthetic check). Found on
      the simulated piezo stand, whose channel noise is 1e-5 of the line and the exciter's
      products 5e-3: with the single formula 20-25 Hz covered 99-99.7 %.
  (5) d is circular: Re d (relative magnitude) and Im d (phase, rad) each have variance s2/2,
      estimated from q complex residuals: s2_hat ~ s2 chi2(2q)/(2q), so the interval uses
      Student's t at 2 q real degrees of freedom (issue 26: the usual order 2, 7-bin window
      leaves q = 1; here `min_dof` q >= 8 is enforced per line).
  (6) Neighbouring lines share window bins, so their errors correlate:
      cov(d_l, d_m) = (sum over W_l & W_m of w_l conj(w_m)) a_l^T C conj(a_m),
      a = (1/Y_hat, -1/U_hat); `relative_covariance` holds it (no pooling as if independent).
  (7) P >= 2 random-phase realisations (the robust method, P&S ch. 7): H = mean_p H_p; the
      noise variance is the mean of the per-realisation LPM variances (2 q P dof); the sample
      variance of H_p over p holds noise plus the stochastic nonlinear distortion, so the
      nonlinear part is their difference. It joins type A when an F test finds it (false alarm
      `NONLINEAR_FALSE_ALARM`); then the type A is the between-realisation variance, 2 (P - 1)
      dof. With P = 1 the LPM variance is labelled "total": nonlinear products that fall on
      non-excited bins are in it, those on the lines cannot be told from the response.

Spectra are peak-scaled, (2/N) rfft, as in dsp.spectral; volts in, V/V out.
Polynomial approximation error bound: Schoukens et al., IEEE TIM 62 (2013) 1346-1353.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp.quantiles import f_quantiles, has_duplicates, median

DRIVE_FLOOR_FACTOR = 10.0  # a recorded drive's leak: judged above this times its noise floor
NONLINEAR_FALSE_ALARM = 0.01  # probability per line that noise alone is taken for nonlinearity
TOTAL = "total"  # P = 1: noise and whatever nonlinear distortion reaches the non-excited bins
NOISE = "noise"  # P >= 2, nothing nonlinear found: noise only
NOISE_AND_NONLINEAR = "noise+nonlinear"  # P >= 2, nonlinear distortion found and included


class LpmError(ValueError):
    """Input the LPM cannot analyse honestly; the message names the field or line."""


@dataclass(frozen=True)
class LpmSettings:
    """Local model: polynomial `order` of the transient (-1: no transient term), `bins`
    non-excited bins per window, at most `reach` bins from the line, and the fewest complex
    residual degrees of freedom q a line may have (`min_dof`)."""

    order: int = 2
    bins: int = 12
    reach: int = 12
    min_dof: int = 8

    @property
    def parameters(self) -> int:
        """Complex parameters of the transient polynomial per channel."""
        return max(self.order + 1, 0)

    @property
    def dof(self) -> int:
        """Complex degrees of freedom q of a full window."""
        return self.bins - self.parameters

    def check(self) -> None:
        """LpmError naming the field when the settings cannot give `min_dof`."""
        if self.order < -1 or self.bins < 1 or self.reach < 1 or self.min_dof < 1:
            raise LpmError("lpm settings: order >= -1, bins, reach and min_dof >= 1")
        if self.dof < self.min_dof:
            raise LpmError(
                f"lpm settings: {self.bins} bins with a transient of order {self.order} leave "
                f"q = {self.dof} degrees of freedom, fewer than min_dof = {self.min_dof}"
            )


def window_offsets(
    line_bins: Sequence[int] | np.ndarray,
    record_bins: int,
    settings: LpmSettings,
    excluded_bins: Iterable[int] = (),
) -> list[np.ndarray]:
    """Per line, the offsets r (bins from the line) of its window: the `settings.bins` nearest
    usable bins (not a line, not DC or Nyquist, not excluded), at most `settings.reach` away.
    `record_bins` is the number of rfft bins (N/2 + 1). A line may get fewer (near DC)."""
    lines = np.asarray(line_bins, dtype=np.int64)
    blocked = set(int(b) for b in lines) | {0, record_bins - 1} | {int(b) for b in excluded_bins}
    out = []
    for k in lines:
        offsets = [
            r
            for r in sorted(range(-settings.reach, settings.reach + 1), key=lambda r: (abs(r), r))
            if r != 0 and 0 < k + r < record_bins - 1 and int(k + r) not in blocked
        ]
        out.append(np.array(sorted(offsets[: settings.bins]), dtype=np.int64))
    return out


def line_dof(
    line_bins: Sequence[int] | np.ndarray,
    record_bins: int,
    settings: LpmSettings,
    excluded_bins: Iterable[int] = (),
) -> np.ndarray:
    """Complex degrees of freedom q per line for this layout (window size minus parameters)."""
    windows = window_offsets(line_bins, record_bins, settings, excluded_bins)
    return np.array([w.size - settings.parameters for w in windows], dtype=np.int64)


def _weights(offsets: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Interpolation weights w (T(0) = w @ Z_window) and the residual projector I - K K^+."""
    m = offsets.size
    if order < 0:
        return np.zeros(m), np.eye(m)
    scale = max(float(np.max(np.abs(offsets))), 1.0)
    basis = np.vander(offsets / scale, order + 1, increasing=True)  # (m, order + 1)
    pinv = np.linalg.pinv(basis)
    return pinv[0], np.eye(m) - basis @ pinv


@dataclass(frozen=True)
class _Realisation:
    """One record's LPM result per line (internal)."""

    response: np.ndarray  # H_p
    y_hat: np.ndarray
    u_hat: np.ndarray
    cov: np.ndarray  # (lines, 2, 2): [[C_yy, C_yu], [C_uy, C_uu]]
    variance: np.ndarray  # s2 of (4), relative
    transient_y: np.ndarray
    transient_u: np.ndarray


def _interpolate(lines: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Complex values of the lines, linearly interpolated in bins at `at` (linear
    extrapolation from the two nearest lines at the ends; constant with one line)."""
    order = np.argsort(lines)
    x, v = lines[order].astype(float), values[order]
    if x.size == 1:
        return np.full(at.shape, v[0], complex)
    i = np.clip(np.searchsorted(x, at) - 1, 0, x.size - 2)
    t = (at - x[i]) / (x[i + 1] - x[i])
    return v[i] + t * (v[i + 1] - v[i])


def _one(
    y_spec: np.ndarray, u_spec: np.ndarray, lines: np.ndarray, layout: list[tuple[Any, ...]]
) -> _Realisation:
    """Relations (3)-(4) for one record. The variance splits in two parts: the line's own
    noise, from the residuals of Y - H(k) U at the window bins with H(k) interpolated between
    the lines (table motion common to both channels at those bins, e.g. the exciter's
    distortion products, is not noise at the line and cancels there), plus the transient
    interpolation's share |w|^2 a^T C a* with the line's own H."""
    count = lines.size
    t_y = np.empty(count, complex)
    t_u = np.empty(count, complex)
    for i, (_k, bins, w, _proj, _q) in enumerate(layout):
        t_y[i], t_u[i] = w @ y_spec[bins], w @ u_spec[bins]
    y_hat = y_spec[lines] - t_y
    u_hat = u_spec[lines] - t_u
    response = y_hat / u_hat
    cov = np.empty((count, 2, 2), complex)
    variance = np.empty(count)
    for i, (_k, bins, w, proj, q) in enumerate(layout):
        z = np.stack([y_spec[bins], u_spec[bins]], axis=1)  # (m, 2)
        residual = proj @ z
        c = residual.T @ residual.conj() / q
        cov[i] = c
        a = np.array([1.0 / y_hat[i], -1.0 / u_hat[i]])
        local = _interpolate(lines, response, bins.astype(float))
        own = proj @ (y_spec[bins] - local * u_spec[bins])
        own_variance = float(np.sum(np.abs(own) ** 2)) / q / abs(y_hat[i]) ** 2
        # HC2 form: sum |w_i|^2 |a^T e_i|^2 / (1 - h_ii); unbiased for |w|^2 s2 with white
        # noise, and it follows table motion that leaks more the farther a bin lies
        combined = residual @ a
        share = float(np.sum(np.abs(w) ** 2 * np.abs(combined) ** 2 / np.diag(proj).real))
        variance[i] = own_variance + share
    return _Realisation(response, y_hat, u_hat, cov, variance, t_y, t_u)


@dataclass(frozen=True)
class LpmEstimate:
    """Per-line LPM result (arrays in line order). `response` H = DUT/reference in V/V;
    type A values are standard uncertainties, relative (magnitude) and rad (phase), with
    `dof` real degrees of freedom (Student t); `line_dof` is q, complex, per realisation.
    `variance_kind` says what the type A holds (TOTAL, NOISE or NOISE_AND_NONLINEAR per line).
    `nonlinear_variance` is the stochastic nonlinear part of one realisation's relative
    variance (NaN when P = 1). `relative_covariance` (lines x lines, complex) is the
    covariance of the relative errors of `response`. Amplitudes, noise and transients are
    peak-scaled DFT magnitudes in volts (one realisation's record)."""

    realisations: int
    response: np.ndarray
    relative_type_a: np.ndarray
    phase_type_a_rad: np.ndarray
    dof: np.ndarray
    line_dof: np.ndarray
    variance_kind: tuple[str, ...]
    noise_variance: np.ndarray
    nonlinear_variance: np.ndarray
    relative_covariance: np.ndarray
    reference_amplitude_v: np.ndarray
    dut_amplitude_v: np.ndarray
    reference_noise_v: np.ndarray
    dut_noise_v: np.ndarray
    reference_transient_v: np.ndarray
    dut_transient_v: np.ndarray
    reference_lines_v: np.ndarray | None = None  # U_hat, complex (mean over realisations)
    dut_per_drive: np.ndarray | None = None  # G_yr, V per drive V (mean over realisations)
    reference_per_drive: np.ndarray | None = None  # G_ur

    @property
    def neighbour_correlation(self) -> np.ndarray:
        """Correlation of the relative magnitude (= phase) errors of consecutive lines (for
        circular noise Re(cov)/2 over var/2; it depends on the lines' phase difference)."""
        c = self.relative_covariance
        d = np.sqrt(np.real(np.diag(c)))
        return np.array([np.real(c[i, i + 1]) / (d[i] * d[i + 1]) for i in range(c.shape[0] - 1)])

    def ratio_type_a(self, line: int, reference_line: int) -> float:
        """Relative standard uncertainty of H[line]/H[reference_line] (the deviation from the
        reference frequency), with the correlation of the two lines (magnitude, = phase)."""
        c = self.relative_covariance
        var = np.real(c[line, line] + c[reference_line, reference_line])
        var -= 2.0 * np.real(c[line, reference_line])
        return math.sqrt(max(float(var), 0.0) / 2.0)


def estimate(
    reference_v: np.ndarray,
    dut_v: np.ndarray,
    line_bins: Sequence[int] | np.ndarray,
    *,
    settings: LpmSettings | None = None,
    excluded_bins: Iterable[int] = (),
    drive_v: np.ndarray | None = None,
) -> LpmEstimate:
    """LPM estimate from P records (rows; one record as a 1-D array), in volts.

    Each record is a whole number of periods over which the drive is periodic; `line_bins`
    are the lines' bins in the record's DFT (period bin x periods in the record). With
    `drive_v` (same shape) the drive is checked to be periodic over the record (no fade in
    it) and the FRFs per drive volt are returned too. LpmError names what is wrong.
    """
    settings = settings or LpmSettings()
    settings.check()
    ref = np.atleast_2d(np.asarray(reference_v, dtype=float))
    dut = np.atleast_2d(np.asarray(dut_v, dtype=float))
    if ref.shape != dut.shape or ref.ndim != 2 or ref.shape[1] < 8:
        raise LpmError(f"records: reference {ref.shape} and DUT {dut.shape} must match")
    lines = np.asarray(line_bins, dtype=np.int64)
    n = ref.shape[1]
    record_bins = n // 2 + 1
    if lines.ndim != 1 or lines.size == 0 or lines.min() < 1 or lines.max() >= record_bins - 1:
        raise LpmError(f"line bins: need at least one, within 1..{record_bins - 2}")
    if has_duplicates(lines):
        raise LpmError("line bins: two lines on one bin")
    layout = _layout(lines, record_bins, settings, excluded_bins)
    y_spec = np.fft.rfft(dut, axis=1) * (2.0 / n)
    u_spec = np.fft.rfft(ref, axis=1) * (2.0 / n)
    r_spec = None
    if drive_v is not None:
        drive = np.atleast_2d(np.asarray(drive_v, dtype=float))
        if drive.shape != ref.shape:
            raise LpmError(f"drive: shape {drive.shape} does not match the records {ref.shape}")
        r_spec = np.fft.rfft(drive, axis=1) * (2.0 / n)
    return _from_spectra(list(y_spec), list(u_spec), lines, layout, r_spec)


def _layout(
    lines: np.ndarray, record_bins: int, settings: LpmSettings, excluded_bins: Iterable[int]
) -> list[tuple[Any, ...]]:
    """Per line (bin, window bins, weights w, residual projector, q); LpmError on too few q."""
    layout = []
    windows = window_offsets(lines, record_bins, settings, excluded_bins)
    for k, offsets in zip(lines, windows, strict=True):
        q = offsets.size - settings.parameters
        if q < settings.min_dof:
            raise LpmError(
                f"line at bin {k}: only {offsets.size} non-excited bins within {settings.reach}"
                f" bins leave q = {q} < {settings.min_dof}; use a longer record or fewer lines"
            )
        w, proj = _weights(offsets, settings.order)
        layout.append((int(k), k + offsets, w, proj, q))
    return layout


def _from_spectra(
    y_specs: Sequence[Any],
    u_specs: Sequence[Any],
    lines: np.ndarray,
    layout: list[tuple[Any, ...]],
    r_specs: Sequence[Any] | None,
) -> LpmEstimate:
    """Relations (3)-(7) from each realisation's peak-scaled spectra (arrays, or
    NeighbourSpectrum: only the bins of the lines and their windows are read)."""
    parts = [_one(y, u, lines, layout) for y, u in zip(y_specs, u_specs, strict=True)]
    per_drive = _per_drive(r_specs, parts, lines, layout) if r_specs is not None else None
    return _combine(parts, lines, layout, per_drive)


def estimate_spectra(
    y_spec: Any,
    u_spec: Any,
    line_bins: Sequence[int] | np.ndarray,
    record_bins: int,
    *,
    settings: LpmSettings | None = None,
    excluded_bins: Iterable[int] = (),
    r_spec: Any | None = None,
) -> LpmEstimate:
    """The LPM of one record given its peak-scaled spectra ((2/N) rfft, V) of DUT, reference
    and (optionally) drive: arrays of `record_bins` bins or NeighbourSpectrum (a long record
    accumulated period by period). Same relations and checks as `estimate`."""
    settings = settings or LpmSettings()
    settings.check()
    lines = np.asarray(line_bins, dtype=np.int64)
    if lines.ndim != 1 or lines.size == 0 or lines.min() < 1 or lines.max() >= record_bins - 1:
        raise LpmError(f"line bins: need at least one, within 1..{record_bins - 2}")
    if has_duplicates(lines):
        raise LpmError("line bins: two lines on one bin")
    layout = _layout(lines, record_bins, settings, excluded_bins)
    return _from_spectra([y_spec], [u_spec], lines, layout, None if r_spec is None else [r_spec])


def _per_drive(
    r_specs: Sequence[Any],
    parts: list[_Realisation],
    lines: np.ndarray,
    layout: list[tuple[Any, ...]],
) -> tuple[np.ndarray, np.ndarray]:
    """Check the drive is periodic over each record (its peak-scaled spectra `r_specs`, one
    per realisation, arrays or NeighbourSpectrum); mean FRFs of both channels per drive V."""
    line_level = np.array([np.abs(r[lines]) for r in r_specs])
    # a recorded drive (the ADC's loopback, quantised) carries its periodic quantisation error
    # at every bin of its period (the multiples of the lines' common divisor): a leak is judged
    # above DRIVE_FLOOR_FACTOR times its median over those that are no line (a fade's leak is
    # not periodic: it fills the bins between them beside the lines; a live run's exact
    # drive has none)
    step = int(np.gcd.reduce(np.asarray(lines, dtype=int)))
    floor = np.zeros(len(r_specs))
    for j, r in enumerate(r_specs):
        grid = np.arange(step, int(r.size), step)
        keep = np.ones(grid.size, dtype=bool)
        keep[np.asarray(lines, dtype=int) // step - 1] = False  # the lines are on the grid
        free = grid[keep]
        if free.size:
            floor[j] = DRIVE_FLOOR_FACTOR * median(np.abs(r[free]))
    for i, (k, bins, *_rest) in enumerate(layout):
        leak = np.array([np.max(np.abs(r[bins])) for r in r_specs])
        if np.any(leak > np.maximum(1e-3 * line_level[:, i], floor)):
            raise LpmError(
                f"drive: not periodic over the record around bin {k} (leakage "
                f"{float(np.max(leak / line_level[:, i])):.1e} of the line); a fade must end "
                "before the analysed record"
            )
    g_y = np.mean([p.y_hat / r_specs[j][lines] for j, p in enumerate(parts)], axis=0)
    g_u = np.mean([p.u_hat / r_specs[j][lines] for j, p in enumerate(parts)], axis=0)
    return g_y, g_u


def _combine(
    parts: list[_Realisation],
    lines: np.ndarray,
    layout: list[tuple[Any, ...]],
    per_drive: tuple[np.ndarray, np.ndarray] | None,
) -> LpmEstimate:
    p_count = len(parts)
    q = np.array([entry[4] for entry in layout], dtype=float)
    responses = np.array([p.response for p in parts])  # (P, lines)
    response = responses.mean(axis=0)
    noise = np.mean([p.variance for p in parts], axis=0)  # one realisation's relative variance
    noise_dof = 2.0 * q * p_count
    covariance = _line_covariance(parts, layout) / p_count
    if p_count == 1:
        kinds = tuple(TOTAL for _ in lines)
        nonlinear = np.full(lines.size, np.nan)
        variance_of_mean = noise.copy()
        dof = noise_dof
    else:
        relative = responses / response - 1.0
        between = np.sum(np.abs(relative - relative.mean(axis=0)) ** 2, axis=0) / (p_count - 1)
        nonlinear = np.maximum(between - noise, 0.0)
        threshold = f_quantiles(2 * (p_count - 1), noise_dof, 1.0 - NONLINEAR_FALSE_ALARM)
        found = between / noise > threshold
        kinds = tuple(NOISE_AND_NONLINEAR if f else NOISE for f in found)
        variance_of_mean = np.where(found, between, noise) / p_count
        dof = np.where(found, 2.0 * (p_count - 1), noise_dof)
        scale = np.sqrt(variance_of_mean / (noise / p_count))  # widen the covariance with it
        covariance = covariance * np.outer(scale, scale)
    standard = np.sqrt(variance_of_mean / 2.0)

    def mean_abs(values: Iterable[np.ndarray]) -> np.ndarray:
        return np.mean(np.abs(np.array(list(values))), axis=0)

    return LpmEstimate(
        realisations=p_count,
        response=response,
        relative_type_a=standard,
        phase_type_a_rad=standard.copy(),
        dof=dof,
        line_dof=q.astype(np.int64),
        variance_kind=kinds,
        noise_variance=noise,
        nonlinear_variance=nonlinear,
        relative_covariance=covariance,
        reference_amplitude_v=mean_abs(p.u_hat for p in parts),
        dut_amplitude_v=mean_abs(p.y_hat for p in parts),
        reference_noise_v=np.sqrt(np.mean([np.real(p.cov[:, 1, 1]) for p in parts], axis=0)),
        dut_noise_v=np.sqrt(np.mean([np.real(p.cov[:, 0, 0]) for p in parts], axis=0)),
        reference_transient_v=mean_abs(p.transient_u for p in parts),
        dut_transient_v=mean_abs(p.transient_y for p in parts),
        reference_lines_v=np.mean([p.u_hat for p in parts], axis=0),
        dut_per_drive=None if per_drive is None else per_drive[0],
        reference_per_drive=None if per_drive is None else per_drive[1],
    )


def _line_covariance(parts: list[_Realisation], layout: list[tuple[Any, ...]]) -> np.ndarray:
    """Covariance of the relative errors of one realisation's H between lines, relation (6),
    averaged over realisations; the diagonal is the variance (4)."""
    count = len(layout)
    out = np.zeros((count, count), complex)
    positions = [dict(zip(entry[1].tolist(), entry[2], strict=True)) for entry in layout]
    for part in parts:
        a = np.stack([1.0 / part.y_hat, -1.0 / part.u_hat], axis=1)  # (lines, 2)
        for i in range(count):
            out[i, i] += part.variance[i]
            for j in range(i + 1, count):
                shared = positions[i].keys() & positions[j].keys()
                if not shared:
                    continue
                overlap = sum(positions[i][b] * np.conj(positions[j][b]) for b in shared)
                c = 0.5 * (part.cov[i] + part.cov[j])
                value = overlap * (a[i] @ c @ a[j].conj())
                out[i, j] += value
                out[j, i] += np.conj(value)
    return out / len(parts)


def mains_bins(
    resolution_hz: float, record_bins: int, mains_hz: float = 50.0, harmonics: int = 5
) -> set[int]:
    """Record bins holding mains hum (periodic, not noise): the bin of each harmonic, or both
    neighbours when it falls between bins; excluded from the windows."""
    out: set[int] = set()
    for h in range(1, harmonics + 1):
        position = h * mains_hz / resolution_hz
        nearest = round(position)
        picks = (
            {nearest}
            if abs(position - nearest) < 1e-6
            else {math.floor(position), math.ceil(position)}
        )
        out |= {b for b in picks if 0 < b < record_bins}
    return out


@dataclass(frozen=True)
class LpmGrid:
    """A period and line grid for the LPM: sample rate (Hz), period (samples), per line the
    nominal and actual (bin) frequency in Hz, its bin in one period and its q (complex dof
    of one record of `periods` periods)."""

    sample_rate_hz: float
    period_samples: int
    periods: int
    nominal_frequencies_hz: tuple[float, ...]
    bins: tuple[int, ...]
    frequencies_hz: tuple[float, ...]
    line_dof: tuple[int, ...]

    @property
    def period_s(self) -> float:
        return self.period_samples / self.sample_rate_hz

    @property
    def record_line_bins(self) -> np.ndarray:
        """The lines' bins in the DFT of one record of `periods` periods."""
        return np.asarray(self.bins, dtype=np.int64) * self.periods

    def describe(self) -> list[str]:
        """One line of text per line: nominal, actual frequency and q."""
        return [
            f"{f0:g} Hz: at {f:.6g} Hz (bin {b}), q = {q} complex degrees of freedom"
            for f0, f, b, q in zip(
                self.nominal_frequencies_hz,
                self.frequencies_hz,
                self.bins,
                self.line_dof,
                strict=True,
            )
        ]


def design_grid(
    nominal_frequencies_hz: Sequence[float],
    sample_rate_hz: float,
    *,
    settings: LpmSettings | None = None,
    tolerance: float = 0.0,
    periods: int = 1,
    min_period_s: float = 0.0,
    max_period_s: float = 100.0,
    step_s: float = 0.05,
    mains_hz: float = 50.0,
    mains_harmonics: int = 5,
    within_hz: tuple[float, float] | None = None,
) -> LpmGrid:
    """The shortest period (a multiple of `step_s`, within [min_period_s, max_period_s]) that
    puts every line on a bin within `tolerance` (relative) of its nominal frequency, on
    distinct bins below 0.45 fs, each with q >= settings.min_dof in a record of `periods`
    periods (mains hum bins excluded), and, given `within_hz` (lo, hi), every line's bin within
    [lo, hi] Hz (issue 32: a 0.4 Hz line played at 0.3966 Hz lies outside a reference
    calibrated from 0.4 Hz). With tolerance 0 the lines sit exactly on their nominal
    frequencies; a low-frequency plan whose exact bins would need a 100 s period takes a
    tolerance and reports the actual frequencies. LpmError when no period qualifies."""
    settings = settings or LpmSettings()
    settings.check()
    nominal = np.asarray([float(f) for f in nominal_frequencies_hz])
    if nominal.size == 0 or not np.all(np.isfinite(nominal) & (nominal > 0)):
        raise LpmError("frequencies: need at least one, each > 0 Hz")
    if not (sample_rate_hz > 0 and step_s > 0 and periods >= 1 and tolerance >= 0):
        raise LpmError("grid: sample rate, step and periods must be > 0, tolerance >= 0")
    if nominal.max() >= 0.45 * sample_rate_hz:
        raise LpmError(f"line {nominal.max():g} Hz: at or above 0.45 fs; raise the sample rate")
    first = max(1, math.ceil(min_period_s / step_s - 1e-9))
    last = math.floor(max_period_s / step_s + 1e-9)
    for j in range(first, last + 1):
        n = round(j * step_s * sample_rate_hz)
        resolution = sample_rate_hz / n
        bins = np.rint(nominal / resolution).astype(np.int64)
        actual = bins * resolution
        if bins.min() < 1 or has_duplicates(bins):
            continue
        if np.any(np.abs(actual - nominal) > tolerance * nominal + 1e-9 * nominal):
            continue
        if within_hz is not None and (
            actual.min() < within_hz[0] * (1 - 1e-9) or actual.max() > within_hz[1] * (1 + 1e-9)
        ):
            continue
        record_bins = n * periods // 2 + 1
        excluded = mains_bins(resolution / periods, record_bins, mains_hz, mains_harmonics)
        q = line_dof(bins * periods, record_bins, settings, excluded)
        if q.min() >= settings.min_dof:
            return LpmGrid(
                float(sample_rate_hz),
                int(n),
                int(periods),
                tuple(nominal.tolist()),
                tuple(int(b) for b in bins),
                tuple(actual.tolist()),
                tuple(int(v) for v in q),
            )
    raise LpmError(
        f"grid: no period of {min_period_s:g}-{max_period_s:g} s puts every line within "
        f"{100 * tolerance:g} % of its nominal frequency with q >= {settings.min_dof}"
        + (f" inside {within_hz[0]:g}-{within_hz[1]:g} Hz" if within_hz is not None else "")
        + "; allow a longer period or a frequency tolerance"
    )
