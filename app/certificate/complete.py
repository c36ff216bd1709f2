"""What makes a certificate complete beyond the run's numbers (issue 35 point 2): the customer's
address (or "not stated" with a reason), the specification behind the conformity statement
(kind, identity, tolerances), the instruments used with their calibration due dates (stand
file and reference standard), and the ambient conditions (temperature in deg C, relative
humidity in %) typed or read from the stand's environment sensor at run start.

The checks here refuse by field and option (CertificateError, exit 2); the PDF
(app.certificate.pdf_complete) and the DCC (app.certificate.dcc_complete) print the same values.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import date
from typing import Any

import app.certificate.text as text
from app.certificate.info import (
    CertificateError,
    CertificateInfo,
    Specification,
    SpecKind,
    UsedInstrument,
)
from app.records.run_record import RunRecord
from app.records.run_start import RunStart
from app.stand.instruments import parse_humidity as parse_humidity  # the one reader
from dsp.calibration import Results

ENVIRONMENT_KEY = "environment"  # config.json's key of the reading taken at run start
TYPED = "as stated by the laboratory"  # the source of a typed temperature or humidity


@dataclass(frozen=True)
class EnvironmentRecord:
    """The ambient conditions read at run start: deg C, % relative humidity, the sensor's
    identity (label) and when (UTC, ISO)."""

    temperature_c: float
    humidity_percent: float
    sensor: str
    read_utc: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "temperature_c": self.temperature_c,
            "humidity_percent": self.humidity_percent,
            "sensor": self.sensor,
            "read_utc": self.read_utc,
        }

    @classmethod
    def from_dict(cls, data: Any) -> EnvironmentRecord | None:
        """The stored reading; None when absent or not a reading (older runs)."""
        if not isinstance(data, Mapping):
            return None
        try:
            return cls(
                float(data["temperature_c"]),
                float(data["humidity_percent"]),
                str(data.get("sensor") or ""),
                str(data.get("read_utc") or ""),
            )
        except (KeyError, TypeError, ValueError):
            return None


def stored_environment(start: RunStart) -> EnvironmentRecord | None:
    """The reading the run took at its start (config.json), None when it took none."""
    return EnvironmentRecord.from_dict(start.extra.get(ENVIRONMENT_KEY))


def with_environment(info: CertificateInfo, start: RunStart) -> CertificateInfo:
    """`info` with the temperature and humidity not typed taken from the reading stored with
    the run, and each one's source stated (typed: TYPED; read: the sensor and time)."""
    import dataclasses

    reading = stored_environment(start)
    read_from = f"read from {reading.sensor} at run start" if reading is not None else ""
    values: dict[str, Any] = {}
    for name, source in (
        ("temperature_c", "temperature_source"),
        ("humidity_percent", "humidity_source"),
    ):
        if getattr(info, name) is not None:
            values[source] = getattr(info, source) or TYPED
        elif reading is not None:
            values[name] = getattr(reading, name)
            values[source] = read_from
    return dataclasses.replace(info, **values)


def address_problem(info: CertificateInfo) -> str | None:
    """Why the customer's address cannot be printed: empty without a "not stated" reason, or
    both given; None when fine."""
    address = (info.customer_address or "").strip()
    reason = (info.address_not_stated or "").strip()
    if address and reason:
        return (
            "customer_address (--customer-address): given together with --address-not-stated; "
            "give one"
        )
    if not address and not reason:
        return (
            "customer_address (--customer-address): required; or state why it is not given "
            '(--address-not-stated "REASON")'
        )
    return None


_TOLERANCE = re.compile(r"tolerance (±[^)]*)\)")


def tolerances_checked(results: Results) -> str:
    """The tolerances the verdict checked, in words, from its reasons ("sensitivity at 160 Hz:
    ±5 %; amplitude characteristic: ±5 %"); "" when none was checked."""
    found: list[str] = []
    for reason in results.verdict_reasons:
        match = _TOLERANCE.search(reason)
        if match is None:
            continue
        name = reason.split(":", 1)[0].strip()
        found.append(f"{name} {match.group(1)}")
    if not found and results.tolerance_percent is not None:
        found.append(f"amplitude characteristic ±{results.tolerance_percent:g} %")
    return "; ".join(found)


def default_specification(record: RunRecord) -> Specification | None:
    """The specification known from the run's DUT: a simulated catalogue DUT's data sheet;
    None otherwise (the records' sensor model gives one in app.certificate.register_issue)."""
    dut = record.dut
    if dut is None or not dut.catalogue:
        return None
    from app.stand.simulated import catalogue_spec

    spec = catalogue_spec(dut.catalogue)
    if not spec.source:
        return None
    return Specification(SpecKind.DATASHEET, f"{spec.source} (accelcal catalogue)", "")


