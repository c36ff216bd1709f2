"""The budget components ISO 16063-21 Annex A expects of a comparison calibration (issue 25
point 1; SPEC.md section 7), as one typed table, and the check of a budget against it.

A stand file tags each of its components with the kind(s) it covers (`kind = "temperature"`
or a list); a budget that does not cover every required (kind, quantity) is not a full
budget: its run is "results for review", never PASS, and no certificate is issued. Terms the
procedure measures itself (hum, background) carry no kind, so they never make an incomplete
stand budget look complete. Pure Python, no I/O.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

__all__ = [
    "ANNEX_A",
    "ComponentKind",
    "Required",
    "incomplete_budget_text",
    "missing_components",
]


class ComponentKind(StrEnum):
    """What a type B component stands for (ISO 16063-21 Annex A, SPEC.md section 7)."""

    REFERENCE_CALIBRATION = "reference_calibration"
    REFERENCE_FREQUENCY_DEPENDENCE = "reference_frequency_dependence"
    REFERENCE_AMPLITUDE_DEPENDENCE = "reference_amplitude_dependence"  # linearity
    REFERENCE_PHASE = "reference_phase"
    REFERENCE_EXTRAPOLATION = "reference_extrapolation"  # optional: outside its certificate
    AMPLIFIER_GAIN = "amplifier_gain"
    AMPLIFIER_PHASE = "amplifier_phase"
    DAQ_GAIN = "daq_gain"
    DAQ_LINEARITY = "daq_linearity"
    CHANNEL_PHASE_MATCH = "channel_phase_match"  # anti-alias filters, conditioning
    SKEW = "skew"  # the DUT channel's sampling delay, its tolerance: 360 f u(tau) degrees
    TRANSVERSE_MOTION = "transverse_motion"
    MOUNTING = "mounting"  # relative motion of DUT and reference
    TEMPERATURE = "temperature"
    RESIDUAL = "residual"  # distortion, hum, noise bias, other residual effects
    OTHER = "other"


@dataclass(frozen=True)
class Required:
    """One entry of the Annex A table: a kind the budget must state for a quantity."""

    kind: ComponentKind
    quantity: str  # "magnitude" (relative) or "phase" (degrees), as dsp.uncertainty.Quantity
    description: str


# ISO 16063-21 Annex A (Tables A.1/A.2 for the comparison method): the components a full
# budget names. Extrapolation beyond the reference's certificate is optional (default: the
# line is refused), so it is not in this table.
ANNEX_A: tuple[Required, ...] = (
    Required(ComponentKind.REFERENCE_CALIBRATION, "magnitude", "reference standard calibration"),
    Required(
        ComponentKind.REFERENCE_FREQUENCY_DEPENDENCE,
        "magnitude",
        "reference frequency dependence (interpolation, drift)",
    ),
    Required(
        ComponentKind.REFERENCE_AMPLITUDE_DEPENDENCE,
        "magnitude",
        "reference amplitude dependence (linearity)",
    ),
    Required(ComponentKind.AMPLIFIER_GAIN, "magnitude", "conditioning amplifier gains"),
    Required(ComponentKind.DAQ_GAIN, "magnitude", "DAQ gain"),
    Required(ComponentKind.DAQ_LINEARITY, "magnitude", "DAQ linearity"),
    Required(ComponentKind.TRANSVERSE_MOTION, "magnitude", "transverse motion"),
    Required(ComponentKind.MOUNTING, "magnitude", "mounting / relative motion"),
    Required(ComponentKind.TEMPERATURE, "magnitude", "temperature"),
    Required(ComponentKind.RESIDUAL, "magnitude", "residual effects"),
    Required(ComponentKind.REFERENCE_PHASE, "phase", "reference standard phase calibration"),
    Required(ComponentKind.SKEW, "phase", "channel skew (sampling delay) uncertainty"),
    Required(ComponentKind.CHANNEL_PHASE_MATCH, "phase", "channel phase match"),
    Required(ComponentKind.AMPLIFIER_PHASE, "phase", "conditioning amplifier phase"),
)


class _Tagged(Protocol):
    """What the check reads of a component (dsp.uncertainty.Component)."""

    @property
    def kind(self) -> tuple[ComponentKind, ...]: ...

    @property
    def quantity(self) -> str: ...


class _HasComponents(Protocol):
    @property
    def components(self) -> tuple[_Tagged, ...]: ...


def missing_components(budget: _HasComponents) -> list[str]:
    """Annex A components `budget` does not state, as "quantity: description (kind)", in
    table order; empty for a full budget. A component counts for every kind it is tagged with,
    for its own quantity only (a magnitude term says nothing about the phase)."""
    stated = _stated(budget.components)
    return [
        f"{r.quantity}: {r.description} ({r.kind.value})"
        for r in ANNEX_A
        if (r.kind, r.quantity) not in stated
    ]


def _stated(components: Iterable[_Tagged]) -> set[tuple[ComponentKind, str]]:
    return {(k, str(c.quantity)) for c in components for k in c.kind}


def incomplete_budget_text(missing: Iterable[str]) -> str:
    """The one wording of the blocking "incomplete budget" warning (app.records.warnings
    classifies it by its start)."""
    names = "; ".join(missing)
    return f"incomplete budget: results for review only; the stand's budget does not state {names}"
