"""Mounted-resonance search from a measured frequency response (issue 26 point 4, issue 32
point 5).

A low-level plan of closely spaced lines up to 20 kHz or more gives the DUT/reference response
H(f) per line (complex, e.g. dsp.lpm.estimate). The mounted resonance is the largest peak of |H|
above the mid band, fitted near the peak by one second-order mode,
H(w) (w0^2 - w^2 + j w w0/Q) = n (Levy's linearised least squares: real unknowns a = w0^2 and
b = w0/Q, complex n, over the lines within the half-power band of the peak, the flanks' lines
down to FIT_LEVEL of the peak, and one line beyond on each side). Frequencies in Hz.

A resonance is stated only when the plan brackets it: the peak at an interior line, a line on
each side of it below the half-power level |H|peak/sqrt(2), and the fitted f0 between those
two lines. Otherwise it is "not found within the plan", with the reason (a peak the plan did
not bracket says nothing about the mounting).

Uncertainty of f0 and Q: the lines' standard uncertainties (relative, of both the real and the
imaginary part of H, e.g. the estimator's type A) propagated through the fit (its Jacobian,
by central differences), scaled by sqrt(chi^2/nu) when the fit's residual is larger than
those uncertainties explain (nu = 2 m - 4 for m lines fitted, 2 m - 6 with the numerator's
slope; the coverage factor is then
Student's t at nu degrees of freedom, else k for the normal distribution). Without stated
line uncertainties the residual alone sets them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from dsp.uncertainty import coverage_factor

MIN_RISE = 1.2  # a peak must stand this far above the mid band (|H| ratio) to count
FIT_LEVEL = 0.25  # the fit takes the lines down to this fraction of the peak's |H|
SLOPE_LINES = 5  # from this many lines fitted the numerator takes a slope too
NOT_FOUND = "not found within the plan"


@dataclass(frozen=True)
class Resonance:
    """Fitted mode: frequency in Hz and quality factor Q with their expanded uncertainties
    (same coverage factor `coverage_factor`), peak |H| over the mid band, lines fitted."""

    frequency_hz: float
    q: float
    peak_ratio: float
    lines_used: int
    frequency_expanded_hz: float = math.nan
    q_expanded: float = math.nan
    coverage_factor: float = math.nan
    coverage_probability: float = 0.9545


class ResonanceError(ValueError):
    """Input from which no resonance can be stated; the message names the reason."""


@dataclass(frozen=True)
class ResonanceSearch:
    """The search's outcome, as stored with the results: the resonance, or why none was
    found within the plan (`reason`)."""

    resonance: Resonance | None
    reason: str = ""
    note: str = ""  # what the statement assumes (e.g. the reference beyond its certificate)

    @property
    def found(self) -> bool:
        return self.resonance is not None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (NaN as None)."""
        data: dict[str, Any] = {"found": self.found, "reason": self.reason, "note": self.note}
        if self.resonance is not None:
            for key, value in asdict(self.resonance).items():
                data[key] = value if not isinstance(value, float) or math.isfinite(value) else None
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ResonanceSearch:
        """Rebuild from `to_dict` (ValueError naming the field on bad input)."""
        try:
            note = str(data.get("note", ""))
            if not data["found"]:
                return cls(None, str(data["reason"]), note)

            def number(key: str) -> float:
                value = data.get(key)
                return math.nan if value is None else float(value)

            found = Resonance(
                frequency_hz=number("frequency_hz"),
                q=number("q"),
                peak_ratio=number("peak_ratio"),
                lines_used=int(data["lines_used"]),
                frequency_expanded_hz=number("frequency_expanded_hz"),
                q_expanded=number("q_expanded"),
                coverage_factor=number("coverage_factor"),
                coverage_probability=number("coverage_probability"),
            )
            return cls(found, "", note)
        except (KeyError, TypeError) as exc:
            raise ValueError(f"resonance: missing or malformed field ({exc})") from None


def search_resonance(
    frequencies_hz: Sequence[float] | np.ndarray,
    response: Sequence[complex] | np.ndarray,
    relative_uncertainty: Sequence[float] | np.ndarray | None = None,
    *,
    mid_band_hz: float | None = None,
    probability: float = 0.9545,
) -> ResonanceSearch:
    """`find_resonance` as a value: the resonance, or the reason it is not found within the
    plan (bad input still raises ResonanceError)."""
    try:
        found = find_resonance(
            frequencies_hz,
            response,
            relative_uncertainty,
            mid_band_hz=mid_band_hz,
            probability=probability,
        )
    except _NotBracketed as exc:
        return ResonanceSearch(None, str(exc))
    return ResonanceSearch(found)


