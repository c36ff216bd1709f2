"""Budget terms that follow from what the stand states (issue 25 point 3; SPEC.md section 7):
the phase term of the skew's tolerance, and what to do with a line outside the reference
standard's calibrated range (refuse it, or carry the stand's stated extrapolation term).

Units: frequencies in Hz, times in seconds, phase in degrees, magnitude relative (fraction).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from dsp.annex_a import ComponentKind
from dsp.uncertainty import Budget, Component, Distribution, Law, Quantity

__all__ = ["ReferenceRange", "reference_range", "skew_phase_component"]

SKEW_NAME = "channel skew (sampling delay) tolerance"


def skew_phase_component(
    tolerance_s: float, distribution: Distribution = Distribution.RECTANGULAR
) -> Component:
    """The phase term of a skew tolerance tau (s): 360 f tau degrees at f (Hz), stated at
    f0 = 1 Hz as 360 tau and scaled by f/f0 (law 'power', n = 1). `tolerance_s` is read as the
    distribution says (half-width for rectangular)."""
    if isinstance(tolerance_s, bool) or not isinstance(tolerance_s, int | float):
        raise ValueError(f"skew tolerance: must be a number of seconds, got {tolerance_s!r}")
    if not (math.isfinite(tolerance_s) and 0 <= tolerance_s < 1e-3):
        raise ValueError(f"skew tolerance: must be between 0 and 1 ms, got {tolerance_s!r} s")
    return Component(
        SKEW_NAME,
        360.0 * float(tolerance_s),
        distribution,
        quantity=Quantity.PHASE,
        kind=(ComponentKind.SKEW,),
        law=Law.POWER,
        law_frequency_hz=1.0,
        law_exponent=1.0,
        note=f"360 f u(tau) degrees, tau tolerance {tolerance_s:g} s",
    )


@dataclass(frozen=True)
class ReferenceRange:
    """Per line: inside the reference's certificate, outside but carried by the stand's
    extrapolation term, or refused (no such term: the default)."""

    inside: tuple[bool, ...]
    extrapolated: tuple[bool, ...]
    refused: tuple[bool, ...]

    def messages(self, frequencies_hz: Sequence[float], lo: float, hi: float) -> list[str]:
        """One line per line outside the certificate, saying what was done."""
        out = []
        for f, ext, ref in zip(frequencies_hz, self.extrapolated, self.refused, strict=True):
            span = f"outside the reference certificate ({lo:g}-{hi:g} Hz)"
            if ref:
                out.append(
                    f"line {f:g} Hz: {span}: refused, not stated (state a "
                    "'reference_extrapolation' component in the stand file to carry it)"
                )
            elif ext:
                out.append(f"line {f:g} Hz: {span}: carried with the stated extrapolation term")
        return out


def reference_range(
    frequencies_hz: Sequence[float], calibrated_hz: Sequence[float], budget: Budget
) -> ReferenceRange:
    """Which lines lie outside [min, max] of the certificate's frequencies (Hz), and whether
    the budget states a 'reference_extrapolation' term (magnitude and phase) applying there;
    a line outside with no such term is refused."""
    if not calibrated_hz:
        raise ValueError("reference range: the certificate has no frequencies")
    lo, hi = min(calibrated_hz), max(calibrated_hz)
    inside, extrapolated, refused = [], [], []
    for f in frequencies_hz:
        ok = lo <= f <= hi
        carried = not ok and all(
            any(ComponentKind.REFERENCE_EXTRAPOLATION in c.kind for c in budget.at(f, q))
            for q in (Quantity.MAGNITUDE, Quantity.PHASE)
        )
        inside.append(ok)
        extrapolated.append(carried)
        refused.append(not ok and not carried)
    return ReferenceRange(tuple(inside), tuple(extrapolated), tuple(refused))
