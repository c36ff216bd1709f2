"""The certificate register in the records: lab settings (number pattern, two-person rule),
numbers allocated in the issuing transaction (no gap, no duplicate), amendments, withdrawals
and the register itself.
"""

from __future__ import annotations

import json
import logging
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import NamedTuple

from sqlalchemy import select
from sqlalchemy.orm import Session, joinedload

from app.records.db.audit import current_actor
from app.records.db.models import AuditEntry, Certificate, RegisterCounter, Run, Sensor, Setting
from app.records.db.sensors import SensorRecords
from app.records.db.signatories import check_two_persons, find_person, signatory_name
from app.records.db.store import RecordsError, text_field, utc
from app.records.run_folder import STATUS_COMPLETE

DEFAULT_PATTERN = "ACC-{year}-{seq:04d}"
SETTING_PATTERN = "certificate_pattern"
SETTING_TWO_PERSON = "two_person_rule"

log = logging.getLogger(__name__)


class Signatories(NamedTuple):
    """Prepared by and approved by as the register keeps them (under the two-person rule: the
    names recorded for the two users they were resolved to)."""

    prepared_by: str
    approved_by: str


@dataclass(frozen=True)
class IssuedFiles:
    """The files of a certificate as its register row keeps them: the PDF's absolute path, its
    SHA-256 and its DCC's (None: no DCC)."""

    file: str
    sha256: str
    dcc_sha256: str | None = None