def search_response(
    frequencies_hz: np.ndarray,
    response: np.ndarray,
    relative_uncertainty: np.ndarray,
    *,
    mid_band_hz: float,
    calibrated_hz: tuple[float, float] | None,
) -> ResonanceSearch:
    """The search in a calibration's complex sensitivity per line (dsp.calibration: with the
    estimator's type A, referred to the reference line) as stored with its results: bad input
    is "not found" too, with the reason. `calibrated_hz`: the reference's certificate span;
    lines beyond it take its end value (noted): a resonance is a shape, stated with its own
    uncertainty, not a sensitivity."""
    try:
        found = search_resonance(
            frequencies_hz, response, relative_uncertainty, mid_band_hz=mid_band_hz
        )
    except ResonanceError as exc:
        return ResonanceSearch(None, f"{NOT_FOUND}: {exc}")
    if calibrated_hz is None:
        return found
    lo, hi = calibrated_hz
    if all(lo <= f <= hi for f in frequencies_hz):
        return found
    note = (
        f"lines beyond the reference's certificate ({lo:g}-{hi:g} Hz) take its response at "
        "the nearer end point"
    )
    return ResonanceSearch(found.resonance, found.reason, note)


class _NotBracketed(ResonanceError):
    """The plan does not bracket a resonance (the message says why)."""


def find_resonance(
    frequencies_hz: Sequence[float] | np.ndarray,
    response: Sequence[complex] | np.ndarray,
    relative_uncertainty: Sequence[float] | np.ndarray | None = None,
    *,
    mid_band_hz: float | None = None,
    probability: float = 0.9545,
) -> Resonance:
    """The largest resonance of `response` (complex per line, lines ascending in Hz) with the
    expanded uncertainties of f0 and Q at `probability` (module docstring).

    `relative_uncertainty`: per line, the standard uncertainty of H relative to |H| (None:
    from the fit's residual). `mid_band_hz`: |H| is referred to the line nearest it (default:
    the lowest line) and the peak sought above it. ResonanceError, its message starting
    "not found within the plan", when the plan does not bracket a resonance (module
    docstring) or no line stands `MIN_RISE` above the mid band; ResonanceError on bad input.
    """
    f = np.asarray(frequencies_hz, dtype=float)
    h = np.asarray(response, dtype=complex)
    if f.ndim != 1 or f.shape != h.shape or f.size < 5:
        raise ResonanceError("response: needs at least 5 lines, one value per frequency")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(h)) and np.all(np.diff(f) > 0)):
        raise ResonanceError("response: frequencies must be finite and ascending, values finite")
    if relative_uncertainty is None:
        u_rel = np.zeros(f.size)
    else:
        u_rel = np.asarray(relative_uncertainty, dtype=float)
        if u_rel.shape != f.shape or not np.all(np.isfinite(u_rel) & (u_rel >= 0)):
            raise ResonanceError("response: one finite uncertainty >= 0 per line")
    if not 0 < probability < 1:
        raise ResonanceError(f"probability: must be between 0 and 1, got {probability!r}")
    magnitude = np.abs(h)
    reference = 0 if mid_band_hz is None else int(np.argmin(np.abs(f - mid_band_hz)))
    mid = magnitude[reference]
    if not mid > 0:
        raise ResonanceError("response: zero at the mid-band line")
    peak = reference + int(np.argmax(magnitude[reference:]))
    ratio = float(magnitude[peak] / mid)
    if ratio < MIN_RISE:
        raise _NotBracketed(
            f"{NOT_FOUND}: no resonance up to {f[-1]:g} Hz (peak {ratio:.2f} x the mid band)"
        )
    if peak == f.size - 1:
        raise _NotBracketed(
            f"{NOT_FOUND}: still rising at the highest line {f[-1]:g} Hz; the resonance lies "
            "above the plan, extend it"
        )
    half = magnitude[peak] / math.sqrt(2.0)
    lo = peak
    while lo > reference and magnitude[lo - 1] >= half:
        lo -= 1
    hi = peak
    while hi < f.size - 1 and magnitude[hi + 1] >= half:
        hi += 1
    lo, hi = lo - 1, hi + 1
    if lo < reference or hi > f.size - 1:
        side = "below" if lo < reference else "above"
        raise _NotBracketed(
            f"{NOT_FOUND}: the peak near {f[peak]:g} Hz has no line {side} it under its "
            "half-power level; add lines around it"
        )
    while lo > reference and magnitude[lo - 1] >= FIT_LEVEL * magnitude[peak]:
        lo -= 1  # closely spaced lines: the fit takes the flanks too (a smaller U)
    while hi < f.size - 1 and magnitude[hi + 1] >= FIT_LEVEL * magnitude[peak]:
        hi += 1
    window = slice(lo, hi + 1)
    scale = 2.0 * math.pi * f[peak]
    w = 2.0 * math.pi * f[window] / scale  # normalised angular frequency
    hh = h[window]
    f0, q, model = _fit(w, hh, scale)
    if not (math.isfinite(f0) and math.isfinite(q)):
        raise _NotBracketed(f"{NOT_FOUND}: the peak near {f[peak]:g} Hz does not fit one mode")
    if not f[lo] < f0 < f[hi]:
        raise _NotBracketed(
            f"{NOT_FOUND}: the mode fitted at {f0:g} Hz lies outside the lines that bracket "
            f"the peak ({f[lo]:g}-{f[hi]:g} Hz); add lines around {f[peak]:g} Hz"
        )
    u_f0, u_q, k = _uncertainty(w, hh, model, u_rel[window] * np.abs(hh), scale, probability)
    return Resonance(
        frequency_hz=f0,
        q=q,
        peak_ratio=ratio,
        lines_used=int(w.size),
        frequency_expanded_hz=k * u_f0,
        q_expanded=k * u_q,
        coverage_factor=k,
        coverage_probability=probability,
    )


