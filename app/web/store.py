"""What the web view reads from the records database, as typed values (no ORM object leaves a
session): the register, one certificate, due items, a sensor's history, the public status of
a certificate (with its review, ISO/IEC 17025 7.10), staff users, and for the customer portal
a customer account and that customer's own certificates and sensors (every portal query is
filtered by the account's customer in SQL: another customer's rows are never read). The engine
is read-only:
SQLite connections are `query_only`, PostgreSQL transactions `default_transaction_read_only`;
nothing here can write.
"""

from __future__ import annotations

import hmac
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, date, datetime
from pathlib import Path
from typing import Any

from sqlalchemy import Engine, create_engine, event, or_, select
from sqlalchemy.engine import make_url
from sqlalchemy.orm import Session, joinedload

from app.certificate.qr import verification_code
from app.records.db.engine import (
    SQLITE_BUSY_TIMEOUT_S,
    DatabaseError,
    current_revision,
    head_revision,
    resolve_url,
)
from app.records.db.lab import DueItem, History, Lab
from app.records.db.models import (
    Certificate,
    CertificateReview,
    Customer,
    CustomerAccount,
    Run,
    Sensor,
    SensorModel,
    User,
)
from app.records.db.reviews import Review, as_review
from app.web.shared import SharedRun, shared_runs

SEARCH_LIMIT = 200  # register rows on one page
STATUS_WORDS = {"issued": "valid", "replaced": "amended", "withdrawn": "withdrawn"}


@dataclass(frozen=True)
class Status:
    """A certificate's status as the web view states it: `word` (valid, amended, withdrawn or
    review: also its CSS class) and `text`, the words shown."""

    word: str
    text: str
    item: str = ""  # the public page's identity of the item: its model and masked serial