class CertificateRegister(SensorRecords):
    """Lab settings and the certificate register."""

    # ---- lab settings --------------------------------------------------------------------
    def set_setting(self, key: str, value: str) -> None:
        """Set a lab setting (certificate_pattern, two_person_rule), checked first."""
        if key == SETTING_PATTERN:
            check_pattern(value)
        elif key == SETTING_TWO_PERSON:
            if value not in ("on", "off"):
                raise RecordsError(f"{key}: must be 'on' or 'off', got {value!r}")
        else:
            raise RecordsError(f"setting: unknown key {key!r}")
        with self.session() as s:
            row = s.get(Setting, key)
            if row is None:
                s.add(Setting(key=key, value=value))
            else:
                row.value = value

    def setting(self, key: str, default: str) -> str:
        with self.session() as s:
            row = s.get(Setting, key)
            return default if row is None else row.value

    # ---- certificate register ------------------------------------------------------------
    def check_signatories(self, prepared_by: str, approved_by: str) -> Signatories:
        """Prepared by and approved by as the register takes them (NFKC, format characters
        removed, spaces collapsed: app.records.db.signatories); RecordsError naming the field
        when one is blank or in confusable scripts. Under the lab's two-person rule each must
        be a person on record (an active user, by user name or recorded name) and the two must
        be two users not recorded under one name; the names returned are then the ones
        recorded for them (what the certificate prints and the register keeps)."""
        prepared_by = signatory_name(prepared_by, "prepared by")
        approved_by = signatory_name(approved_by, "approved by")
        if not self.two_person_rule():
            return Signatories(prepared_by, approved_by)
        with self.session() as s:
            prepared = find_person(s, prepared_by, "prepared by")
            approved = find_person(s, approved_by, "approved by")
        check_two_persons(prepared, approved)
        return Signatories(prepared.name, approved.name)

    def two_person_rule(self) -> bool:
        """Whether the lab's two-person rule is on (`register set two_person_rule on`)."""
        return self.setting(SETTING_TWO_PERSON, "off") == "on"

    def complete_runs(self, serial: str) -> list[Run]:
        """The indexed complete runs of sensor `serial`, newest first (what a certificate or
        its amendment may be issued for)."""
        sensor = self.sensor(serial)
        with self.session() as s:
            query = (
                select(Run)
                .where(Run.sensor_id == sensor.id, Run.status == STATUS_COMPLETE)
                .order_by(Run.started_utc.desc(), Run.id.desc())
            )
            return list(s.scalars(query).all())

    def issue_certificate(
        self,
        *,
        run_id: str,
        prepared_by: str,
        approved_by: str,
        when: datetime | None = None,
        replaces: str | None = None,
        reason: str | None = None,
        as_found_run_id: str | None = None,
        produce: Callable[[str], IssuedFiles | None] | None = None,
        taken: Callable[[str], bool] | None = None,
        customer_id: int | None = None,
    ) -> Certificate:
        """Enter a certificate for a complete, indexed run of a known sensor in the register.
        Its number is the next in the lab's pattern, allocated in the same transaction (no gap,
        no duplicate, whichever stand issues at the same time). With `replaces` it is an
        amendment: the replaced certificate is marked replaced with the reason. With
        `as_found_run_id` the sensor was adjusted: that earlier complete run of the same sensor
        is the as-found result and the certified run the as-left one. `produce(number)`, when
        given, makes the certificate itself inside the transaction (under temporary names; the
        files it returns are kept in the row): if it fails, the number is not taken (no gap, no
        entry without its certificate). `taken(number)`: a number some file on disk already
        carries (a crashed issue's leftover); it is skipped, never given twice. One issued
        certificate per run: another is refused (amend it: `replaces`); an amendment must
        replace a certificate of the same sensor. The certificate is issued to the sensor's
        owner now (its `customer_id`, never changed); `customer_id`, when given, is the owner
        the caller's certificate names: refused if the sensor has another owner by now."""
        prepared_by, approved_by = self.check_signatories(prepared_by, approved_by)
        when = when or datetime.now(UTC)
        pattern = self.setting(SETTING_PATTERN, DEFAULT_PATTERN)
        with self.session() as s:
            run = s.scalar(select(Run).where(Run.run_id == run_id))
            if run is None:
                raise RecordsError(f"run: {run_id!r} is not indexed (accelcal db import)")
            if run.status != STATUS_COMPLETE:
                raise RecordsError(f"run: {run_id} is {run.status}, not complete")
            if run.sensor_id is None:
                raise RecordsError(f"run: {run_id}'s DUT {run.dut_id!r} is no sensor on record")
            as_found = None
            if as_found_run_id is not None:
                as_found = s.scalar(select(Run).where(Run.run_id == as_found_run_id))
                if as_found is None:
                    raise RecordsError(f"as found: run {as_found_run_id!r} is not indexed")
                if as_found.sensor_id != run.sensor_id or as_found.status != STATUS_COMPLETE:
                    raise RecordsError(
                        f"as found: run {as_found_run_id} is no complete run of {run.dut_id}"
                    )
                if utc(as_found.started_utc) >= utc(run.started_utc):
                    raise RecordsError(
                        f"as found: run {as_found_run_id} is not before the as-left run {run_id}"
                    )
            old = None
            if replaces is None:
                current = s.scalar(
                    select(Certificate).where(
                        Certificate.run_id == run.id, Certificate.state == "issued"
                    )
                )
                if current is not None:
                    raise RecordsError(
                        f"run: {run_id} already has certificate {current.number}; a run has "
                        f"one certificate: amend it (--replaces {current.number} --reason ...)"
                    )
            else:
                old = s.scalar(
                    select(Certificate).where(Certificate.number == replaces).with_for_update()
                )
                if old is None:
                    raise RecordsError(f"replaces: no certificate {replaces!r}")
                if old.state != "issued":
                    raise RecordsError(f"replaces: {replaces} is already {old.state}")
                if old.sensor_id != run.sensor_id:
                    other = s.get(Sensor, old.sensor_id)
                    raise RecordsError(
                        f"replaces: {replaces} is a certificate of sensor "
                        f"{other.serial if other else old.sensor_id}, not of {run.dut_id}; an "
                        "amendment replaces a certificate of the same sensor"
                    )
                text_field(reason, "reason")
                old.state = "replaced"
                old.reason = reason
            prefix = split_pattern(pattern, when.year)
            self._ensure_counter(s, prefix)
            counter = s.scalar(
                select(RegisterCounter).where(RegisterCounter.prefix == prefix).with_for_update()
            )
            assert counter is not None
            counter.last += 1
            number = pattern.format(year=when.year, seq=counter.last)
            while taken is not None and taken(number):  # a file on disk carries it: skip
                log.warning("certificate number %s skipped: a file on disk carries it", number)
                counter.last += 1
                number = pattern.format(year=when.year, seq=counter.last)
            certificate = Certificate(
                number=number,
                prefix=prefix,
                sequence=counter.last,
                run_id=run.id,
                sensor_id=run.sensor_id,
                state="issued",
                replaces=replaces,
                reason=reason if replaces else None,
                prepared_by=prepared_by,
                approved_by=approved_by,
                issued_utc=when,
                as_found_run=as_found,
                customer_id=self._issued_to(s, run.sensor_id, customer_id),
            )
            s.add(certificate)
            if produce is not None:
                s.flush()  # the number is ours (unique) before anything is written
                files = produce(number)
                if files is not None:
                    certificate.file = files.file
                    certificate.sha256 = files.sha256
                    certificate.dcc_sha256 = files.dcc_sha256
        return certificate

    @staticmethod
    def _issued_to(s: Session, sensor_id: int, named: int | None) -> int:
        """The customer a certificate of sensor `sensor_id` is issued to: its owner, read
        locked in the issuing transaction; refused when it is not `named` (the customer the
        certificate's PDF names, read before), i.e. the sensor changed owner meanwhile."""
        # FOR SHARE (PostgreSQL): a move (UPDATE) waits for the issue; other issues and runs
        # of the sensor do not
        sensor = s.scalar(select(Sensor).where(Sensor.id == sensor_id).with_for_update(read=True))
        assert sensor is not None  # a foreign key of the run
        if named is not None and sensor.owner_id != named:
            raise RecordsError(
                f"customer: sensor {sensor.serial} changed owner while its certificate was "
                "issued; issue it again (the certificate names its owner)"
            )
        return sensor.owner_id

    @staticmethod
    def _ensure_counter(s: Session, prefix: str) -> None:
        """Create the counter row of `prefix` at 0 unless it exists (race-free on both
        engines: INSERT ... ON CONFLICT DO NOTHING)."""
        if s.get_bind().dialect.name == "postgresql":
            from sqlalchemy.dialects.postgresql import insert
        else:
            from sqlalchemy.dialects.sqlite import insert  # type: ignore[assignment]
        s.execute(insert(RegisterCounter).values(prefix=prefix, last=0).on_conflict_do_nothing())

    def withdraw_certificate(self, number: str, reason: str) -> None:
        """Withdraw an issued certificate; the reason is required and kept."""
        reason = text_field(reason, "reason")
        with self.session() as s:
            row = s.scalar(select(Certificate).where(Certificate.number == number))
            if row is None:
                raise RecordsError(f"number: no certificate {number!r}")
            if row.state != "issued":
                raise RecordsError(f"number: {number} is already {row.state}")
            row.state, row.reason = "withdrawn", reason

    def note_override(self, run_id: str, what: str, reason: str) -> None:
        """Enter an override of a check on a run's behalf in the audit trail (e.g. a TEDS
        written to another sensor than the run's); the reason is required."""
        reason = text_field(reason, "reason", max_len=2000)
        with self.session() as s:
            s.add(
                AuditEntry(
                    at_utc=datetime.now(UTC),
                    actor=s.info.get("actor") or current_actor(),
                    action="override",
                    table_name="runs",
                    row_key=text_field(run_id, "run", max_len=200),
                    changes=json.dumps({"override": what, "reason": reason}),
                )
            )

    def certificate(self, number: str) -> Certificate | None:
        """The register's row of certificate `number` (any state), None when there is none."""
        with self.session() as s:
            return s.scalar(select(Certificate).where(Certificate.number == number))

    def issued_for_run(self, run_id: str) -> Certificate | None:
        """The certificate in force (state issued) of the run `run_id`, if any."""
        with self.session() as s:
            return s.scalar(
                select(Certificate)
                .join(Run, Certificate.run_id == Run.id)
                .where(Run.run_id == run_id, Certificate.state == "issued")
            )

    def register(self) -> list[Certificate]:
        """Every certificate in the register, in issue order, with run, sensor and the
        customer it was issued to."""
        with self.session() as s:
            return list(
                s.scalars(
                    select(Certificate)
                    .options(
                        joinedload(Certificate.run),
                        joinedload(Certificate.sensor).joinedload(Sensor.owner),
                        joinedload(Certificate.customer),
                        joinedload(Certificate.as_found_run),
                    )
                    .order_by(Certificate.issued_utc, Certificate.id)
                ).all()
            )


_PATTERN_SEQ = re.compile(r"\{seq:0?(\d+)d\}")


def check_pattern(pattern: str) -> str:
    """A certificate-number pattern: text with {year} optional and {seq:0Nd} once, at the end."""
    match = _PATTERN_SEQ.search(pattern)
    if pattern.count("{seq") != 1 or match is None:
        raise RecordsError(
            f"certificate_pattern: needs exactly one {{seq:04d}}-style field, got {pattern!r}"
        )
    if match.end() != len(pattern):
        raise RecordsError("certificate_pattern: {seq:...} must end the pattern")
    try:
        pattern.format(year=2026, seq=1)
    except (KeyError, ValueError, IndexError) as exc:
        raise RecordsError(f"certificate_pattern: {pattern!r} ({exc})") from None
    return pattern


def split_pattern(pattern: str, year: int) -> str:
    """The fixed prefix of a pattern for `year` (numbers sharing it share one sequence)."""
    match = _PATTERN_SEQ.search(check_pattern(pattern))
    assert match is not None
    return pattern[: match.start()].format(year=year)