def _fit(w: np.ndarray, h: np.ndarray, scale: float) -> tuple[float, float, np.ndarray]:
    """Levy's fit over normalised angular frequencies `w`: f0 (Hz), Q and the model at `w`
    (NaN, NaN when the peak does not fit one mode). From SLOPE_LINES lines on, the numerator
    is n0 + n1 w, which takes up a smooth tilt across the band (the reference's own response
    beyond its certificate, a neighbouring mode) that would otherwise shift f0."""
    jwh = 1j * w * h
    ones, zeros = np.ones(w.size), np.zeros(w.size)
    real = [h.real, jwh.real, -ones, zeros]
    imag = [h.imag, jwh.imag, zeros, -ones]
    slope = w.size >= SLOPE_LINES
    if slope:
        real += [-w, zeros]
        imag += [zeros, -w]
    rows = np.vstack([np.column_stack(real), np.column_stack(imag)])
    rhs = np.concatenate([(w**2 * h).real, (w**2 * h).imag])
    solution, *_ = np.linalg.lstsq(rows, rhs, rcond=None)
    a, b = solution[0], solution[1]
    if not (a > 0 and b > 0):
        return math.nan, math.nan, np.full(w.size, np.nan, dtype=complex)
    numerator = complex(solution[2], solution[3]) + (
        complex(solution[4], solution[5]) * w if slope else 0.0
    )
    w0 = math.sqrt(a)
    model = numerator / (a - w**2 + 1j * w * b)
    return float(w0 * scale / (2.0 * math.pi)), float(w0 / b), model


def _uncertainty(
    w: np.ndarray,
    h: np.ndarray,
    model: np.ndarray,
    sigma: np.ndarray,
    scale: float,
    probability: float,
) -> tuple[float, float, float]:
    """Standard uncertainties of f0 (Hz) and Q, and the coverage factor (module docstring).
    `sigma`: the absolute standard uncertainty of the real and of the imaginary part of each
    line of `h`."""
    nu = 2 * w.size - (6 if w.size >= SLOPE_LINES else 4)
    residual = np.abs(h - model) ** 2
    rms = math.sqrt(float(residual.sum()) / (2 * nu)) if nu > 0 else 0.0
    from_residual = not np.any(sigma > 0)
    if from_residual:
        sigma = np.full(w.size, rms)
    scaled = 1.0
    if nu > 0 and not from_residual:
        chi2 = float(np.sum(residual / np.maximum(sigma, 1e-300) ** 2)) / 2.0
        scaled = max(1.0, chi2 / nu)
    jacobian = np.zeros((2, 2 * w.size))
    for i in range(w.size):
        step = 1e-6 * max(abs(h[i]), 1e-300)
        for part, delta in enumerate((step, 1j * step)):
            plus, minus = h.copy(), h.copy()
            plus[i] += delta
            minus[i] -= delta
            f_p, q_p, _ = _fit(w, plus, scale)
            f_m, q_m, _ = _fit(w, minus, scale)
            jacobian[:, 2 * i + part] = ((f_p - f_m) / (2 * step), (q_p - q_m) / (2 * step))
    weights = np.repeat(sigma, 2)
    variance = (jacobian * weights) ** 2 @ np.ones(2 * w.size) * scaled
    if not np.all(np.isfinite(variance)):
        return math.inf, math.inf, math.nan
    k = coverage_factor(nu if (from_residual or scaled > 1.0) and nu > 0 else math.inf, probability)
    return math.sqrt(float(variance[0])), math.sqrt(float(variance[1])), k
