"""The laboratory's calibration and measurement capability (CMC), per frequency band, for the
magnitude and the phase of the sensitivity, as on its accreditation scope (issue 32 point 1;
ILAC P14: a stated uncertainty is never smaller than the CMC).

A band states the least expanded uncertainty (coverage probability about 95 %) the laboratory
claims from `min_frequency_hz` to `max_frequency_hz` inclusive: `magnitude_percent` (relative,
%) and `phase_deg` (degrees). `Cmc.at` gives the band at a frequency (the larger value where two
bands meet); a line no band covers is outside the scope. Pure Python, no I/O.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from dsp.annex_a import implausible_budget_text, implausible_components, plausible_floor
from dsp.conformity import uncertainty_stated

__all__ = [
    "CMC_KEYS",
    "Cmc",
    "CmcBand",
    "LineBound",
    "bound_line",
    "no_cmc_text",
    "outside_cmc_text",
    "scope_warnings",
]

CMC_KEYS = ("min_frequency_hz", "max_frequency_hz", "magnitude_percent", "phase_deg")


def _number(where: str, key: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where}: {key} must be a number, got {value!r}")
    x = float(value)
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"{where}: {key} must be finite and > 0, got {value!r}")
    return x


@dataclass(frozen=True)
class CmcBand:
    """One band of the scope: frequencies (Hz, inclusive) and the least expanded uncertainty
    of the sensitivity's magnitude (%, relative) and phase (degrees)."""

    min_frequency_hz: float
    max_frequency_hz: float
    magnitude_percent: float
    phase_deg: float

    def __post_init__(self) -> None:
        where = f"cmc band {self.min_frequency_hz!r}-{self.max_frequency_hz!r} Hz"
        for key in CMC_KEYS:
            object.__setattr__(self, key, _number(where, key, getattr(self, key)))
        if self.min_frequency_hz >= self.max_frequency_hz:
            raise ValueError(f"{where}: min_frequency_hz must be below max_frequency_hz")

    def covers(self, frequency_hz: float) -> bool:
        """Whether `frequency_hz` (Hz) lies in the band (edges included)."""
        return self.min_frequency_hz <= frequency_hz <= self.max_frequency_hz

    def to_dict(self) -> dict[str, float]:
        return {key: getattr(self, key) for key in CMC_KEYS}

    def text(self) -> str:
        """ "10-1000 Hz: 0.8 %, 0.5°"."""
        return (
            f"{self.min_frequency_hz:g}-{self.max_frequency_hz:g} Hz: "
            f"{self.magnitude_percent:g} %, {self.phase_deg:g}°"
        )


@dataclass(frozen=True)
class Cmc:
    """The scope's bands, sorted by frequency, not overlapping (they may share an edge)."""

    bands: tuple[CmcBand, ...]

    def __post_init__(self) -> None:
        bands = tuple(sorted(self.bands, key=lambda b: b.min_frequency_hz))
        if not bands:
            raise ValueError("cmc: at least one band")
        for a, b in itertools.pairwise(bands):
            if b.min_frequency_hz < a.max_frequency_hz:
                raise ValueError(f"cmc: bands {a.text()} and {b.text()} overlap")
        object.__setattr__(self, "bands", bands)

    def at(self, frequency_hz: float) -> CmcBand | None:
        """The band at `frequency_hz` (Hz); at a shared edge the one with the larger values
        (magnitude first); None outside the scope."""
        hits = [b for b in self.bands if b.covers(frequency_hz)]
        if not hits:
            return None
        return max(hits, key=lambda b: (b.magnitude_percent, b.phase_deg))

    def text(self) -> str:
        """All bands, "; "-separated."""
        return "; ".join(b.text() for b in self.bands)

    def to_list(self) -> list[dict[str, float]]:
        return [b.to_dict() for b in self.bands]

    @classmethod
    def from_list(cls, entries: Iterable[Mapping[str, Any]]) -> Cmc:
        """A CMC from [[cmc]] tables; ValueError naming the entry (1-based) and key."""
        items = list(entries)
        bands = []
        for i, entry in enumerate(items, start=1):
            where = f"cmc entry {i} of {len(items)}"
            if not isinstance(entry, Mapping):
                raise ValueError(f"{where}: must be a table")
            unknown = sorted(set(entry) - set(CMC_KEYS))
            if unknown:
                raise ValueError(
                    f"{where}: unknown key {unknown[0]!r} (known keys: {', '.join(CMC_KEYS)})"
                )
            missing = [k for k in CMC_KEYS if k not in entry]
            if missing:
                raise ValueError(f"{where}: missing key {missing[0]!r}")
            try:
                bands.append(CmcBand(*(entry[k] for k in CMC_KEYS)))
            except ValueError as exc:
                raise ValueError(f"{where}: {exc}") from None
        return cls(tuple(bands))


