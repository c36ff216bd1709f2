"""The device under test's specification, in one place: identity, nominal sensitivity
(mV/(m/s^2)), tolerances (sensitivity and characteristic in %, phase in degrees, per band of
Hz), mass (g) and plan preset; whichever source it comes from (records, TEDS, stand file,
simulated catalogue), the run request carries one and the verdict reads its tolerances here.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Band:
    """A tolerance over a frequency range (inclusive), in % (characteristic) or degrees (phase)."""

    min_hz: float
    max_hz: float
    tolerance: float

    def covers(self, frequency_hz: float) -> bool:
        return self.min_hz <= frequency_hz <= self.max_hz


@dataclass(frozen=True)
class Tolerances:
    """A DUT model's tolerances; a missing one is not checked (and named in the reasons)."""

    nominal_sensitivity_mv_per_ms2: float | None = None
    sensitivity_percent: float | None = None
    characteristic: tuple[Band, ...] = ()
    phase: tuple[Band, ...] = ()
    source: str = ""

    @property
    def empty(self) -> bool:
        sensitivity = (
            self.nominal_sensitivity_mv_per_ms2 is not None and self.sensitivity_percent is not None
        )
        return not (sensitivity or self.characteristic or self.phase)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _everywhere(tolerance_percent: float) -> tuple[Band, ...]:
    """One characteristic band over every line (the --tolerance option)."""
    return (Band(0.0, math.inf, float(tolerance_percent)),)


@dataclass(frozen=True)
class DutSpec:
    """What is known of the DUT before its run (None: not known).

    `catalogue` names the simulated stand's catalogue DUT (only that stand uses it);
    `response` gives the nominal sensitivity (mV/(m/s^2)) at a frequency (Hz) where the DUT's
    model knows its shape (the simulated catalogue), else `nominal_mv_per_ms2` holds at every
    frequency. `tolerance_percent` is the characteristic's tolerance over every line."""

    serial: str | None = None
    model: str | None = None
    manufacturer: str | None = None
    kind: str | None = None  # e.g. "piezoelectric"
    description: str = ""
    catalogue: str | None = None
    nominal_mv_per_ms2: float | None = None
    sensitivity_percent: float | None = None  # tolerance of the sensitivity at the reference f
    tolerance_percent: float | None = None  # the characteristic's, over every line
    characteristic: tuple[Band, ...] = ()
    phase: tuple[Band, ...] = ()
    mass_g: float | None = None
    preset: str | None = None
    level_ms2: float | None = None
    source: str = ""
    response: Callable[[float], float] | None = field(default=None, compare=False, repr=False)

    def nominal_at(self, frequency_hz: float) -> float | None:
        """The nominal sensitivity in mV/(m/s^2) at `frequency_hz` (None: not known)."""
        if self.nominal_mv_per_ms2 is None:
            return None
        if self.response is not None:
            return self.response(frequency_hz)
        return self.nominal_mv_per_ms2

    def with_options(
        self,
        *,
        serial: str | None = None,
        nominal_mv_per_ms2: float | None = None,
        tolerance_percent: float | None = None,
        mass_g: float | None = None,
    ) -> DutSpec:
        """This spec with what the operator stated instead (None: keep): a stated nominal
        replaces the model's shape too; a stated tolerance replaces the characteristic's bands
        by one over every line."""
        spec = self
        if serial is not None:
            spec = dataclasses.replace(spec, serial=serial)
        if nominal_mv_per_ms2 is not None and nominal_mv_per_ms2 != spec.nominal_mv_per_ms2:
            spec = dataclasses.replace(spec, nominal_mv_per_ms2=nominal_mv_per_ms2, response=None)
        if tolerance_percent is not None and tolerance_percent != spec.tolerance_percent:
            source = f"{spec.source} with --tolerance" if spec.source else "--tolerance"
            spec = dataclasses.replace(
                spec,
                tolerance_percent=tolerance_percent,
                characteristic=_everywhere(tolerance_percent),
                source=source,
            )
        if mass_g is not None:
            spec = dataclasses.replace(spec, mass_g=mass_g)
        return spec

    def tolerances(self, reference_frequency_hz: float) -> Tolerances:
        """The tolerances the verdict checks, the sensitivity's nominal value taken at
        `reference_frequency_hz` (Hz); the nominal is checked only with a sensitivity
        tolerance."""
        checked = self.sensitivity_percent is not None
        characteristic = self.characteristic
        if not characteristic and self.tolerance_percent:
            characteristic = _everywhere(self.tolerance_percent)
        return Tolerances(
            nominal_sensitivity_mv_per_ms2=self.nominal_at(reference_frequency_hz)
            if checked
            else None,
            sensitivity_percent=self.sensitivity_percent,
            characteristic=characteristic,
            phase=self.phase,
            source=self.source,
        )


def spec_from_record(
    *,
    serial: str,
    manufacturer: str,
    model: str,
    description: str,
    nominal_mv_per_ms2: float,
    tolerance_percent: float,
    frequency_min_hz: float,
    frequency_max_hz: float,
    phase_tolerance_deg: float | None,
    preset: str | None,
    level_ms2: float | None,
) -> DutSpec:
    """A sensor model's record: the nominal sensitivity and the characteristic within
    `tolerance_percent` (over every line, as the run states it), the phase within
    `phase_tolerance_deg` over the model's range (Hz)."""
    phase = (
        (Band(frequency_min_hz, frequency_max_hz, phase_tolerance_deg),)
        if phase_tolerance_deg is not None
        else ()
    )
    return DutSpec(
        serial=serial,
        model=model,
        manufacturer=manufacturer,
        description=description,
        nominal_mv_per_ms2=nominal_mv_per_ms2,
        sensitivity_percent=tolerance_percent,
        tolerance_percent=tolerance_percent,
        characteristic=_everywhere(tolerance_percent),
        phase=phase,
        preset=preset,
        level_ms2=level_ms2,
        source=f"records: sensor model {manufacturer} {model}",
    )


def spec_from_teds(
    identity: str, sensitivity_mv_per_ms2: float | None, serial: str | None = None
) -> DutSpec:
    """A DUT known by its TEDS ('manufacturer/model/version/serial' identity): serial
    TEDS-<identity> unless given, and the nominal sensitivity the TEDS holds (mV/(m/s^2))."""
    return DutSpec(
        serial=serial or f"TEDS-{identity.replace('/', '-')}",
        nominal_mv_per_ms2=sensitivity_mv_per_ms2,
        description=f"TEDS identity {identity}",
        source="TEDS",
    )


def spec_from_stand(certificate: Mapping[str, Any]) -> DutSpec:
    """The DUT model the stand file's [certificate] table names (dut_model, dut_type; its
    dut_serial is a certificate's default, not the run's identity), else an unknown DUT."""
    return DutSpec(
        model=certificate.get("dut_model") or None,
        kind=certificate.get("dut_type") or None,
        source="stand file" if certificate.get("dut_model") else "",
    )
