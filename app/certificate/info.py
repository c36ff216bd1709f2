"""What a certificate states beyond the run: the items (customer, DUT, conditions, number,
dates), their defaults from the run and the stand's [certificate] table, and their checks.

Missing mandatory items are refused by name with their option; a temperature is in deg C, a
date is ISO (yyyy-mm-dd).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from datetime import date
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from app.certificate.validated import ValidationClaim
from app.errors import Refusal
from app.records.run_record import DutIdentity, RunRecord
from app.records.run_start import RunStart

if TYPE_CHECKING:
    from dsp.triaxial import TriaxialResult

MANDATORY = (
    ("customer", "--customer"),
    ("authorised_by", "--authorised-by"),
    ("dut_model", "--dut-model"),
    ("dut_serial", "--dut-serial (or --dut-id when running)"),
    ("dut_type", "--dut-type"),
    ("temperature_c", "--temperature"),
    ("mounting", "--mounting"),
)


class CertificateError(Refusal):
    """A certificate that must not be issued; the message says why (missing items by name)."""


class SpecKind(StrEnum):
    """What kind of document the conformity statement is made against."""

    DATASHEET = "datasheet"
    CUSTOMER = "customer"
    STANDARD = "standard"


SPEC_WORDS: dict[str, str] = {
    SpecKind.DATASHEET: "manufacturer's data sheet",
    SpecKind.CUSTOMER: "customer requirement",
    SpecKind.STANDARD: "standard",
}


@dataclass(frozen=True)
class Specification:
    """The specification a conformity statement is made against: its kind, its identity
    (document and revision) and its tolerances in words (e.g. "sensitivity ±5 %")."""

    kind: SpecKind
    identity: str
    tolerances: str

    def line(self) -> str:
        """One sentence naming it, as the PDF and the DCC state it."""
        return (
            f"Specification: {SPEC_WORDS[self.kind]}, {self.identity}; tolerances: "
            f"{self.tolerances}."
        )


@dataclass(frozen=True)
class UsedInstrument:
    """An instrument used, as the certificate lists it: kind, model, serial, calibration due
    (ISO date; "" unknown) and where it is known from (stand file, records)."""

    kind: str
    model: str
    serial: str
    calibration_due: str
    source: str

    def line(self) -> str:
        due = self.calibration_due or "not stated"
        return f"{self.kind}: {self.model}, serial {self.serial}, calibration due {due}"


@dataclass(frozen=True)
class Amendment:
    """What an amendment states about the certificate it replaces (ISO/IEC 17025 7.8.8.3):
    its number, the reason, and the SHA-256 of its issued DCC (else of its PDF) from the
    register, so that a reader can tell which document is meant."""

    replaces: str  # the replaced certificate's number
    reason: str
    sha256: str  # hex; the replaced DCC's when it had one, else its PDF's ("" when unknown)
    of_dcc: bool  # True: `sha256` is the replaced DCC's; False: the replaced PDF's


@dataclass(frozen=True)
class CertificateInfo:
    """What the certificate needs beyond the run."""

    customer: str | None = None
    customer_address: str = ""
    authorised_by: str | None = None
    dut_model: str | None = None
    dut_serial: str | None = None
    dut_type: str | None = None
    temperature_c: float | None = None
    mounting: str | None = None
    certificate_number: str | None = None
    issue_date: str | None = None
    notes: str = ""
    prepared_by: str = ""  # who made the calibration ("Prepared by"); the register's too
    sensitivity_unit: str = ""  # the sensor model's unit (records); mV/g adds a column
    # the authorising person's function ("head of laboratory"), apart from the name (issue 33)
    authorised_function: str = ""
    # the software validation report the certificate names (app.certificate.validated; chosen
    # by the issuing service against the lab's key): None names none
    validation: ValidationClaim | None = None
    # an amendment: the certificate it replaces and why (set by the records' register when
    # issuing with --replaces; printed on page 1 and in the DCC's coreData)
    amendment: Amendment | None = None
    # issue 35 point 2 (app.certificate.complete): why the customer's address is not stated
    # (instead of an address), the relative humidity (%), where temperature and humidity come
    # from (typed, or the sensor read at run start), the specification behind the statement
    # of conformity, and the instruments used (set by the issuing service)
    address_not_stated: str = ""
    humidity_percent: float | None = None
    temperature_source: str = ""
    humidity_source: str = ""
    specification: Specification | None = None
    instruments: tuple[UsedInstrument, ...] = ()
    conditions_from: str = ""  # where the mounting was offered from ("model X")
    template: str = ""  # the run template chosen (its remembered mounting is offered first)
    # issue 36 point 3: a triaxial sensor's certificate (its section in the PDF and the DCC;
    # app.certificate.triaxial_issue), issued on its x orientation's x channel run
    triaxial: TriaxialResult | None = field(default=None, compare=False, repr=False)

    def merged(self, defaults: dict[str, Any]) -> CertificateInfo:
        """Options win; empty ones take the default."""
        values = {}
        for f in fields(self):
            mine = getattr(self, f.name)
            values[f.name] = mine if mine not in (None, "") else defaults.get(f.name, mine)
        return CertificateInfo(**values)


def default_info(record: RunRecord, start: RunStart) -> dict[str, Any]:
    """Defaults from the run (its record and config.json) and the stand's [certificate] table
    (the number is not one: `issue` takes the next free one from the runs root's register)."""
    defaults: dict[str, Any] = start.certificate_defaults()
    dut = record.dut or DutIdentity()
    if dut.id:
        defaults.setdefault("dut_serial", dut.id)
    catalogue = dut.catalogue
    if catalogue:
        from app.stand.simulated import catalogue_spec

        spec = catalogue_spec(catalogue)
        if spec.catalogue:
            defaults.setdefault("dut_model", spec.model)
            defaults.setdefault("dut_type", f"{spec.kind} accelerometer")
    defaults.setdefault("issue_date", record.finished_utc[:10])
    if record.technician:  # who ran it prepares it, over the stand file's [certificate] one
        defaults["prepared_by"] = record.technician
    return defaults


def missing_items(info: CertificateInfo) -> list[str]:
    """Mandatory items not given (None, empty or only blanks), each with its option."""
    return [
        f"{name} ({option})"
        for name, option in MANDATORY
        if getattr(info, name) is None or not str(getattr(info, name)).strip()
    ]


TEMPERATURE_RANGE_C = (-50.0, 150.0)  # ambient of a calibration, incl. climatic chambers
ISO_DATE = re.compile(r"^\d{4}-\d{2}-\d{2}$")


def invalid_items(info: CertificateInfo) -> list[str]:
    """Items given but unusable, each naming its field and option: a temperature that is not a
    finite number in TEMPERATURE_RANGE_C, an issue date that is not an ISO date (yyyy-mm-dd)."""
    problems = []
    t = info.temperature_c
    if t is not None:
        low, high = TEMPERATURE_RANGE_C
        try:
            value = float(t)
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and low <= value <= high):
            problems.append(
                f"temperature_c (--temperature): {t!r} is not a temperature in "
                f"[{low:g}, {high:g}] deg C"
            )
    h = info.humidity_percent
    if h is not None:
        try:
            ok = math.isfinite(float(h)) and 0.0 <= float(h) <= 100.0
        except (TypeError, ValueError):
            ok = False
        if not ok:
            problems.append(f"humidity_percent (--humidity): {h!r} is not a humidity in [0, 100] %")
    d = info.issue_date
    if d not in (None, ""):
        try:
            ok = bool(ISO_DATE.match(str(d))) and date.fromisoformat(str(d)) is not None
        except ValueError:
            ok = False
        if not ok:
            problems.append(f"issue_date (--issue-date): {d!r} is not a date as yyyy-mm-dd")
    return problems