def no_cmc_text() -> str:
    """The one wording of the blocking "no CMC" warning (app.records.warnings)."""
    return (
        "no CMC: results for review only; the stand states no calibration and measurement "
        "capability ([[cmc]] bands in the stand file), so nothing bounds the stated U from below"
    )


def outside_cmc_text(frequencies_hz: Iterable[float], cmc: Cmc) -> str:
    """The blocking warning for lines outside every CMC band (app.records.warnings)."""
    lines = ", ".join(f"{f:g} Hz" for f in frequencies_hz)
    return f"no CMC at {lines}: outside the laboratory's scope ({cmc.text()})"


@dataclass(frozen=True)
class LineBound:
    """One line's uncertainties after the CMC (expanded: relative, degrees, % of the reference
    line's sensitivity), the floors a conformity statement needs (fraction, degrees) and what
    the CMC raised ("U", "phase U", "U of the deviation", comma-separated; "" nothing)."""

    magnitude: float
    phase_deg: float
    deviation_percent: float
    magnitude_floor: float
    phase_floor_deg: float
    bounds: str


def bound_line(
    cmc: Cmc | None,
    nominal_hz: float,
    magnitude: float,
    phase_deg: float,
    deviation_u_percent: float,
    deviation: float,
) -> LineBound:
    """Raise each stated U of a line to the CMC at `nominal_hz` (ILAC P14; the deviation's,
    in % of the reference line's sensitivity, to (1 + `deviation`) times it; `deviation` a
    fraction); a U not stated (0, NaN) stays as it is. Without a band there the floors are
    the plausible floors of a full budget (dsp.annex_a.plausible_floor) and nothing is raised."""
    band = cmc.at(nominal_hz) if cmc is not None else None
    if band is None:
        floors = plausible_floor("magnitude"), plausible_floor("phase")
        return LineBound(magnitude, phase_deg, deviation_u_percent, floors[0], floors[1], "")
    bounds = []
    mag_floor, ph_floor = band.magnitude_percent / 100, band.phase_deg
    dev_floor = band.magnitude_percent * (1.0 + deviation)
    out = []
    for u, least, what in (
        (magnitude, mag_floor, "U"),
        (phase_deg, ph_floor, "phase U"),
        (deviation_u_percent, dev_floor, "U of the deviation"),
    ):
        if uncertainty_stated(u) and u < least:
            u = least
            bounds.append(what)
        out.append(u)
    return LineBound(out[0], out[1], out[2], mag_floor, ph_floor, ", ".join(bounds))


def scope_warnings(cmc: Cmc | None, nominal_hz: Iterable[float], budget: Any) -> list[str]:
    """The blocking warnings of a budget and a CMC: implausible components (named), no CMC,
    or lines outside it."""
    out = []
    implausible = implausible_components(budget)
    if implausible:
        out.append(implausible_budget_text(implausible))
    if cmc is None:
        return [*out, no_cmc_text()]
    outside = [float(f) for f in nominal_hz if cmc.at(float(f)) is None]
    return [*out, outside_cmc_text(outside, cmc)] if outside else out
