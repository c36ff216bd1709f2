"""Presentation helpers shared by the CLI, the GUI and the certificate."""

from __future__ import annotations

import math
from collections.abc import Sequence
from decimal import ROUND_HALF_UP, Decimal, localcontext
from typing import Any


def _round_half_up(x: float, exponent: int) -> Decimal:
    """`x` rounded to a multiple of 10**exponent, ties away from zero, on the decimal that
    prints as `x` (repr): 9.95 -> 10 and 1.25e-05 -> 1.3e-05, although the binary doubles lie
    just below and just above those ties."""
    with localcontext() as ctx:
        ctx.prec = 800  # enough for any double at any exponent: quantize never raises
        return Decimal(repr(float(x))).quantize(Decimal(1).scaleb(exponent), ROUND_HALF_UP)


def round_gum(value: float, uncertainty: float, digits: int = 2) -> tuple[str, str]:
    """Round per GUM 7.2.6: uncertainty to `digits` significant digits, value to the same place."""
    if not (math.isfinite(value) and math.isfinite(uncertainty)) or uncertainty <= 0:
        return (f"{value:.4g}" if math.isfinite(value) else "n/a", "n/a")
    exponent = Decimal(repr(float(uncertainty))).adjusted() - (digits - 1)
    rounded_u = _round_half_up(uncertainty, exponent)
    if rounded_u >= Decimal(1).scaleb(exponent + digits):  # 0.0996 -> 0.10: one digit fewer
        exponent += 1
        rounded_u = _round_half_up(uncertainty, exponent)
    decimals = max(0, -exponent)
    text = f"{_round_half_up(value, exponent):.{decimals}f}"
    if float(text) == 0:
        text = text.lstrip("-")
    return text, f"{rounded_u:.{decimals}f}"


def signed(value: float, decimals: int) -> str:
    """'+0.12', '-0.05', and '0.00' rather than '-0.00'."""
    text = f"{value:+.{decimals}f}"
    return text[1:] if float(text) == 0 else text


def significant(value: float, digits: int = 2) -> str:
    """`value` to `digits` significant digits, trailing zeros kept (0.80, 1.2, 12)."""
    if not math.isfinite(value) or value == 0:
        return "n/a" if not math.isfinite(value) else "0"
    exponent = Decimal(repr(float(value))).adjusted() - (digits - 1)
    if abs(_round_half_up(value, exponent)) >= Decimal(1).scaleb(exponent + digits):
        exponent += 1  # 9.96 -> 10: one digit fewer after the point
    decimals = max(0, -exponent)  # never rounded left of the point: 123.4 -> 123
    return f"{_round_half_up(value, -decimals):.{decimals}f}"


def percent(ratio: float, decimals: int = 2) -> str:
    """A ratio (0.01) as a percentage string ('1.00 %'), 'n/a' when not finite."""
    return f"{100 * ratio:.{decimals}f} %" if math.isfinite(ratio) else "n/a"


NOT_STATED_SHORT = "n/s"  # a table cell of a line that is not stated


def not_stated_notes(lines: Sequence[Any]) -> list[str]:
    """One note per reason a line is not stated (dsp.calibration.LineResult.not_stated),
    naming the lines: "n/s (not stated) at 25000, 31500 Hz: outside ..."."""
    reasons: dict[str, list[str]] = {}
    for ln in lines:
        if ln.not_stated:
            reasons.setdefault(ln.not_stated, []).append(f"{ln.nominal_frequency_hz:g}")
    return [
        f"{NOT_STATED_SHORT} (not stated) at {', '.join(hz)} Hz: {why}"
        for why, hz in reasons.items()
    ]


COHERENCE_NOT_AVAILABLE = (
    "coherence n/a: one period analysed (the LPM takes its type A from the non-excited bins; "
    "a coherence needs two or more periods)"
)


def coherence(value: float) -> str:
    """A line's coherence (0..1) to 4 decimals, or "n/a" where it is not defined (one period:
    COHERENCE_NOT_AVAILABLE says why)."""
    return f"{value:.4f}" if math.isfinite(value) else "n/a"


def table(headers: list[str], rows: list[list[str]]) -> str:
    """A plain text table with right-aligned columns."""
    widths = [
        max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(headers)
    ]
    lines = ["  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return "\n".join(lines)


def resonance_text(resonance: dict[str, Any] | None) -> str:
    """The mounted-resonance search stored with the results (dsp.resonance.ResonanceSearch's
    dict) in one line: f0 and Q with their expanded uncertainties rounded per GUM 7.2.6, or
    "not found within the plan" with the reason; "not searched" without one."""
    from dsp.resonance import ResonanceSearch

    if resonance is None:
        return "resonance: not searched (run with --resonance)"
    search = ResonanceSearch.from_dict(resonance)
    found = search.resonance
    if found is None:
        return f"resonance: {search.reason}"
    f0, u_f0 = round_gum(found.frequency_hz, found.frequency_expanded_hz)
    q, u_q = round_gum(found.q, found.q_expanded)
    text = (
        f"resonance: f0 = ({f0} ± {u_f0}) Hz, Q = {q} ± {u_q} (k = {found.coverage_factor:.2f}, "
        f"p = {100 * found.coverage_probability:.2f} %), {found.peak_ratio:.2f} x the "
        f"reference line, {found.lines_used} lines fitted"
    )
    return f"{text}; {search.note}" if search.note else text
