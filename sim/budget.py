"""The simulated stand's own uncertainty budget (sim/stand.toml) and the systematic deviations
it draws from it per seed: relative factors (reference certificate, gains, mounting) and a
phase in degrees, which the analysis never sees.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from dsp.budget_terms import skew_phase_component
from dsp.uncertainty import Budget, Component, Distribution

TARGETS = (
    "reference_certificate",
    "reference_gain",
    "daq_gain_reference",
    "daq_gain_dut",
    "dut_motion",
    "reference_phase",
)


@dataclass(frozen=True)
class SimBudget:
    """The simulated stand's budget and which components it draws its deviations from."""

    budget: Budget
    targets: dict[str, str]

    @classmethod
    def load(cls, text: str | None = None, source: str = "sim/stand.toml") -> SimBudget:
        """Parse the stand TOML (default: the shipped sim/stand.toml)."""
        if text is None:
            text = resources.files("sim").joinpath("stand.toml").read_text(encoding="utf-8")
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ValueError(f"{source}: {exc}") from None
        budget = Budget.from_list(data.get("component", []))
        tolerance = data.get("daq", {}).get("skew_tolerance_s")
        if tolerance is not None:  # as app.stand.config reads it: the phase term 360 f tau
            budget = Budget((*budget.components, skew_phase_component(tolerance)))
        names = {c.name for c in budget.components}
        targets = dict(data.get("simulation", {}))
        for name, target in targets.items():
            if name not in names:
                raise ValueError(f"{source}: [simulation] names no component {name!r}")
            if target not in TARGETS:
                raise ValueError(
                    f"{source}: [simulation] {name!r}: unknown target {target!r}; "
                    f"one of {', '.join(TARGETS)}"
                )
        return cls(budget, targets)


def draw(component: Component, rng: np.random.Generator) -> float:
    """One draw of a component's error from its distribution (relative or degrees)."""
    a = component.value
    match component.distribution:
        case Distribution.RECTANGULAR:
            return float(rng.uniform(-a, a))
        case Distribution.TRIANGULAR:
            return float(rng.triangular(-a, 0.0, a))
        case Distribution.U_SHAPED:
            return float(a * math.sin(rng.uniform(0, 2 * math.pi)))
        case _:  # normal or standard
            return float(rng.normal(0.0, component.standard_uncertainty))


@dataclass(frozen=True)
class Deviations:
    """The stand's true deviations from nominal for one seed."""

    reference_gain: float = 1.0
    daq_gain_reference: float = 1.0
    daq_gain_dut: float = 1.0
    dut_motion: float = 1.0
    reference_phase_deg: float = 0.0
    certificate: tuple[tuple[float, float | None, float | None], ...] = ()  # (e, fmin, fmax)
    transverse_cos: float = 0.0

    def certificate_factor(self, frequency_hz: np.ndarray) -> np.ndarray:
        """Certificate value / true value of the reference sensitivity, per frequency."""
        f = np.asarray(frequency_hz, dtype=float)
        factor = np.ones_like(f)
        for e, lo, hi in self.certificate:
            inside = np.ones(f.shape, bool)
            if lo is not None:
                inside &= f >= lo
            if hi is not None:
                inside &= f <= hi
            factor = np.where(inside, factor * (1.0 + e), factor)
        return factor


def draw_deviations(sim_budget: SimBudget, rng: np.random.Generator) -> Deviations:
    """Draw every mapped component once (relative factors, phase in degrees)."""
    values: dict[str, Any] = {"certificate": []}
    for component in sim_budget.budget.components:
        target = sim_budget.targets.get(component.name)
        e = draw(component, rng)
        if target is None:
            continue
        if target == "reference_certificate":
            values["certificate"].append(
                (e, component.min_frequency_hz, component.max_frequency_hz)
            )
        elif target == "reference_phase":
            values["reference_phase_deg"] = values.get("reference_phase_deg", 0.0) + e
        else:
            values[target] = values.get(target, 1.0) * (1.0 + e)
    values["certificate"] = tuple(values["certificate"])
    values["transverse_cos"] = float(math.cos(rng.uniform(0, 2 * math.pi)))
    return Deviations(**values)
