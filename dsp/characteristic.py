"""The amplitude-frequency characteristic: per line the deviation of the sensitivity from its
value at the reference frequency (%) with its expanded uncertainty (%), and the phase (degree)
with its expanded uncertainty (degree). The one answer the GUI, the certificate and the DCC show.

SPEC.md section 8 states the characteristic as S(f)/S(f_ref), dev = S/S_ref - 1. Its
uncertainty is the correlated model (issue 25 point 4; JCGM 100:2008 5.2): S(f) and S(f_ref)
share every factor common to both lines, and a common factor cancels in the ratio: the
reference standard's calibration at the reference frequency, the conditioning amplifier gains,
the DAQ gains and the temperature coefficient (COMMON_KINDS; only a component that applies at
both lines with a constant law is common). What stays: the type A of the line and the type A
of the reference line (added: the periodic estimators' noise is independent from bin to bin,
the lines on different bins, so the two are uncorrelated), and every other component at the
line (reference frequency dependence, linearity, mounting, transverse motion, residual
effects, hum), carried at its value at f as a bound (a cause acting on both lines alike
partly cancels; stated at f it is not understated). Relative standard uncertainty of the ratio
u_r, nu_eff by Welch-Satterthwaite, k as the line's rule; U(dev) = (1 + dev) * k * u_r in %.
At the reference line dev = 0 by definition; its U(dev) is stated as that line's own U_rel(S)
(the uncertainty of the point everything is referred to). `deviation_expanded_percent`
(U(dev) = (1 + dev) * U_rel(S)) remains for results stored before issue 25.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from dsp.annex_a import ComponentKind
from dsp.uncertainty import Budget, Combined, Component, Distribution, Law, Quantity, combine

if TYPE_CHECKING:
    from dsp.calibration import LineResult, Results

# the factors S(f) and S(f_ref) share: they cancel in the ratio
COMMON_KINDS = frozenset(
    {
        ComponentKind.REFERENCE_CALIBRATION,
        ComponentKind.AMPLIFIER_GAIN,
        ComponentKind.DAQ_GAIN,
        ComponentKind.TEMPERATURE,
    }
)
REFERENCE_LINE_TYPE_A = "type A of the reference line"


def is_common(component: Component, frequency_hz: float, reference_hz: float) -> bool:
    """Whether `component` is one factor of both S(f) and S(f_ref) (it cancels in dev)."""
    return (
        bool(component.kind)
        and all(k in COMMON_KINDS for k in component.kind)
        and component.law is Law.CONSTANT
        and component.applies_at(frequency_hz)
        and component.applies_at(reference_hz)
    )


def ratio_uncertainty(
    type_a: float,
    type_a_dof: float,
    reference_type_a: float,
    reference_type_a_dof: float,
    budget: Budget,
    frequency_hz: float,
    reference_hz: float,
    *,
    probability: float = 0.9545,
    rule: str = "gum",
    periods: int | None = None,
) -> Combined:
    """The relative uncertainty of S(f)/S(f_ref) by the correlated model (module docstring):
    type A at f (relative) with the reference line's type A as one more input, the budget's
    magnitude components at f except the common ones. Relative (fraction)."""
    kept = [
        c
        for c in budget.at(frequency_hz, Quantity.MAGNITUDE)
        if not is_common(c, frequency_hz, reference_hz)
    ]
    if math.isfinite(reference_type_a) and reference_type_a > 0:
        kept.append(
            Component(
                REFERENCE_LINE_TYPE_A,
                float(reference_type_a),
                Distribution.STANDARD,
                dof=float(reference_type_a_dof),
            )
        )
    return combine(
        type_a,
        type_a_dof,
        Budget(tuple(kept)),
        frequency_hz,
        Quantity.MAGNITUDE,
        probability=probability,
        rule=rule,
        periods=periods,
    )


def line_deviation_expanded_percent(line: LineResult) -> float:
    """U of a line's deviation in %: the stored correlated-model value, or for results stored
    before issue 25 (NaN there) (1 + dev) * U_rel(S)."""
    stored = line.deviation_expanded_percent
    if math.isfinite(stored):
        return stored
    return deviation_expanded_percent(line.deviation_percent, line.relative_expanded_uncertainty)


def deviation_expanded_percent(deviation_percent: float, relative_expanded: float) -> float:
    """U of the deviation in % from the deviation (%) and the sensitivity's relative U
    (fraction): (1 + dev) * U_rel * 100; NaN where U_rel is not finite."""
    if not math.isfinite(relative_expanded):
        return math.nan
    return 100.0 * relative_expanded * (1.0 + deviation_percent / 100.0)


@dataclass(frozen=True)
class Characteristic:
    """Per line (arrays of equal length): frequency (Hz), deviation and its U (%), phase and
    its U (degree). A U that is not stated is NaN."""

    frequency_hz: np.ndarray
    deviation_percent: np.ndarray
    deviation_expanded_percent: np.ndarray
    phase_deg: np.ndarray
    phase_expanded_deg: np.ndarray


def characteristic(results: Results) -> Characteristic:
    """The characteristic of `results` (dsp.calibration.Results), see the module docstring,
    over the stated lines only: a line that is not stated (outside the reference's calibrated
    range) is not drawn, with no value and no U."""
    lines = [ln for ln in results.lines if ln.stated]
    deviation = np.array([ln.deviation_percent for ln in lines], dtype=float)
    return Characteristic(
        frequency_hz=np.array([ln.frequency_hz for ln in lines], dtype=float),
        deviation_percent=deviation,
        deviation_expanded_percent=np.array(
            [line_deviation_expanded_percent(ln) for ln in lines], dtype=float
        ),
        phase_deg=np.array([ln.phase_deg for ln in lines], dtype=float),
        phase_expanded_deg=np.array(
            [ln.phase_expanded_uncertainty_deg for ln in lines], dtype=float
        ),
    )
