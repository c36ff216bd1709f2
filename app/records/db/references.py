"""The lab's reference standards (calibration table: frequency in Hz, sensitivity in
mV/(m/s^2), relative expanded uncertainty stored as a fraction and given in percent, phase in
degrees), the due-date rule a run meets before using one, the table a run takes from the
records, the overrides entered in the audit trail, and the list of sensors and reference
standards due for calibration.
"""

from __future__ import annotations

import base64
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta
from typing import TYPE_CHECKING

from sqlalchemy import or_, select
from sqlalchemy.orm import joinedload

from app.records.db.models import (
    AuditEntry,
    Customer,
    ReferenceDccFile,
    ReferencePoint,
    ReferenceStandard,
    Sensor,
)
from app.records.db.store import RecordsError, Store, number_field, text_field
from app.records.run_record import Override

if TYPE_CHECKING:
    from sqlalchemy.orm import Session

    from app.io.reference_dcc import ReferenceDcc


@dataclass(frozen=True)
class DccIdentity:
    """The reference standard's DCC in force: its uniqueIdentifier, calibrating laboratory,
    SHA-256 (hex) and its signature as verified when it was read in."""

    unique_identifier: str
    laboratory: str
    sha256: str
    signature: str = ""

    @classmethod
    def of(cls, row: ReferenceDccFile) -> DccIdentity:
        return cls(row.unique_identifier, row.laboratory, row.sha256, row.signature)


@dataclass(frozen=True)
class StoredDcc:
    """A reference DCC as kept: its identity, file name and bytes (SHA-256 checked)."""

    identity: DccIdentity
    file_name: str
    content: bytes
    added_utc: datetime


@dataclass(frozen=True)
class ReferenceTable:
    """A reference standard as a run takes it from the records: identity, certificate, dates
    and its calibration table (Hz, mV/(m/s^2), relative expanded uncertainty as a fraction,
    phase in degrees; phase None where the certificate states none)."""

    identifier: str
    model: str
    serial: str
    certificate_number: str
    calibration_date: date
    due_date: date
    frequencies_hz: tuple[float, ...]
    sensitivity_mv_per_ms2: tuple[float, ...]
    relative_expanded_uncertainty: tuple[float, ...]
    phase_deg: tuple[float | None, ...]
    dcc: DccIdentity | None = None  # the DCC in force, when the table was read from one

    @classmethod
    def of(cls, ref: ReferenceStandard, dcc: DccIdentity | None = None) -> ReferenceTable:
        """The table of a reference standard read with its points (and its DCC in force)."""
        points = sorted(ref.points, key=lambda p: p.frequency_hz)
        return cls(
            identifier=ref.identifier,
            model=ref.model,
            serial=ref.serial,
            certificate_number=ref.certificate_number,
            calibration_date=ref.calibration_date,
            due_date=ref.due_date,
            frequencies_hz=tuple(p.frequency_hz for p in points),
            sensitivity_mv_per_ms2=tuple(p.sensitivity_mv_per_ms2 for p in points),
            relative_expanded_uncertainty=tuple(p.relative_expanded_uncertainty for p in points),
            phase_deg=tuple(p.phase_deg for p in points),
            dcc=dcc,
        )


def _points(table: Sequence[tuple[float, float, float, float | None]]) -> list[ReferencePoint]:
    """The rows of a calibration table, each field checked (a refusal names row and field)."""
    if not table:
        raise RecordsError("table: a reference standard needs its calibration table")
    points = []
    for row_number, (freq, sens, rel_u, phase) in enumerate(table, 1):
        where = f"table row {row_number}"
        number_field(freq, f"{where} frequency", low=0, high=1e6)
        number_field(sens, f"{where} sensitivity", low=0, high=1e6)
        number_field(rel_u, f"{where} uncertainty", low=0, high=1)
        points.append(
            ReferencePoint(
                frequency_hz=freq,
                sensitivity_mv_per_ms2=sens,
                relative_expanded_uncertainty=rel_u,
                phase_deg=phase,
            )
        )
    return points


def _keep_dcc(s: Session, ref: ReferenceStandard, dcc: ReferenceDcc) -> None:
    """Keep `dcc` (the file, its identity, SHA-256 and signature) as `ref`'s DCC in force."""
    s.add(
        ReferenceDccFile(
            reference_id=ref.id,
            unique_identifier=text_field(
                dcc.unique_identifier, "DCC uniqueIdentifier", max_len=200
            ),
            laboratory=text_field(dcc.laboratory, "DCC calibration laboratory", max_len=300),
            sha256=dcc.sha256,
            signature=dcc.signature.line()[:500],
            file_name=(dcc.file_name or "reference-dcc.xml")[:255],
            content_base64=base64.b64encode(dcc.content).decode("ascii"),
            added_utc=datetime.now(UTC),
            in_force=True,
        )
    )