def with_specification(
    info: CertificateInfo, record: RunRecord, results: Results
) -> CertificateInfo:
    """`info` with its specification complete: the one given (its tolerances, if not given, the
    ones the verdict checked), else the run's DUT's; CertificateError naming --spec-kind and
    --spec-id when the results state conformity against tolerances and none is named."""
    import dataclasses

    checked = tolerances_checked(results)
    spec = info.specification or default_specification(record)
    if spec is None:
        if checked:
            raise CertificateError(
                "specification (--spec-kind, --spec-id): the statement of conformity checks "
                f"tolerances ({checked}); name the specification they come from (data sheet, "
                "customer requirement or standard, with its document and revision)"
            )
        return info
    if not spec.identity.strip():
        raise CertificateError("specification (--spec-id): the document and its revision")
    tolerances = spec.tolerances.strip() or checked or "none checked"
    return dataclasses.replace(info, specification=dataclasses.replace(spec, tolerances=tolerances))


def used_instruments(record: RunRecord, start: RunStart) -> tuple[UsedInstrument, ...]:
    """The instruments the run used: the reference standard (its due date from the records
    when the run took it from there) and the stand file's [[instrument]] entries."""
    from app.stand.instruments import ROLE_WORDS, InstrumentError, parse_instruments

    reference = dict(record.stand.reference or start.reference)
    found: list[UsedInstrument] = []
    if reference:
        from_records = reference.get("table_from") == "records"
        found.append(
            UsedInstrument(
                "Reference standard",
                str(reference.get("model") or ""),
                str(reference.get("serial") or ""),
                str(reference.get("due_date") or ""),
                "records" if from_records else "stand file",
            )
        )
    try:
        instruments = parse_instruments((start.stand or {}).get("instrument"))
    except InstrumentError:  # checked when the run started: an old run's, unreadable
        instruments = ()
    for x in instruments:
        found.append(
            UsedInstrument(
                ROLE_WORDS[x.role], x.model, x.serial, x.calibration_due.isoformat(), "stand file"
            )
        )
    return tuple(found)


def overdue_on_run_date(instruments: tuple[UsedInstrument, ...], run_date: str) -> list[str]:
    """Each listed instrument (but the reference standard: its own rule and override) whose
    calibration was due before the run date (yyyy-mm-dd)."""
    problems = []
    for x in instruments:
        if x.kind == "Reference standard" or not x.calibration_due:
            continue
        try:
            due = date.fromisoformat(x.calibration_due)
        except ValueError:
            continue
        if due.isoformat() < run_date:
            problems.append(f"{x.kind} {x.model} serial {x.serial} was due on {x.calibration_due}")
    return problems


def complete(
    info: CertificateInfo, record: RunRecord, start: RunStart, results: Results
) -> CertificateInfo:
    """`info` (merged with its defaults) completed and checked: conditions from the run's
    reading, the specification, the instruments; CertificateError naming the field."""
    import dataclasses

    problem = address_problem(info)
    if problem is not None:
        raise CertificateError(problem)
    info = with_specification(info, record, results)
    instruments = used_instruments(record, start)
    late = overdue_on_run_date(instruments, (record.started_utc or "")[:10])
    if late:
        raise CertificateError(
            "instruments: overdue for calibration on the run date: " + "; ".join(late)
        )
    sources: dict[str, Any] = {
        source: getattr(info, source) or TYPED
        for name, source in (
            ("temperature_c", "temperature_source"),
            ("humidity_percent", "humidity_source"),
        )
        if getattr(info, name) is not None
    }
    return dataclasses.replace(info, instruments=instruments, **sources)


def customer_address_text(info: CertificateInfo) -> str:
    """The customer's address as the PDF and the DCC print it: the address, else "Address
    not stated: REASON" (the reason recorded when issuing)."""
    address = " ".join((info.customer_address or "").split())
    if address:
        return address
    reason = " ".join((info.address_not_stated or "").split())
    if reason:
        return f"Address not stated: {reason}"
    return text.ADDRESS_NOT_STATED  # a document built without the issuing checks (tests, old runs)


def condition_value(value: float | None, unit: str, source: str, digits: int = 1) -> str:
    """'23.1 °C (read from ... at run start)' or 'not stated'."""
    if value is None:
        return "not stated"
    return f"{float(value):.{digits}f} {unit}" + (f" ({source})" if source else "")


def fixture_position_text(start: RunStart) -> str | None:
    """Where on the fixture a DUT of a several-DUT run was mounted and with how many others
    (issue 36): the certificate's Conditions row and the DCC's statement say the same; None for
    a single-DUT run."""
    batch = start.batch
    if batch is None:
        return None
    others = len(batch.members) - 1
    return (
        f"position {batch.position} of the fixture, {batch.distance_mm:g} mm from the reference "
        f"axis; calibrated in one excitation with {others} other DUT{'s' if others != 1 else ''} "
        f"(batch {batch.batch_id})"
    )
