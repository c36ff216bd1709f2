"""The budget components ISO 16063-21 Annex A expects of a comparison calibration (issue 25
point 1; SPEC.md section 7), as one typed table, and the check of a budget against it.

A stand file tags each of its components with the one kind it covers (`kind = "temperature"`;
a list of several is refused by name, and so is a value below its kind's plausible minimum,
issue 32 point 1); a budget that does not cover every required (kind, quantity) is not a full
budget: its run is "results for review", never PASS, and no certificate is issued. Terms the
procedure measures itself (hum, background) carry no kind, so they never make an incomplete
stand budget look complete. Pure Python, no I/O.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

__all__ = [
    "ANNEX_A",
    "PLAUSIBLE_MINIMUM",
    "ComponentKind",
    "Required",
    "implausible_budget_text",
    "implausible_components",
    "incomplete_budget_text",
    "missing_components",
    "plausible_floor",
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


# The least standard uncertainty (in the component's unit: relative for magnitude, degrees for
# phase, at the law's f0) a component of each kind can plausibly state (issue 32 point 1). They
# are well below what any comparison stand achieves (the best primary calibrations of a
# reference standard state about 0.1 % and 0.1 degrees, k = 2) and only catch a budget made
# complete by tags with nominal values (1e-9); the laboratory's CMC (dsp.cmc) is what bounds
# a stated U in practice. The skew's term is 360 f tau stated at f0 = 1 Hz: 2e-8 degrees is a
# tolerance of about 0.1 ns (rectangular).
PLAUSIBLE_MINIMUM: dict[ComponentKind, float] = {
    ComponentKind.REFERENCE_CALIBRATION: 5e-4,
    ComponentKind.REFERENCE_FREQUENCY_DEPENDENCE: 1e-5,
    ComponentKind.REFERENCE_AMPLITUDE_DEPENDENCE: 1e-5,
    ComponentKind.REFERENCE_PHASE: 0.02,
    ComponentKind.REFERENCE_EXTRAPOLATION: 1e-5,
    ComponentKind.AMPLIFIER_GAIN: 1e-5,
    ComponentKind.AMPLIFIER_PHASE: 1e-3,
    ComponentKind.DAQ_GAIN: 1e-5,
    ComponentKind.DAQ_LINEARITY: 1e-6,
    ComponentKind.CHANNEL_PHASE_MATCH: 1e-3,
    ComponentKind.SKEW: 2e-8,
    ComponentKind.TRANSVERSE_MOTION: 1e-5,
    ComponentKind.MOUNTING: 1e-5,
    ComponentKind.TEMPERATURE: 1e-5,
    ComponentKind.RESIDUAL: 1e-6,
}
# (ComponentKind.OTHER has no minimum: it names what the table does not.)


def plausible_floor(quantity: str) -> float:
    """The least expanded uncertainty (k = 2; relative for "magnitude", degrees for "phase") a
    full budget of plausible minima gives: 2 sqrt(sum u_min^2) over the Annex A kinds required
    for `quantity`. A stated U below it is rounding noise or a budget left out, never a basis
    for a conformity statement (issue 32 point 7)."""
    mins = [PLAUSIBLE_MINIMUM[r.kind] for r in ANNEX_A if r.quantity == quantity]
    if not mins:
        raise ValueError(
            f"plausible floor: quantity must be 'magnitude' or 'phase', got {quantity!r}"
        )
    return 2.0 * math.sqrt(sum(u * u for u in mins))


class _Tagged(Protocol):
    """What the check reads of a component (dsp.uncertainty.Component)."""

    @property
    def name(self) -> str: ...

    @property
    def kind(self) -> tuple[ComponentKind, ...]: ...

    @property
    def quantity(self) -> str: ...

    @property
    def standard_uncertainty(self) -> float: ...


class _HasComponents(Protocol):
    @property
    def components(self) -> tuple[_Tagged, ...]: ...


def missing_components(budget: _HasComponents) -> list[str]:
    """Annex A components `budget` does not state, as "quantity: description (kind)", in
    table order; empty for a full budget. A component counts for its one kind, for its own
    quantity only (a magnitude term says nothing about the phase), and not at all when it is
    tagged with several kinds or below its kind's plausible minimum (implausible_components)."""
    stated = _stated(budget.components)
    return [
        f"{r.quantity}: {r.description} ({r.kind.value})"
        for r in ANNEX_A
        if (r.kind, r.quantity) not in stated
    ]


def _stated(components: Iterable[_Tagged]) -> set[tuple[ComponentKind, str]]:
    """The (kind, quantity) pairs stated: a component counts only for a single kind and only
    when it is at least that kind's plausible minimum (issue 32 point 1)."""
    return {
        (c.kind[0], str(c.quantity))
        for c in components
        if len(c.kind) == 1 and not _below_minimum(c)
    }


def _below_minimum(component: _Tagged) -> bool:
    least = PLAUSIBLE_MINIMUM.get(component.kind[0]) if len(component.kind) == 1 else None
    return least is not None and component.standard_uncertainty < least


def implausible_components(budget: _HasComponents) -> list[str]:
    """Each component of `budget` that cannot state an Annex A kind, named with why: tagged
    with several kinds (one value cannot stand for several independent effects: split it), or
    a standard uncertainty below its kind's plausible minimum (PLAUSIBLE_MINIMUM); empty for a
    plausible budget. Such a component states none of its kinds (missing_components)."""
    out = []
    for c in budget.components:
        if len(c.kind) > 1:
            kinds = ", ".join(k.value for k in c.kind)
            out.append(f"{c.name!r} is tagged with several kinds ({kinds}): one component per kind")
        elif _below_minimum(c):
            least = PLAUSIBLE_MINIMUM[c.kind[0]]
            unit = "degrees" if str(c.quantity) == "phase" else "(relative)"
            out.append(
                f"{c.name!r} ({c.kind[0].value}): standard uncertainty "
                f"{c.standard_uncertainty:.3g} {unit} is below the plausible minimum "
                f"{least:g} for its kind"
            )
    return out


def implausible_budget_text(refused: Iterable[str]) -> str:
    """The one wording of the blocking "implausible budget" warning (app.records.warnings
    classifies it by its start)."""
    return "implausible budget: results for review only; refused component(s): " + "; ".join(
        refused
    )


def incomplete_budget_text(missing: Iterable[str]) -> str:
    """The one wording of the blocking "incomplete budget" warning (app.records.warnings
    classifies it by its start)."""
    names = "; ".join(missing)
    return f"incomplete budget: results for review only; the stand's budget does not state {names}"
