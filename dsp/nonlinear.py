"""Nonlinear distortion of the DUT measured at every line from one record (issue 32 point 4).

A random-phase multisine through a weakly nonlinear DUT gives, per line, the best linear
approximation (BLA, Pintelon & Schoukens, "System Identification: a frequency domain
approach", 2nd ed., Wiley/IEEE 2012, ch. 3-4: the expected FRF over random-phase
realisations of the same amplitude spectrum) plus a stochastic nonlinear contribution G_s that
changes with the phases and does not average over periods. The LPM's window bins do not
carry the distortion that lands on a line: on an ISO 266 grid the products of lines fall on
other lines and on arithmetic coincidences, rarely beside a line (issue 32). What the record
does carry is the products at the free bins (the detection bins: every bin that is no line,
no DC, no Nyquist and no mains harmonic). This module measures them and carries them to the
lines with a model of the DUT's distortion:

  (1) x(t): the record's table motion as the reference channel sees it (its lines, the
      exciter's own distortion and any transient: the DUT distorts all of it; the reference's
      noise is far below), in units of the rms of its lines.
  (2) Regressors: the spectra X2 = DFT(x^2), X3 = DFT(x^3) (orders 2 and 3, a static
      polynomial before the DUT's linear dynamics: the Hammerstein structure of a sensing
      element followed by its electronics). At a free bin j the DUT's residual after the
      table's common motion, r(j) = Y(j) - H(j) U(j) (H interpolated between the lines),
      is modelled as s H(j) (theta_2 X2(j) + theta_3 X3(j)) + noise; theta (real) by least
      squares over all free bins, its covariance heteroscedasticity-consistent (HC0: the
      noise level changes across the band); a Wald test names it found at
      `NONLINEAR_FALSE_ALARM`.
  (3) At line k, X3(k) holds the Bussgang part U_k (0.75 |a_k|^2 + 1.5 sum_m!=k |a_m|^2)
      (a the normalised line amplitudes: the phase-independent part, which is the BLA's for
      a pure multisine of these amplitudes) and a rest X3s(k) (the stochastic part, and the
      cross products with the exciter's distortion, which belong to the stand, not the DUT);
      X2 has no phase-independent part at a line. The relative error of this record's H
      against the BLA is then
      e_k = (theta_2 X2(k) + theta_3 X3s(k)) / (a_k (1 + theta_3 beta_k)),
      known from the record. It is removed (the stated H is the BLA estimate) and the
      uncertainty of theta carried to the line (real part: magnitude, imaginary: phase).
      The free bins see the DUT's linear part H_lin = H / ((1 + theta_3 beta) (1 + e)), so
      the fit is repeated with it (FIT_PASSES).
  (4) The model is tested by fitting orders 4 and 5 with it (a nested-model Wald test, HC0,
      at MODEL_FALSE_ALARM): products the model does not explain (a nonlinearity of higher
      order) make `adequate` False, and the caller then blocks PASS naming the lines the
      distortion reaches.

The fitted products are also removed from the free bins before the LPM (`cleaned`), so that its
windows hold noise only. Spectra are peak-scaled, (2/N) rfft, volts; ratios out.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dsp.quantiles import chi2_sf_even  # not scipy.special (issue 34): 2 and 2 orders

NONLINEAR_FALSE_ALARM = 0.01  # probability per record that noise alone is taken for distortion
MODEL_FALSE_ALARM = 0.01  # probability per record that a right model is called inadequate
ORDERS = (2, 3)  # the polynomial orders of the distortion model
MIN_FRACTION = 1e-6  # below: rounding in a noise-free record, never reported as distortion
FIT_PASSES = 3  # refits with H_lin (the lines' H holds the compression and e_k: 0.5 % in theta)
CHECK_ORDERS = (4, 5)  # orders the model leaves out: the test of relation (4)
ALL_ORDERS = (*ORDERS, *CHECK_ORDERS)


@dataclass(frozen=True)
class NonlinearEstimate:
    """The DUT's distortion from one record. `coefficients` theta per order of `ORDERS`
    (ratio of the normalised excitation's power), `covariance` theta's (HC0); `found` when
    the Wald test rejects theta = 0; `fraction` the rms of the fitted distortion over the
    excitation's rms (ratio); per line (plan order) `relative_error` e_k of this record's H
    against the BLA (complex ratio, removed from the stated H when found) and its standard
    uncertainty from theta's, real part (magnitude, ratio) and imaginary part (phase, rad);
    `linear_response` the DUT's linear part H_lin per line (V/V, the BLA without compression);
    `model_p_value` the p-value of relation (4)'s test, `adequate` whether the model passes
    it (True when nothing was found), `tested_bins` the number of detection bins."""

    coefficients: np.ndarray
    covariance: np.ndarray
    p_value: float
    found: bool
    fraction: float
    relative_error: np.ndarray
    magnitude_u: np.ndarray
    phase_u_rad: np.ndarray
    linear_response: np.ndarray
    model_p_value: float
    adequate: bool
    tested_bins: int

    def reached_lines(self, type_a: np.ndarray, share: float = 0.3) -> np.ndarray:
        """Per line, whether the distortion at it is at least `share` of `type_a` (ratio):
        the lines an inadequate model leaves uncertain."""
        return np.abs(self.relative_error) >= share * np.asarray(type_a, dtype=float)


def _interpolated(lines: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Complex values of the lines, linear in bins between them, constant beyond the ends."""
    order = np.argsort(lines)
    x, v = lines[order].astype(float), values[order]
    return np.interp(at, x, v.real) + 1j * np.interp(at, x, v.imag)


def free_bins(record_bins: int, line_bins: np.ndarray, excluded: Iterable[int] = ()) -> np.ndarray:
    """The detection bins of a record of `record_bins` rfft bins: every bin that is no line,
    no DC, no Nyquist and not excluded (mains harmonics)."""
    free = np.ones(max(int(record_bins), 0), dtype=bool)  # one mask, no Python loop over bins
    free[:1] = False  # DC
    free[-1:] = False  # Nyquist
    for blocked in (line_bins, excluded):
        b = np.asarray(list(blocked) if not isinstance(blocked, np.ndarray) else blocked)
        b = b.astype(np.int64).ravel()
        free[b[(b >= 0) & (b < free.size)]] = False
    return np.flatnonzero(free).astype(np.int64)


def _scale(u_lines: np.ndarray) -> float:
    """The rms of the reference's lines (peak values `u_lines`, V); ValueError when none."""
    scale = float(np.sqrt(np.sum(np.abs(np.asarray(u_lines)) ** 2) / 2.0))
    if not scale > 0:
        raise ValueError("reference: no signal at the lines")
    return scale


def _excitation(reference_v: np.ndarray, u_lines: np.ndarray) -> tuple[np.ndarray, float]:
    """Relation (1): the record's table motion as the reference sees it, in units of the
    rms of its lines (peak values `u_lines`), and that rms (V)."""
    scale = _scale(u_lines)
    return np.asarray(reference_v, dtype=float) / scale, scale


def estimate(
    y_spec: np.ndarray,
    u_spec: np.ndarray,
    line_bins: np.ndarray,
    u_lines: np.ndarray,
    response: np.ndarray,
    reference_v: np.ndarray,
    *,
    excluded_bins: Iterable[int] = (),
) -> NonlinearEstimate:
    """The distortion of one record: `y_spec`, `u_spec` the DUT's and the reference's
    peak-scaled spectra (rfft of the record x 2/N), `line_bins` the lines' record bins,
    `u_lines` the reference's line values with the transient removed and `response` H at
    the lines (both from the LPM), `reference_v` the reference's record (V), `excluded_bins`
    bins holding hum. Relations (1)-(4)."""
    lines = np.asarray(line_bins, dtype=np.int64)
    size = y_spec.size
    n = 2 * (size - 1)
    x, scale = _excitation(reference_v, u_lines)
    regressors = [np.fft.rfft(x**order) * (2.0 / n) for order in ORDERS]
    a = np.asarray(u_lines, complex) / scale  # the normalised line amplitudes (peak)
    power = np.abs(a) ** 2
    bussgang = 0.75 * power + 1.5 * (power.sum() - power)  # relation (3), per line

    free = free_bins(size, lines, excluded_bins)
    raw_at_lines = np.stack([r[lines] for r in regressors], axis=1)  # (lines, orders)
    third = ORDERS.index(3)
    linear = np.asarray(response, complex)
    for _ in range(FIT_PASSES):  # the free bins see H_lin, the lines H_lin (1 + bussgang)(1 + e)
        h_free = _interpolated(lines, linear, free.astype(float))
        residual = y_spec[free] - h_free * u_spec[free]
        design = np.stack([scale * h_free * r[free] for r in regressors], axis=1)
        real_design = np.vstack([design.real, design.imag])
        real_residual = np.concatenate([residual.real, residual.imag])
        theta, *_ = np.linalg.lstsq(real_design, real_residual, rcond=None)
        at_lines = raw_at_lines.copy()
        at_lines[:, third] -= bussgang * a  # the phase-independent part belongs to the BLA
        compression = 1.0 + theta[third] * bussgang
        sensitivity = at_lines / (a * compression)[:, None]  # d e_k / d theta
        relative_error = sensitivity @ theta
        linear = np.asarray(response, complex) / (compression * (1.0 + relative_error))
    error = real_residual - real_design @ theta
    gram_inv = np.linalg.pinv(real_design.T @ real_design)
    meat = real_design.T @ (real_design * (error**2)[:, None])
    covariance = gram_inv @ meat @ gram_inv
    wald = float(theta @ np.linalg.pinv(covariance) @ theta)
    p_value = chi2_sf_even(len(ORDERS), wald)
    distortion = sum(t * x**order for t, order in zip(theta, ORDERS, strict=True))
    fraction = float(np.sqrt(np.mean(np.asarray(distortion) ** 2)))
    found = p_value < NONLINEAR_FALSE_ALARM and fraction > MIN_FRACTION

    magnitude_u = np.sqrt(np.einsum("li,ij,lj->l", sensitivity.real, covariance, sensitivity.real))
    phase_u = np.sqrt(np.einsum("li,ij,lj->l", sensitivity.imag, covariance, sensitivity.imag))

    model_p = _model_test(
        residual, h_free, scale, x, free, dict(zip(ORDERS, regressors, strict=True))
    )
    return NonlinearEstimate(
        coefficients=theta,
        covariance=covariance,
        p_value=p_value,
        found=found,
        fraction=fraction,
        relative_error=relative_error,
        magnitude_u=magnitude_u,
        phase_u_rad=phase_u,
        linear_response=linear,
        model_p_value=model_p,
        adequate=model_p >= MODEL_FALSE_ALARM or not found,
        tested_bins=int(free.size),
    )


CHUNK_BINS = 16384  # detection bins per step of the neighbourhood fit's sums (bounded memory)


def _held_free(y_spec: Any, lines: np.ndarray, excluded_bins: Iterable[int]) -> np.ndarray:
    """The free bins a NeighbourSpectrum holds (as `free_bins`, restricted to those held)."""
    held = y_spec.held_bins()
    blocked = np.array(
        sorted({int(b) for b in lines} | {int(b) for b in excluded_bins} | {0, y_spec.size - 1}),
        dtype=np.int64,
    )
    return held[~np.isin(held, blocked)]


def estimate_neighbourhood(
    y_spec: Any,
    u_spec: Any,
    line_bins: np.ndarray,
    u_lines: np.ndarray,
    response: np.ndarray,
    powers: dict[int, Any],
    moments: dict[int, float],
    *,
    excluded_bins: Iterable[int] = (),
) -> NonlinearEstimate:
    """Relations (1)-(4) for a long record held only near its period grid (dsp.lpm's
    NeighbourSpectrum): the detection bins are the free bins held (within the neighbourhood of
    every grid bin, where the periodic products of a steady multisine land), not all of the
    record's. `powers[o]` is the peak-scaled spectrum of reference_v**o (o = 2..5, V^o) held at
    the same bins, `moments[o]` the mean of reference_v**o over the record (o = 4..6, for the
    fraction). The least squares and the HC0 sums are taken CHUNK_BINS bins at a time (normal
    equations, 2 and 4 unknowns), so memory does not grow with the bins held. Otherwise as
    `estimate`."""
    lines = np.asarray(line_bins, dtype=np.int64)
    free = _held_free(y_spec, lines, excluded_bins)
    scale = _scale(u_lines)
    m = {o: moments[o] / scale**o for o in (4, 5, 6)}
    a = np.asarray(u_lines, complex) / scale  # the normalised line amplitudes (peak)
    power = np.abs(a) ** 2
    bussgang = 0.75 * power + 1.5 * (power.sum() - power)  # relation (3), per line
    raw_at_lines = np.stack([powers[o][lines] / scale**o for o in ORDERS], axis=1)
    third = ORDERS.index(3)

    def rows(chunk: np.ndarray, h: np.ndarray, orders: tuple[int, ...]):
        """Real design rows and residuals of relation (2) at the bins `chunk`."""
        y, u = y_spec[chunk], u_spec[chunk]
        h_chunk = _interpolated(lines, h, chunk.astype(float))
        residual = y - h_chunk * u
        design = np.stack([scale * h_chunk * (powers[o][chunk] / scale**o) for o in orders], axis=1)
        return np.vstack([design.real, design.imag]), np.concatenate([residual.real, residual.imag])

    def chunks() -> Iterable[np.ndarray]:
        for i in range(0, free.size, CHUNK_BINS):
            yield free[i : i + CHUNK_BINS]

    def solve(h: np.ndarray, orders: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
        """theta by least squares over every chunk, and the inverse Gram matrix."""
        gram = np.zeros((len(orders), len(orders)))
        moment = np.zeros(len(orders))
        for chunk in chunks():
            d, r = rows(chunk, h, orders)
            gram += d.T @ d
            moment += d.T @ r
        gram_inv = np.linalg.pinv(gram)
        return gram_inv @ moment, gram_inv

    def hc0(h: np.ndarray, orders: tuple[int, ...], theta: np.ndarray, gram_inv: np.ndarray):
        meat = np.zeros((len(orders), len(orders)))
        for chunk in chunks():
            d, r = rows(chunk, h, orders)
            error = r - d @ theta
            meat += d.T @ (d * (error**2)[:, None])
        return gram_inv @ meat @ gram_inv

    linear = np.asarray(response, complex)
    for _ in range(FIT_PASSES):
        h_pass = linear
        theta, gram_inv = solve(h_pass, ORDERS)
        at_lines = raw_at_lines.copy()
        at_lines[:, third] -= bussgang * a  # the phase-independent part belongs to the BLA
        compression = 1.0 + theta[third] * bussgang
        sensitivity = at_lines / (a * compression)[:, None]  # d e_k / d theta
        relative_error = sensitivity @ theta
        linear = np.asarray(response, complex) / (compression * (1.0 + relative_error))
    covariance = hc0(h_pass, ORDERS, theta, gram_inv)
    wald = float(theta @ np.linalg.pinv(covariance) @ theta)
    p_value = chi2_sf_even(len(ORDERS), wald)
    t2, t3 = (theta[ORDERS.index(o)] for o in (2, 3))
    fraction = float(np.sqrt(max(t2 * t2 * m[4] + 2 * t2 * t3 * m[5] + t3 * t3 * m[6], 0.0)))
    found = p_value < NONLINEAR_FALSE_ALARM and fraction > MIN_FRACTION
    magnitude_u = np.sqrt(np.einsum("li,ij,lj->l", sensitivity.real, covariance, sensitivity.real))
    phase_u = np.sqrt(np.einsum("li,ij,lj->l", sensitivity.imag, covariance, sensitivity.imag))

    # relation (4): the residuals of the last pass (H of that pass) fitted with every order
    full, full_inv = solve(h_pass, ALL_ORDERS)
    full_cov = hc0(h_pass, ALL_ORDERS, full, full_inv)
    extra = slice(len(ORDERS), len(ALL_ORDERS))
    added = full[extra]
    wald_model = float(added @ np.linalg.pinv(full_cov[extra, extra]) @ added)
    model_p = chi2_sf_even(len(CHECK_ORDERS), wald_model)
    return NonlinearEstimate(
        coefficients=theta,
        covariance=covariance,
        p_value=p_value,
        found=found,
        fraction=fraction,
        relative_error=relative_error,
        magnitude_u=magnitude_u,
        phase_u_rad=phase_u,
        linear_response=linear,
        model_p_value=model_p,
        adequate=model_p >= MODEL_FALSE_ALARM or not found,
        tested_bins=int(free.size),
    )


def _model_test(
    residual: np.ndarray,
    h_free: np.ndarray,
    scale: float,
    x: np.ndarray,
    free: np.ndarray,
    spectra: dict[int, np.ndarray] | None = None,
) -> float:
    """Relation (4): the p-value of the Wald test (HC0) that the orders CHECK_ORDERS add
    nothing to the model at the free bins, both fitted together. `spectra`: the peak-scaled
    spectra of x**order already computed (the model's orders: not computed again)."""
    n = x.size
    known = spectra or {}

    def spectrum(order: int) -> np.ndarray:
        held = known.get(order)
        return held if held is not None else np.fft.rfft(x**order) * (2.0 / n)

    design = np.stack([scale * h_free * spectrum(order)[free] for order in ALL_ORDERS], axis=1)
    real_design = np.vstack([design.real, design.imag])
    real_residual = np.concatenate([residual.real, residual.imag])
    theta, *_ = np.linalg.lstsq(real_design, real_residual, rcond=None)
    error = real_residual - real_design @ theta
    gram_inv = np.linalg.pinv(real_design.T @ real_design)
    covariance = gram_inv @ (real_design.T @ (real_design * (error**2)[:, None])) @ gram_inv
    extra = slice(len(ORDERS), len(ALL_ORDERS))
    added = theta[extra]
    wald = float(added @ np.linalg.pinv(covariance[extra, extra]) @ added)
    return chi2_sf_even(len(CHECK_ORDERS), wald)


def cleaned(
    y_spec: np.ndarray,
    nonlinear: NonlinearEstimate,
    u_lines: np.ndarray,
    line_bins: np.ndarray,
    reference_v: np.ndarray,
    excluded_bins: Iterable[int] = (),
) -> np.ndarray:
    """`y_spec` with the fitted products removed at the free bins (for the LPM's windows)."""
    lines = np.asarray(line_bins, dtype=np.int64)
    size = y_spec.size
    n = 2 * (size - 1)
    x, scale = _excitation(reference_v, u_lines)
    free = free_bins(size, lines, excluded_bins)
    h_free = _interpolated(lines, nonlinear.linear_response, free.astype(float))
    out = y_spec.copy()
    for theta, order in zip(nonlinear.coefficients, ORDERS, strict=True):
        out[free] -= theta * scale * h_free * (np.fft.rfft(x**order) * (2.0 / n))[free]
    return out


def cleaned_neighbourhood(
    y_spec: Any,
    nonlinear: NonlinearEstimate,
    u_lines: np.ndarray,
    line_bins: np.ndarray,
    powers: dict[int, Any],
    excluded_bins: Iterable[int] = (),
) -> Any:
    """`cleaned` for a spectrum held near the period grid (lpm_neighbours.NeighbourSpectrum, with
    `powers` as for `estimate_neighbourhood`): a copy with the fitted products removed at the
    free bins it holds (CHUNK_BINS at a time)."""
    lines = np.asarray(line_bins, dtype=np.int64)
    free = _held_free(y_spec, lines, excluded_bins)
    scale = _scale(u_lines)
    out = y_spec.copy()
    for i in range(0, free.size, CHUNK_BINS):
        chunk = free[i : i + CHUNK_BINS]
        h_chunk = _interpolated(lines, nonlinear.linear_response, chunk.astype(float))
        values = out[chunk]
        for theta, order in zip(nonlinear.coefficients, ORDERS, strict=True):
            values -= theta * scale * h_chunk * (powers[order][chunk] / scale**order)
        out[chunk] = values
    return out


@dataclass(frozen=True)
class Carried:
    """An estimator's per-line result with the distortion carried: H the BLA estimate (V/V),
    type A of magnitude (ratio) and phase (rad), and their Welch-Satterthwaite dof."""

    response: np.ndarray
    magnitude_u: np.ndarray
    phase_u_rad: np.ndarray
    dof: np.ndarray


def carry(
    response: np.ndarray,
    magnitude_u: np.ndarray,
    phase_u_rad: np.ndarray,
    dof: float | np.ndarray,
    found: NonlinearEstimate,
) -> Carried:
    """Relation (3) applied to an estimator's result: the record's stochastic part removed
    from H, the model's uncertainty joined to the type A (the model's dof are infinite: its
    coefficients come from thousands of bins)."""
    magnitude = np.hypot(magnitude_u, found.magnitude_u)
    phase = np.hypot(phase_u_rad, found.phase_u_rad)
    dofs = np.broadcast_to(np.asarray(dof, dtype=float), magnitude.shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        welch = magnitude**4 / (np.asarray(magnitude_u, dtype=float) ** 4 / dofs)
    return Carried(
        response=np.asarray(response) / (1.0 + found.relative_error),
        magnitude_u=magnitude,
        phase_u_rad=phase,
        dof=np.where(np.isfinite(welch), welch, dofs),
    )


def warnings(found: NonlinearEstimate, labels: list[str], type_a: np.ndarray) -> list[str]:
    """The warnings of a result whose DUT distortion was found (none otherwise): printed when
    the model carries it (the largest line named), blocking naming the lines it reaches when
    the model does not explain the products."""
    if not found.found:
        return []
    size = np.abs(found.relative_error)
    worst = int(np.argmax(size))
    orders = "-".join(str(o) for o in ORDERS)
    out = [
        f"nonlinear distortion of the DUT: {100 * found.fraction:.2g} % of the signal (orders "
        f"{orders}, measured at {found.tested_bins} detection bins); the best linear "
        "approximation at this excitation is stated, its stochastic part at the lines removed "
        f"(largest {100 * size[worst]:.2g} % at {labels[worst]}) and its estimate's uncertainty "
        "carried in type A"
    ]
    if not found.adequate:
        reached = [lab for lab, hit in zip(labels, found.reached_lines(type_a), strict=True) if hit]
        out.append(
            f"nonlinear distortion at lines {', '.join(reached or labels)}: the order {orders} "
            "model does not explain the products at the detection bins (orders "
            f"{'-'.join(str(o) for o in CHECK_ORDERS)} add to it, p = "
            f"{found.model_p_value:.1g}); U does not cover the distortion it leaves at these lines"
        )
    return out