def masked_serial(serial: str) -> str:
    """A serial as the public page shows it: its last third (1-4 characters) kept, the rest
    masked, so that the holder of the certificate recognises the item and a stranger who
    guessed an address learns no whole serial ("SN-WEB-1" -> "•••••B-1")."""
    keep = min(4, max(1, -(-len(serial) // 3)))  # a third, rounded up
    return "•" * (len(serial) - keep) + serial[-keep:]


def _why(review: Review) -> str:
    opened = f"{review.opened_utc:%Y-%m-%d}"
    if review.reference:
        return f"reference standard {review.reference} found out of tolerance on {opened}"
    return f"{review.subject}, since {opened}"


def certificate_status(state: str, reviews: Sequence[Review]) -> Status:
    """The status of a certificate in register `state` with its `reviews` (oldest first):
    withdrawn; else under review while a review is open ("under review (reference standard
    REF found out of tolerance on DATE)"); else amended ("amended by N" when a review was
    closed by that amendment); else valid (also once a review is closed as confirmed)."""
    if state == "withdrawn":
        return Status("withdrawn", "withdrawn")
    still_open = [r for r in reviews if r.outcome is None]
    if still_open:
        return Status("review", f"under review ({'; '.join(_why(r) for r in still_open)})")
    if state == "replaced":
        amended = [r.amended_by for r in reviews if r.outcome == "amended" and r.amended_by]
        return Status("amended", f"amended by {amended[-1]}" if amended else "amended")
    return Status("valid", STATUS_WORDS.get(state, state))


@dataclass(frozen=True)
class CertificateRow:
    """One certificate of the register as the web view shows it (sensitivity and U at the
    reference frequency in mV/(m/s^2), the run folder's path on the lab's disk, the files
    issued as the register recorded them)."""

    number: str
    state: str
    status: str  # the words shown (certificate_status)
    issued_utc: datetime
    serial: str
    customer: str
    model: str
    run_id: str
    run_folder: str
    manifest_sha256: str
    prepared_by: str
    approved_by: str
    replaces: str | None
    reason: str | None
    reference_frequency_hz: float | None
    sensitivity_mv_per_ms2: float | None
    expanded_uncertainty_mv_per_ms2: float | None
    file: str | None = None  # the issued PDF's absolute path (None: entered before 0009)
    sha256: str | None = None  # the issued PDF's SHA-256, hex
    dcc_sha256: str | None = None  # its DCC's SHA-256, hex (None: issued without a DCC)
    status_class: str = "valid"  # Status.word: valid, amended, withdrawn or review


@dataclass(frozen=True)
class StaffUser:
    """A staff user as the login needs it."""

    username: str
    display_name: str
    password_hash: str
    active: bool


@dataclass(frozen=True)
class PortalAccount:
    """A customer account as the portal's sign-in and guard need it: the customer it is bound
    to (id and name) is read from the records at every request."""

    username: str
    display_name: str
    password_hash: str
    active: bool
    customer_id: int
    customer: str


@dataclass(frozen=True)
class SensorDue:
    """A customer's sensor with its next calibration due: the date the records keep (the last
    calibration here plus the sensor's interval in months; None: never calibrated here)."""

    serial: str
    model: str
    interval_months: int
    last_calibrated_utc: datetime | None
    due: date | None


def _safe(url: str) -> str:
    return make_url(url).render_as_string(hide_password=True)


def _sqlite_read_only(dbapi_connection: Any, _record: Any) -> None:
    cursor = dbapi_connection.cursor()
    cursor.execute(f"PRAGMA busy_timeout = {int(SQLITE_BUSY_TIMEOUT_S * 1000)}")
    cursor.execute("PRAGMA query_only = ON")
    cursor.close()


def open_read_only(url: str | None) -> Engine:
    """A read-only engine on the records at `url` (else $ACCELCAL_DB, else the default file),
    refused (DatabaseError naming why) when the database is missing, unreachable or not at
    this program's schema revision."""
    resolved = resolve_url(url)
    parsed = make_url(resolved)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database or ""
        if database in ("", ":memory:") or not Path(database).is_file():
            raise DatabaseError(f"--db: no records database at {_safe(resolved)}")
        engine = create_engine(resolved, connect_args={"timeout": SQLITE_BUSY_TIMEOUT_S})
        event.listen(engine, "connect", _sqlite_read_only)
    else:
        engine = create_engine(
            resolved,
            pool_pre_ping=True,
            connect_args={"options": "-c default_transaction_read_only=on"},
        )
    try:
        current = current_revision(engine)
    except Exception as exc:  # unreachable server, damaged file
        engine.dispose()
        raise DatabaseError(f"--db: {_safe(resolved)}: cannot connect ({exc})") from exc
    head = head_revision(engine)
    if current != head:
        engine.dispose()
        raise DatabaseError(
            f"--db: {_safe(resolved)}: schema revision {current or 'none'}, this program needs "
            f"{head}; run `accelcal db upgrade`"
        )
    return engine


class Store:
    """Read-only queries of the web view over one engine."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self.lab = Lab(engine, actor="web view")

    @contextmanager
    def _session(self) -> Iterator[Session]:
        with Session(self.engine) as session:
            try:
                yield session
            finally:
                session.rollback()  # nothing to keep: read only

    def _rows(self, session: Session, *where: Any) -> list[CertificateRow]:
        query = (
            select(Certificate, Run, Sensor, Customer, SensorModel)
            .join(Run, Certificate.run_id == Run.id)
            .join(Sensor, Certificate.sensor_id == Sensor.id)
            .join(Customer, Certificate.customer_id == Customer.id)  # issued to, not the owner now
            .join(SensorModel, Sensor.model_id == SensorModel.id)
            .where(*where)
            .order_by(Certificate.issued_utc.desc(), Certificate.id.desc())
            .limit(SEARCH_LIMIT)
        )
        found = session.execute(query).all()
        reviews = self._reviews(session, [c.id for c, *_ in found])
        rows = []
        for c, r, s, o, m in found:
            status = certificate_status(c.state, reviews.get(c.id, ()))
            rows.append(
                CertificateRow(
                    number=c.number,
                    state=c.state,
                    status=status.text,
                    issued_utc=_utc(c.issued_utc),
                    serial=s.serial,
                    customer=o.name,
                    model=f"{m.maker} {m.model}",
                    run_id=r.run_id,
                    run_folder=r.folder,
                    manifest_sha256=r.manifest_sha256,
                    prepared_by=c.prepared_by,
                    approved_by=c.approved_by,
                    replaces=c.replaces,
                    reason=c.reason,
                    reference_frequency_hz=r.reference_frequency_hz,
                    sensitivity_mv_per_ms2=r.sensitivity_mv_per_ms2,
                    expanded_uncertainty_mv_per_ms2=r.expanded_uncertainty_mv_per_ms2,
                    file=c.file,
                    sha256=c.sha256,
                    dcc_sha256=c.dcc_sha256,
                    status_class=status.word,
                )
            )
        return rows

    @staticmethod
    def _reviews(session: Session, certificate_ids: list[int]) -> dict[int, list[Review]]:
        """The reviews of these certificates (by certificate id), oldest first."""
        if not certificate_ids:
            return {}
        query = (
            select(CertificateReview)
            .options(joinedload(CertificateReview.certificate))
            .where(CertificateReview.certificate_id.in_(certificate_ids))
            .order_by(CertificateReview.opened_utc, CertificateReview.id)
        )
        out: dict[int, list[Review]] = {}
        for row in session.scalars(query):
            out.setdefault(row.certificate_id, []).append(as_review(row))
        return out

    def register(self, search: str = "") -> list[CertificateRow]:
        """Certificates, newest first (at most SEARCH_LIMIT), whose number, sensor serial,
        customer or run id contains `search` (case-insensitive)."""
        text = search.strip()
        where = []
        if text:
            pattern = f"%{_escape_like(text)}%"
            where.append(
                or_(
                    *(
                        column.ilike(pattern, escape="\\")
                        for column in (Certificate.number, Sensor.serial, Customer.name, Run.run_id)
                    )
                )
            )
        with self._session() as s:
            return self._rows(s, *where)

    def certificate(self, number: str) -> CertificateRow | None:
        """The certificate numbered `number` exactly, or None."""
        with self._session() as s:
            rows = self._rows(s, Certificate.number == number)
        return rows[0] if rows else None

    def replaced_by(self, number: str) -> str | None:
        """The number of the certificate that amends `number`, if any."""
        with self._session() as s:
            return s.scalar(select(Certificate.number).where(Certificate.replaces == number))

    def public_status(self, number: str, code: str) -> Status | None:
        """The status of certificate `number` (certificate_status: valid, under review,
        amended, withdrawn) when `code` is its verification code (app.certificate.qr); None
        for an unknown number or a wrong code alike (the answer never tells which numbers
        exist)."""
        with self._session() as s:
            row = s.execute(
                select(
                    Certificate.id,
                    Certificate.state,
                    Run.manifest_sha256,
                    Sensor.serial,
                    SensorModel.maker,
                    SensorModel.model,
                )
                .join(Run, Certificate.run_id == Run.id)
                .join(Sensor, Certificate.sensor_id == Sensor.id)
                .join(SensorModel, Sensor.model_id == SensorModel.id)
                .where(Certificate.number == number)
            ).first()
            reviews = self._reviews(s, [row[0]]) if row is not None else {}
        expected = verification_code(number, row[2]) if row is not None else "x" * 16
        if not hmac.compare_digest(expected.encode(), code.strip().lower().encode()):
            return None
        if row is None:
            return None
        status = certificate_status(row[1], reviews.get(row[0], ()))
        item = f"{row[4]} {row[5]}, serial {masked_serial(row[3])}"
        return Status(status.word, status.text, item)

    def due(self, *, today: date, days: int) -> list[DueItem]:
        """Sensors and reference standards due by today + days (Lab.due)."""
        return self.lab.due(today=today, days=days)

    def history(self, serial: str) -> History:
        """A sensor's calibrations and drift (Lab.history); RecordsError when unknown."""
        return self.lab.history(serial)

    def shared_runs(self, serial: str) -> list[SharedRun]:
        """The runs sensor `serial` shared with other DUTs (staff only: app.web.shared)."""
        with self._session() as s:
            return shared_runs(s, serial)

    def sensor_certificates(self, serial: str) -> list[CertificateRow]:
        """The certificates of sensor `serial`, newest first."""
        with self._session() as s:
            return self._rows(s, Sensor.serial == serial)

    def user(self, username: str) -> StaffUser | None:
        """The staff user named `username`, or None."""
        with self._session() as s:
            row = s.scalar(select(User).where(User.username == username))
            if row is None:
                return None
            return StaffUser(row.username, row.display_name, row.password_hash, row.active)

    # ---- the customer portal: every query bound to one customer --------------------------
    def account(self, username: str) -> PortalAccount | None:
        """The customer account named `username` with its customer, or None."""
        with self._session() as s:
            row = s.execute(
                select(CustomerAccount, Customer.name)
                .join(Customer, CustomerAccount.customer_id == Customer.id)
                .where(CustomerAccount.username == username)
            ).first()
            if row is None:
                return None
            a, name = row
            return PortalAccount(
                a.username, a.display_name, a.password_hash, a.active, a.customer_id, name
            )

    def customer_certificates(self, customer_id: int) -> list[CertificateRow]:
        """The certificates issued to customer `customer_id` (Certificate.customer_id: of
        sensors it owned then, whoever owns them now), newest first."""
        with self._session() as s:
            return self._rows(s, Certificate.customer_id == customer_id)

    def customer_certificate(self, customer_id: int, number: str) -> CertificateRow | None:
        """Certificate `number` when it was issued to customer `customer_id`, else None (the
        same None as for a number that does not exist; a sensor's later owner gets None too)."""
        with self._session() as s:
            where = (Certificate.number == number, Certificate.customer_id == customer_id)
            rows = self._rows(s, *where)
        return rows[0] if rows else None

    def customer_sensors(self, customer_id: int, serial: str | None = None) -> list[SensorDue]:
        """Customer `customer_id`'s sensors (only `serial`, when given) with their due dates,
        the never calibrated first, then soonest due."""
        where = [Sensor.owner_id == customer_id]
        if serial is not None:
            where.append(Sensor.serial == serial)
        with self._session() as s:
            found = s.execute(
                select(Sensor, SensorModel)
                .join(SensorModel, Sensor.model_id == SensorModel.id)
                .where(*where)
            ).all()
            rows = [
                SensorDue(
                    serial=sensor.serial,
                    model=f"{model.maker} {model.model}",
                    interval_months=sensor.interval_months,
                    last_calibrated_utc=(
                        _utc(sensor.last_calibrated_utc) if sensor.last_calibrated_utc else None
                    ),
                    due=sensor.due_date,
                )
                for sensor, model in found
            ]
        return sorted(rows, key=lambda r: (r.due is not None, r.due or date.min, r.serial))

    def customer_sensor_certificates(self, customer_id: int, serial: str) -> list[CertificateRow]:
        """The certificates of sensor `serial` issued to customer `customer_id` (none of a
        previous owner's; the portal shows the sensor's page only to its owner now)."""
        with self._session() as s:
            return self._rows(s, Sensor.serial == serial, Certificate.customer_id == customer_id)


def _escape_like(text: str) -> str:
    return text.replace("\\", "\\\\").replace("%", "\\%").replace("_", "\\_")


def _utc(moment: datetime) -> datetime:
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)
