"""The amplitude-frequency characteristic: per line the deviation of the sensitivity from its
value at the reference frequency (%) with its expanded uncertainty (%), and the phase (degree)
with its expanded uncertainty (degree). The one answer the GUI, the certificate and the DCC show.

SPEC.md section 8 states the characteristic as S(f)/S(f_ref). With dev = S/S_ref - 1 and S_ref
treated as exact (its own uncertainty is the reference line's, stated at the reference
frequency), the GUM law of propagation (JCGM 100:2008, 5.1.2) gives
u(dev) = u(S)/S_ref = u_rel(S) * S/S_ref = (1 + dev) * u_rel(S); so U(dev) = (1 + dev) * U_rel(S).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from dsp.calibration import Results


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
    """The characteristic of `results` (dsp.calibration.Results), see the module docstring."""
    lines = results.lines
    deviation = np.array([ln.deviation_percent for ln in lines], dtype=float)
    return Characteristic(
        frequency_hz=np.array([ln.frequency_hz for ln in lines], dtype=float),
        deviation_percent=deviation,
        deviation_expanded_percent=np.array(
            [
                deviation_expanded_percent(d, ln.relative_expanded_uncertainty)
                for d, ln in zip(deviation, lines, strict=True)
            ],
            dtype=float,
        ),
        phase_deg=np.array([ln.phase_deg for ln in lines], dtype=float),
        phase_expanded_deg=np.array(
            [ln.phase_expanded_uncertainty_deg for ln in lines], dtype=float
        ),
    )