@dataclass(frozen=True)
class DueItem:
    """A sensor or reference standard due for calibration by `due` (None: never calibrated)."""

    kind: str
    identifier: str
    due: date | None
    owner: str


class ReferenceRecords(Store):
    """Reference standards and the due list."""

    # ---- reference standards -------------------------------------------------------------
    def add_reference(
        self,
        identifier: str,
        *,
        model: str,
        serial: str,
        certificate_number: str,
        calibration_date: date,
        due_date: date,
        table: Sequence[tuple[float, float, float, float | None]],
        dcc: ReferenceDcc | None = None,
    ) -> ReferenceStandard:
        """A reference standard with its calibration table: rows of (frequency Hz,
        sensitivity mV/(m/s^2), relative expanded uncertainty as a fraction (0.005 is 0.5 %),
        phase deg or None; a run refuses a table with a phase on some rows only). `dcc`: the
        DCC the table was read from (app.io.reference_dcc), kept with it and in force."""
        identifier = text_field(identifier, "reference id", max_len=100)
        if due_date <= calibration_date:
            raise RecordsError(
                f"due date: {due_date} is not after the calibration date {calibration_date}"
            )
        points = _points(table)
        row = ReferenceStandard(
            identifier=identifier,
            model=text_field(model, "model", max_len=100),
            serial=text_field(serial, "serial", max_len=100),
            certificate_number=text_field(certificate_number, "certificate number", max_len=100),
            calibration_date=calibration_date,
            due_date=due_date,
            points=points,
        )
        with self.session() as s:
            if s.scalar(
                select(ReferenceStandard).where(ReferenceStandard.identifier == identifier)
            ):
                raise RecordsError(f"reference id: {identifier!r} already exists")
            s.add(row)
            if dcc is not None:
                s.flush()
                _keep_dcc(s, row, dcc)
        return row

    def update_reference(
        self,
        identifier: str,
        *,
        model: str,
        serial: str,
        certificate_number: str,
        calibration_date: date,
        due_date: date,
        table: Sequence[tuple[float, float, float, float | None]] | None = None,
        dcc: ReferenceDcc | None = None,
    ) -> ReferenceStandard:
        """Change reference standard `identifier` (a recalibration: its certificate, dates and,
        unless None, its whole calibration table, in `add_reference`'s units), checked as
        `add_reference` checks them; the old values stay in the audit trail. A new table takes
        the DCC in force out of force; `dcc`: the new table's DCC (then in force)."""
        if due_date <= calibration_date:
            raise RecordsError(
                f"due date: {due_date} is not after the calibration date {calibration_date}"
            )
        fields = {
            "model": text_field(model, "model", max_len=100),
            "serial": text_field(serial, "serial", max_len=100),
            "certificate_number": text_field(certificate_number, "certificate number", max_len=100),
        }
        points = _points(table) if table is not None else None
        with self.session() as s:
            row = s.scalar(
                select(ReferenceStandard)
                .options(joinedload(ReferenceStandard.points))
                .where(ReferenceStandard.identifier == identifier.strip())
            )
            if row is None:
                raise RecordsError(f"reference: no reference standard {identifier!r}")
            row.model, row.serial = fields["model"], fields["serial"]
            row.certificate_number = fields["certificate_number"]
            row.calibration_date, row.due_date = calibration_date, due_date
            if points is not None:
                for old in list(row.points):
                    s.delete(old)
                s.flush()
                row.points = points
                for kept in s.scalars(
                    select(ReferenceDccFile).where(
                        ReferenceDccFile.reference_id == row.id, ReferenceDccFile.in_force
                    )
                ):
                    kept.in_force = False
                if dcc is not None:
                    s.flush()
                    _keep_dcc(s, row, dcc)
        return row

    def reference_dcc(self, identifier: str) -> StoredDcc | None:
        """The DCC in force of reference standard `identifier` with its bytes, None when its
        table was not read from one; RecordsError when the bytes kept no longer have the
        SHA-256 recorded."""
        with self.session() as s:
            row = s.scalar(
                select(ReferenceDccFile)
                .join(ReferenceStandard, ReferenceDccFile.reference_id == ReferenceStandard.id)
                .where(
                    ReferenceStandard.identifier == identifier.strip(), ReferenceDccFile.in_force
                )
            )
            if row is None:
                return None
            content = base64.b64decode(row.content_base64)
            if hashlib.sha256(content).hexdigest() != row.sha256:
                raise RecordsError(
                    f"reference {identifier}: its DCC kept no longer has the SHA-256 recorded"
                )
            return StoredDcc(DccIdentity.of(row), row.file_name, content, row.added_utc)

    def references(self) -> list[ReferenceStandard]:
        """Every reference standard with its table, by identifier."""
        with self.session() as s:
            query = (
                select(ReferenceStandard)
                .options(joinedload(ReferenceStandard.points))
                .order_by(ReferenceStandard.identifier)
            )
            return list(s.scalars(query).unique().all())

    def reference_for_run(
        self, identifier: str, *, today: date, override_reason: str | None = None
    ) -> ReferenceStandard:
        """The reference standard a run may use today: an expired one is refused naming its
        due date, unless an override reason is given (it then belongs on the certificate)."""
        with self.session() as s:
            ref = s.scalar(
                select(ReferenceStandard)
                .options(joinedload(ReferenceStandard.points))
                .where(ReferenceStandard.identifier == identifier)
            )
            if ref is None:
                raise RecordsError(f"reference: no reference standard {identifier!r}")
        if ref.due_date < today and not (override_reason and override_reason.strip()):
            raise RecordsError(
                f"reference: {identifier} was due for calibration on {ref.due_date}; "
                "recalibrate it, or give an override reason (it is printed on the certificate)"
            )
        return ref

    def reference_table(self, identifier: str, serial: str) -> ReferenceTable | None:
        """The reference standard named `identifier`, else the one of serial `serial` (a
        stand file's [reference] id and serial), with its table; None when neither is on
        record. Two records of that serial and no identifier match: refused, naming both."""
        with self.session() as s:
            query = select(ReferenceStandard).options(joinedload(ReferenceStandard.points))
            ref = s.scalar(query.where(ReferenceStandard.identifier == identifier))
            if ref is None:
                found = list(
                    s.scalars(query.where(ReferenceStandard.serial == serial)).unique().all()
                )
                if len(found) > 1:
                    names = ", ".join(sorted(r.identifier for r in found))
                    raise RecordsError(
                        f"reference: serial {serial!r} is on record twice ({names}); name one "
                        f"by its id in the stand file's [reference] table"
                    )
                ref = found[0] if found else None
            if ref is None:
                return None
            dcc = s.scalar(
                select(ReferenceDccFile).where(
                    ReferenceDccFile.reference_id == ref.id, ReferenceDccFile.in_force
                )
            )
            return ReferenceTable.of(ref, None if dcc is None else DccIdentity.of(dcc))

    def record_override(self, override: Override, row_key: str) -> None:
        """Enter `override` in the audit trail (action "override", table reference_standards,
        the reference's id or serial as key): who, why, when and what was gone past."""
        with self.session() as s:
            s.add(
                AuditEntry(
                    at_utc=datetime.now(UTC),
                    actor=override.who,
                    action="override",
                    table_name="reference_standards",
                    row_key=text_field(row_key, "reference id", max_len=200),
                    changes=json.dumps(override.to_dict(), sort_keys=True),
                )
            )

    # ---- due list ------------------------------------------------------------------------
    def due(self, *, today: date, days: int) -> list[DueItem]:
        """Sensors and reference standards due on or before today + days, soonest first;
        sensors never calibrated here come first with no date."""
        horizon = today + timedelta(days=days)
        items: list[DueItem] = []
        with self.session() as s:
            rows = s.execute(
                select(Sensor.serial, Sensor.due_date, Customer.name)
                .join(Customer, Sensor.owner_id == Customer.id)
                .where(or_(Sensor.due_date.is_(None), Sensor.due_date <= horizon))
            ).all()
            items.extend(
                DueItem("sensor", serial, due_day, owner) for serial, due_day, owner in rows
            )
            for ref in s.scalars(
                select(ReferenceStandard).where(ReferenceStandard.due_date <= horizon)
            ):
                items.append(DueItem("reference", ref.identifier, ref.due_date, "lab"))
        return sorted(items, key=lambda i: (i.due is not None, i.due or today, i.identifier))
