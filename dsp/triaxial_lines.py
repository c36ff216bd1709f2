"""The inputs of a triaxial calibration (dsp.triaxial): each (orientation, channel)'s lines
as its run's results state them (ChannelLines: complex sensitivity in mV/(m/s^2), relative
type A with its degrees of freedom, the stated U), and the checks that refuse an inconsistent
set by orientation and channel (a missing orientation or channel, plans that differ, a
channel's runs with and without the skew correction). Pure numpy.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from dsp.calibration import Results
from dsp.errors import InputRefused
from dsp.uncertainty import Budget, Quantity


class Axis(StrEnum):
    """A sensor axis, and the orientation with the exciter along it."""

    X = "x"
    Y = "y"
    Z = "z"


AXES: tuple[Axis, Axis, Axis] = (Axis.X, Axis.Y, Axis.Z)


@dataclass(frozen=True)
class ChannelLines:
    """One channel's lines in one orientation, as its run's results state them (arrays per
    line, plan order): complex sensitivity S (mV/(m/s^2)); relative type A u_A (fraction, on
    each of the in-phase and quadrature parts) with its dof; the combined relative standard
    uncertainty u_c and nu_eff; the stated relative U and k of the magnitude, the phase's U
    (degrees) and k; the deviation from the reference line and its U (%); `stated` False
    where the line is not stated. `phase_stated`: the run's phase was corrected for skew."""

    nominal_frequency_hz: np.ndarray
    frequency_hz: np.ndarray
    sensitivity: np.ndarray
    relative_type_a: np.ndarray
    type_a_dof: np.ndarray
    relative_standard: np.ndarray
    dof: np.ndarray
    relative_expanded: np.ndarray
    coverage_factor: np.ndarray
    phase_expanded_deg: np.ndarray
    phase_coverage_factor: np.ndarray
    deviation_percent: np.ndarray
    deviation_expanded_percent: np.ndarray
    stated: np.ndarray
    reference_index: int
    coverage_probability: float = 0.9545
    phase_stated: bool = True
    # the run's own type B budget (its measured per-channel terms included: the ADC's
    # resolution, hum); None: the budget the combination is given
    budget: Budget | None = field(default=None, compare=False, repr=False)

    @classmethod
    def from_results(cls, results: Results, budget: Budget) -> ChannelLines:
        """From a run's dsp.calibration.Results: the type A's dof is what its nu_eff leaves
        once the budget's finite-dof components are taken out (GUM G.4.1 solved for nu_A)."""
        if not isinstance(results, Results):
            raise InputRefused(f"triaxial: expected dsp.calibration.Results, got {results!r}")
        lines = results.lines
        ref = results.reference.frequency_hz
        index = [i for i, ln in enumerate(lines) if ln.nominal_frequency_hz == ref]
        if not index:
            raise InputRefused(f"triaxial: the reference frequency {ref:g} Hz is not a line")

        def arr(name: str) -> np.ndarray:
            return np.array([getattr(ln, name) for ln in lines], dtype=float)

        magnitude, phase = arr("sensitivity_mv_per_ms2"), arr("phase_deg")
        u_a, u_c, nu = (
            arr("relative_type_a"),
            arr("relative_standard_uncertainty"),
            arr("effective_dof"),
        )
        nu_a = np.array(
            [
                _type_a_dof(u_a[i], u_c[i], nu[i], budget, float(lines[i].frequency_hz))
                for i in range(len(lines))
            ]
        )
        return cls(
            nominal_frequency_hz=arr("nominal_frequency_hz"),
            frequency_hz=arr("frequency_hz"),
            sensitivity=magnitude * np.exp(1j * np.radians(phase)),
            relative_type_a=u_a,
            type_a_dof=nu_a,
            relative_standard=u_c,
            dof=nu,
            relative_expanded=arr("relative_expanded_uncertainty"),
            coverage_factor=arr("coverage_factor"),
            phase_expanded_deg=arr("phase_expanded_uncertainty_deg"),
            phase_coverage_factor=arr("phase_coverage_factor"),
            deviation_percent=arr("deviation_percent"),
            deviation_expanded_percent=arr("deviation_expanded_percent"),
            stated=np.array([ln.stated for ln in lines], dtype=bool),
            reference_index=index[0],
            coverage_probability=results.coverage_probability,
            phase_stated=results.phase_corrected_for_skew,
            budget=budget,
        )


