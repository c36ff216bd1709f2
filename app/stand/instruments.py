"""The stand's instruments besides the reference standard (the stand file's [[instrument]]
entries): DAQ, amplifiers, environment sensor, each with its model, serial and calibration due
date (ISO yyyy-mm-dd), listed on every certificate; an instrument overdue on the run date
refuses the run. An environment sensor may name a VISA resource: the run reads the ambient
temperature (deg C) and relative humidity (%) from it when it starts.

    [[instrument]]
    role = "daq"            # daq | measuring amplifier | power amplifier | environment sensor
    model = "NI PCIe-6351"
    serial = "1A2B3C4"
    calibration_due = 2027-03-31
    resource = "ASRL3::INSTR"   # environment sensor only: read at run start (optional)
    driver = "fluke1620a"       # environment sensor only: the driver of that resource
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import date
from enum import StrEnum
from typing import Any


class InstrumentRole(StrEnum):
    """What an instrument does on the stand (printed as its kind)."""

    DAQ = "daq"
    MEASURING_AMPLIFIER = "measuring amplifier"
    POWER_AMPLIFIER = "power amplifier"
    ENVIRONMENT_SENSOR = "environment sensor"


class SensorDriver(StrEnum):
    """The environment sensors a stand file may name (hardware.environment)."""

    FLUKE_1620A = "fluke1620a"  # Fluke (Hart Scientific) 1620A "DewK" thermo-hygrometer


INSTRUMENT_KEYS = frozenset({"role", "model", "serial", "calibration_due", "resource", "driver"})
ROLE_WORDS: dict[str, str] = {
    InstrumentRole.DAQ: "Data acquisition (DAQ)",
    InstrumentRole.MEASURING_AMPLIFIER: "Conditioning amplifier",
    InstrumentRole.POWER_AMPLIFIER: "Power amplifier",
    InstrumentRole.ENVIRONMENT_SENSOR: "Thermo-hygrometer",
}


HUMIDITY_RANGE_PERCENT = (0.0, 100.0)


def parse_humidity(text: str | float | None) -> float | None:
    """'45%', '45 %' or 45 as a relative humidity in %; None for empty; ValueError naming
    --humidity for anything else (outside 0..100 %)."""
    if text is None or (isinstance(text, str) and not text.strip()):
        return None
    raw = str(text).strip().rstrip("%").strip().replace(",", ".")
    try:
        value = float(raw)
    except ValueError:
        raise ValueError(
            f"humidity (--humidity): {text!r} is not a relative humidity in %"
        ) from None
    low, high = HUMIDITY_RANGE_PERCENT
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"humidity (--humidity): {text!r} is not in [{low:g}, {high:g}] %")
    return value


class InstrumentError(ValueError):
    """An [[instrument]] entry that cannot be used; the message names the entry and key."""


@dataclass(frozen=True)
class Instrument:
    """One instrument of the stand: its role, identity and calibration due date."""

    role: InstrumentRole
    model: str
    serial: str
    calibration_due: date
    resource: str = ""  # VISA resource (environment sensor only; "": typed values)
    driver: SensorDriver | None = None

    @property
    def label(self) -> str:
        """'<kind> <model>, serial <serial>' as the certificate names it."""
        return f"{ROLE_WORDS[self.role]} {self.model}, serial {self.serial}"

    def to_dict(self) -> dict[str, str]:
        """The JSON form (dates ISO)."""
        return {
            "role": str(self.role),
            "model": self.model,
            "serial": self.serial,
            "calibration_due": self.calibration_due.isoformat(),
        }


def _due(value: Any, where: str) -> date:
    if isinstance(value, date):
        return value
    try:
        return date.fromisoformat(str(value))
    except ValueError:
        raise InstrumentError(
            f"{where}.calibration_due: {value!r} is not a date (yyyy-mm-dd)"
        ) from None


def _text(entry: Mapping[str, Any], key: str, where: str) -> str:
    value = entry.get(key)
    if not isinstance(value, str) or not value.strip():
        raise InstrumentError(f"{where}.{key}: required, a non-empty text")
    return " ".join(value.split())


def parse_instruments(entries: Any) -> tuple[Instrument, ...]:
    """The stand file's [[instrument]] list (None: none) as Instruments; InstrumentError names
    the entry (instrument[i]) and the key. At most one environment sensor."""
    if entries is None:
        return ()
    if not isinstance(entries, list):
        raise InstrumentError("instrument: must be a list of tables ([[instrument]])")
    found: list[Instrument] = []
    for i, entry in enumerate(entries):
        where = f"instrument[{i}]"
        if not isinstance(entry, dict):
            raise InstrumentError(f"{where}: must be a table")
        unknown = sorted(set(entry) - INSTRUMENT_KEYS)
        if unknown:
            raise InstrumentError(
                f"{where}.{unknown[0]}: unknown key (known: {', '.join(sorted(INSTRUMENT_KEYS))})"
            )
        role_text = _text(entry, "role", where)
        try:
            role = InstrumentRole(role_text)
        except ValueError:
            roles = ", ".join(repr(str(r)) for r in InstrumentRole)
            raise InstrumentError(f"{where}.role: {role_text!r} is not one of {roles}") from None
        if "calibration_due" not in entry:
            raise InstrumentError(f"{where}.calibration_due: required (yyyy-mm-dd)")
        resource = str(entry.get("resource") or "").strip()
        driver = None
        if resource or "driver" in entry:
            if role != InstrumentRole.ENVIRONMENT_SENSOR:
                raise InstrumentError(f"{where}.resource: only an environment sensor is read")
            name = str(entry.get("driver") or "")
            try:
                driver = SensorDriver(name)
            except ValueError:
                known = ", ".join(repr(str(d)) for d in SensorDriver)
                raise InstrumentError(f"{where}.driver: {name!r} is not one of {known}") from None
            if not resource:
                raise InstrumentError(f"{where}.resource: required with a driver (VISA name)")
        found.append(
            Instrument(
                role=role,
                model=_text(entry, "model", where),
                serial=_text(entry, "serial", where),
                calibration_due=_due(entry["calibration_due"], where),
                resource=resource,
                driver=driver,
            )
        )
    sensors = [x for x in found if x.role == InstrumentRole.ENVIRONMENT_SENSOR]
    if len(sensors) > 1:
        raise InstrumentError("instrument: more than one environment sensor; name one")
    return tuple(found)


def overdue(instruments: Sequence[Instrument], on: date) -> list[str]:
    """Each instrument whose calibration was due before `on` (the run date), named with its
    due date; empty when all are in calibration. Due on the day itself is still in."""
    return [
        f"{x.label} was due for calibration on {x.calibration_due.isoformat()}"
        for x in instruments
        if x.calibration_due < on
    ]


def environment_sensor(instruments: Sequence[Instrument]) -> Instrument | None:
    """The environment sensor the run reads (one with a resource), None when there is none."""
    return next(
        (x for x in instruments if x.role == InstrumentRole.ENVIRONMENT_SENSOR and x.resource),
        None,
    )