def _type_a_dof(u_a: float, u_c: float, nu_eff: float, budget: Budget, f: float) -> float:
    """nu_A from nu_eff = u_c^4 / (u_A^4/nu_A + sum u_i^4/nu_i) (GUM G.4.1), inf when nu_eff
    is; NaN when u_A is not finite."""
    if not (math.isfinite(u_a) and math.isfinite(u_c) and u_c > 0 and u_a > 0):
        return math.nan if not math.isfinite(u_a) else math.inf
    if not math.isfinite(nu_eff):
        return math.inf
    rest = sum(
        c.standard_uncertainty_at(f) ** 4 / c.dof
        for c in budget.at(f, Quantity.MAGNITUDE)
        if math.isfinite(c.dof)
    )
    left = u_c**4 / nu_eff - rest
    return u_a**4 / left if left > 0 else math.inf


def check_keys(runs: Mapping[str, Mapping[str, object]]) -> None:
    """Refuse a set of runs without the orientations x, y, z each with channels x, y, z."""
    names = [a.value for a in AXES]
    for o in runs:
        if o not in names:
            raise InputRefused(
                f"triaxial: orientation {o!r} is not one of x, y, z (the sensor's axis the "
                "exciter moves along)"
            )
    for o in names:
        if o not in runs:
            raise InputRefused(
                f"triaxial: orientation {o!r} missing: the run with the exciter along the "
                f"sensor's axis {o} is needed (three orientations x, y, z)"
            )
    for o in names:
        for j in runs[o]:
            if j not in names:
                raise InputRefused(f"triaxial: orientation {o!r}: channel {j!r} is not x, y or z")
        for j in names:
            if j not in runs[o]:
                raise InputRefused(
                    f"triaxial: orientation {o!r}: channel {j!r} missing (each orientation "
                    "needs the x, y and z channels' results)"
                )


def check_consistent(lines: Mapping[tuple[Axis, Axis], ChannelLines]) -> None:
    """Refuse lines whose plans, reference line, coverage probability or skew statement
    differ, naming the orientation and channel."""
    first = lines[(Axis.X, Axis.X)]
    for (o, j), ch in lines.items():
        where = f"triaxial: orientation {o.value!r}, channel {j.value!r}"
        if ch.nominal_frequency_hz.shape != first.nominal_frequency_hz.shape or not (
            np.array_equal(ch.nominal_frequency_hz, first.nominal_frequency_hz)
            and np.allclose(ch.frequency_hz, first.frequency_hz, rtol=1e-9, atol=0.0)
        ):
            raise InputRefused(
                f"{where}: its plan's lines differ from orientation 'x', channel 'x' "
                f"({_lines_text(ch)} against {_lines_text(first)}); the three orientations "
                "need one plan"
            )
        if ch.reference_index != first.reference_index:
            raise InputRefused(
                f"{where}: its reference frequency differs from orientation 'x', channel 'x'"
            )
        if ch.coverage_probability != first.coverage_probability:
            raise InputRefused(
                f"{where}: coverage probability {ch.coverage_probability:g} differs from "
                f"orientation 'x', channel 'x' ({first.coverage_probability:g})"
            )
        main = lines[(j, j)]
        if ch.phase_stated != main.phase_stated:
            raise InputRefused(
                f"{where}: its phase is {'' if ch.phase_stated else 'not '}corrected for skew "
                f"and orientation {j.value!r}'s is {'' if main.phase_stated else 'not '}: one "
                "channel's runs need the same skew statement"
            )


def _lines_text(ch: ChannelLines) -> str:
    f = ch.nominal_frequency_hz
    return f"{f.size} lines, {f[0]:g}-{f[-1]:g} Hz" if f.size else "no lines"
