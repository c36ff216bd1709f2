"""The records database's tables as typed SQLAlchemy 2 mapped classes.

The schema itself is created by the Alembic migrations in app/records/db/migrations (never by
`create_all`), so a database always carries the revision it was built to.
"""

from __future__ import annotations

from datetime import date, datetime

from sqlalchemy import (
    Boolean,
    CheckConstraint,
    Date,
    DateTime,
    Float,
    ForeignKey,
    Integer,
    String,
    Text,
    UniqueConstraint,
)
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column, relationship


class Base(DeclarativeBase):
    """Declarative base of every records table."""


class Customer(Base):
    """A customer owning sensors; `name` is unique."""

    __tablename__ = "customers"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200), unique=True)
    address: Mapped[str] = mapped_column(Text, default="")
    sensors: Mapped[list[Sensor]] = relationship(back_populates="owner")


class SensorModel(Base):
    """An accelerometer model: maker, type, nominal sensitivity with tolerance, range, plan."""

    __tablename__ = "sensor_models"
    __table_args__ = (
        UniqueConstraint("maker", "model"),
        CheckConstraint("nominal_sensitivity > 0", name="nominal_positive"),
        CheckConstraint("tolerance_percent > 0", name="tolerance_positive"),
        CheckConstraint(
            "frequency_min_hz > 0 AND frequency_max_hz > frequency_min_hz", name="range"
        ),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    maker: Mapped[str] = mapped_column(String(100))
    model: Mapped[str] = mapped_column(String(100))
    nominal_sensitivity: Mapped[float] = mapped_column(Float)
    unit: Mapped[str] = mapped_column(String(20))
    tolerance_percent: Mapped[float] = mapped_column(Float)
    frequency_min_hz: Mapped[float] = mapped_column(Float)
    frequency_max_hz: Mapped[float] = mapped_column(Float)
    preset: Mapped[str] = mapped_column(String(40), default="piezo")
    level_ms2: Mapped[float] = mapped_column(Float, default=5.0)
    phase_tolerance_deg: Mapped[float | None] = mapped_column(Float, nullable=True)
    sensors: Mapped[list[Sensor]] = relationship(back_populates="model")


class RunTemplate(Base):
    """Named run settings for one sensor model, chosen from a list in the GUI: plan preset and
    lines (Hz), level (m/s^2 peak per line), periods or a type A target (relative), a time
    bound (s), tolerance (%) and estimator. `name` is unique per model."""

    __tablename__ = "run_templates"
    __table_args__ = (
        UniqueConstraint("model_id", "name", name="uq_run_templates_model_name"),
        CheckConstraint("level_ms2 > 0", name="level_positive"),
        CheckConstraint("periods >= 2", name="periods_enough"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    model_id: Mapped[int] = mapped_column(ForeignKey("sensor_models.id"))
    name: Mapped[str] = mapped_column(String(100))
    preset: Mapped[str] = mapped_column(String(40))
    frequencies_hz: Mapped[str | None] = mapped_column(Text, nullable=True)  # "10,12.5,..." Hz
    level_ms2: Mapped[float] = mapped_column(Float)
    periods: Mapped[int] = mapped_column(Integer)
    target_type_a: Mapped[float | None] = mapped_column(Float, nullable=True)  # relative
    max_acquisition_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    tolerance_percent: Mapped[float | None] = mapped_column(Float, nullable=True)
    estimator: Mapped[str] = mapped_column(String(20))
    model: Mapped[SensorModel] = relationship()

    def lines_hz(self) -> tuple[float, ...] | None:
        """The template's own line list in Hz (None: the preset's lines)."""
        if not self.frequencies_hz:
            return None
        return tuple(float(item) for item in self.frequencies_hz.split(","))


class Sensor(Base):
    """One accelerometer: serial (unique), model, owner, TEDS identity, calibration interval."""

    __tablename__ = "sensors"
    __table_args__ = (CheckConstraint("interval_months > 0", name="interval_positive"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    serial: Mapped[str] = mapped_column(String(100), unique=True)
    model_id: Mapped[int] = mapped_column(ForeignKey("sensor_models.id"))
    owner_id: Mapped[int] = mapped_column(ForeignKey("customers.id"))
    teds_identity: Mapped[str | None] = mapped_column(String(100), nullable=True)
    interval_months: Mapped[int] = mapped_column(Integer, default=12)
    # derived from the runs, kept by the records in the transaction that indexes a run
    last_calibrated_utc: Mapped[datetime | None] = mapped_column(
        DateTime(timezone=True), nullable=True
    )
    due_date: Mapped[date | None] = mapped_column(Date, nullable=True)
    check_standard: Mapped[bool] = mapped_column(Boolean, default=False)
    model: Mapped[SensorModel] = relationship(back_populates="sensors")
    owner: Mapped[Customer] = relationship(back_populates="sensors")
    runs: Mapped[list[Run]] = relationship(back_populates="sensor")


class ReferenceStandard(Base):
    """A reference accelerometer with its own calibration (certificate, dates, table)."""

    __tablename__ = "reference_standards"
    __table_args__ = (CheckConstraint("due_date > calibration_date", name="due_after_calibration"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    identifier: Mapped[str] = mapped_column(String(100), unique=True)
    model: Mapped[str] = mapped_column(String(100))
    serial: Mapped[str] = mapped_column(String(100))
    certificate_number: Mapped[str] = mapped_column(String(100))
    calibration_date: Mapped[date] = mapped_column(Date)
    due_date: Mapped[date] = mapped_column(Date)
    points: Mapped[list[ReferencePoint]] = relationship(
        back_populates="reference", order_by="ReferencePoint.frequency_hz"
    )


class ReferencePoint(Base):
    """One row of a reference standard's calibration table, in mV/(m/s^2) and degrees."""

    __tablename__ = "reference_points"
    __table_args__ = (
        UniqueConstraint("reference_id", "frequency_hz"),
        CheckConstraint("frequency_hz > 0 AND sensitivity_mv_per_ms2 > 0", name="positive"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    reference_id: Mapped[int] = mapped_column(ForeignKey("reference_standards.id"))
    frequency_hz: Mapped[float] = mapped_column(Float)
    sensitivity_mv_per_ms2: Mapped[float] = mapped_column(Float)
    relative_expanded_uncertainty: Mapped[float] = mapped_column(Float)
    phase_deg: Mapped[float | None] = mapped_column(Float, nullable=True)
    reference: Mapped[ReferenceStandard] = relationship(back_populates="points")


class ReferenceDccFile(Base):
    """A reference standard's DCC as read in (`refs add --dcc`): its identity, the signature
    as verified, the SHA-256 and the file itself (base64 of its bytes); the one `in_force` is
    the reference's current calibration (a recalibration takes it out of force, migration
    0013)."""

    __tablename__ = "reference_dccs"
    id: Mapped[int] = mapped_column(primary_key=True)
    reference_id: Mapped[int] = mapped_column(ForeignKey("reference_standards.id"), index=True)
    unique_identifier: Mapped[str] = mapped_column(String(200))
    laboratory: Mapped[str] = mapped_column(String(300))
    sha256: Mapped[str] = mapped_column(String(64))
    signature: Mapped[str] = mapped_column(String(500))
    file_name: Mapped[str] = mapped_column(String(255))
    content_base64: Mapped[str] = mapped_column(Text)
    added_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    in_force: Mapped[bool] = mapped_column(Boolean, default=True)


class Stand(Base):
    """A calibration stand, known by the SHA-256 of its stand file."""

    __tablename__ = "stands"
    id: Mapped[int] = mapped_column(primary_key=True)
    stand_file_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    name: Mapped[str] = mapped_column(String(200))


class Run(Base):
    """A stored run folder, indexed by its run id and its manifest's SHA-256."""

    __tablename__ = "runs"
    id: Mapped[int] = mapped_column(primary_key=True)
    run_id: Mapped[str] = mapped_column(String(100), unique=True)
    manifest_sha256: Mapped[str] = mapped_column(String(64), unique=True)
    folder: Mapped[str] = mapped_column(Text)
    status: Mapped[str] = mapped_column(String(20))
    started_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    dut_id: Mapped[str] = mapped_column(String(100))
    stand_id: Mapped[int] = mapped_column(ForeignKey("stands.id"))
    sensor_id: Mapped[int | None] = mapped_column(ForeignKey("sensors.id"), nullable=True)
    reference_frequency_hz: Mapped[float | None] = mapped_column(Float, nullable=True)
    sensitivity_mv_per_ms2: Mapped[float | None] = mapped_column(Float, nullable=True)
    expanded_uncertainty_mv_per_ms2: Mapped[float | None] = mapped_column(Float, nullable=True)
    # the batch it was one DUT of (issue 36, migration 0015); None: a single-DUT run
    batch_id: Mapped[str | None] = mapped_column(String(100), nullable=True, index=True)
    sensor: Mapped[Sensor | None] = relationship(back_populates="runs")
    stand: Mapped[Stand] = relationship()


class Setting(Base):
    """A lab setting (certificate number pattern, two-person rule), one row per key."""

    __tablename__ = "settings"
    key: Mapped[str] = mapped_column(String(100), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class RegisterCounter(Base):
    """The last sequence number used for one certificate-number prefix (e.g. 'ACC-2026-')."""

    __tablename__ = "register_counters"
    prefix: Mapped[str] = mapped_column(String(100), primary_key=True)
    last: Mapped[int] = mapped_column(Integer)


class Certificate(Base):
    """One certificate in the register: issued, amended (replaced) or withdrawn."""

    __tablename__ = "certificates"
    __table_args__ = (
        CheckConstraint("state IN ('issued', 'replaced', 'withdrawn')", name="state"),
        UniqueConstraint("prefix", "sequence"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    number: Mapped[str] = mapped_column(String(100), unique=True)
    prefix: Mapped[str] = mapped_column(String(100))
    sequence: Mapped[int] = mapped_column(Integer)
    run_id: Mapped[int] = mapped_column(ForeignKey("runs.id"))
    sensor_id: Mapped[int] = mapped_column(ForeignKey("sensors.id"))
    state: Mapped[str] = mapped_column(String(20), default="issued")
    replaces: Mapped[str | None] = mapped_column(String(100), nullable=True)
    reason: Mapped[str | None] = mapped_column(Text, nullable=True)
    prepared_by: Mapped[str] = mapped_column(String(200))
    approved_by: Mapped[str] = mapped_column(String(200))
    issued_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    as_found_run_id: Mapped[int | None] = mapped_column(ForeignKey("runs.id"), nullable=True)
    # the files issued (migration 0009; None for rows entered before): the PDF's absolute path,
    # its SHA-256 and its DCC's (None: no DCC), as written under their temporary names
    file: Mapped[str | None] = mapped_column(Text, nullable=True)
    sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    dcc_sha256: Mapped[str | None] = mapped_column(String(64), nullable=True)
    # the customer it is issued to (migration 0014): the sensor's owner when it was issued,
    # the customer its PDF names; never changed (rows issued before 0014: the owner at upgrade)
    customer_id: Mapped[int] = mapped_column(ForeignKey("customers.id"))
    run: Mapped[Run] = relationship(foreign_keys=[run_id])
    as_found_run: Mapped[Run | None] = relationship(foreign_keys=[as_found_run_id])
    sensor: Mapped[Sensor] = relationship()
    customer: Mapped[Customer] = relationship()


class AuditEntry(Base):
    """One write to the records: who, when (UTC), what (table, key, action, changed values).

    Append-only: the migrations install triggers that refuse UPDATE and DELETE on this table.
    """

    __tablename__ = "audit_trail"
    id: Mapped[int] = mapped_column(primary_key=True)
    at_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    actor: Mapped[str] = mapped_column(String(200))
    action: Mapped[str] = mapped_column(String(10))
    table_name: Mapped[str] = mapped_column(String(100))
    row_key: Mapped[str] = mapped_column(String(200))
    changes: Mapped[str] = mapped_column(Text)


class User(Base):
    """A member of the lab's staff who may sign in to the web view: a unique user name, a
    display name and an argon2 password hash (app.web.users); `active` False locks them out."""

    __tablename__ = "users"
    id: Mapped[int] = mapped_column(primary_key=True)
    username: Mapped[str] = mapped_column(String(100), unique=True)
    display_name: Mapped[str] = mapped_column(String(200))
    password_hash: Mapped[str] = mapped_column(String(200))
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    created_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))


class CustomerAccount(Base):
    """A customer's sign-in to the web view's portal (issue 35 point 5), created by staff and
    bound to one records customer: a unique user name, a display name, an argon2 password hash
    (app.web.accounts) and `active` (False: disabled by staff). It opens no staff page."""

    __tablename__ = "customer_accounts"
    id: Mapped[int] = mapped_column(primary_key=True)
    username: Mapped[str] = mapped_column(String(100), unique=True)
    display_name: Mapped[str] = mapped_column(String(200))
    customer_id: Mapped[int] = mapped_column(ForeignKey("customers.id"))
    password_hash: Mapped[str] = mapped_column(String(200))
    active: Mapped[bool] = mapped_column(Boolean, default=True)
    created_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    customer: Mapped[Customer] = relationship()


class CertificateReview(Base):
    """A certificate under review (ISO/IEC 17025 7.10): why (e.g. the impact of a reference
    standard found out of tolerance), when it was opened (UTC) and, once decided, whether the
    certificate was amended or confirmed. The certificate's own state is left as it is."""

    __tablename__ = "certificate_reviews"
    __table_args__ = (
        CheckConstraint("outcome IS NULL OR outcome IN ('amended', 'confirmed')", name="outcome"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    certificate_id: Mapped[int] = mapped_column(ForeignKey("certificates.id"))
    subject: Mapped[str] = mapped_column(String(200))  # e.g. "impact of REF SIM-0001"
    reason: Mapped[str] = mapped_column(Text)
    opened_utc: Mapped[datetime] = mapped_column(DateTime(timezone=True))
    outcome: Mapped[str | None] = mapped_column(String(20), nullable=True)
    closed_utc: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    # migration 0010: who closed it, why, and the amendment that replaced the certificate
    closed_by: Mapped[str | None] = mapped_column(String(200), nullable=True)
    close_reason: Mapped[str | None] = mapped_column(Text, nullable=True)
    amended_by: Mapped[str | None] = mapped_column(String(100), nullable=True)
    certificate: Mapped[Certificate] = relationship()


class ChainEntry(Base):
    """One link of the records' hash chain (app.records.db.chain): the full new content of one
    audited row (canonical JSON; None when deleted), who and when (UTC, ISO 8601), the journal
    row it accounts for, the schema fingerprint, and sha256(prev_hash || entry) in hex; the last
    entry of each append also the records key's signature of it.

    Append-only: migration 0007 installs triggers that refuse UPDATE and DELETE on it."""

    __tablename__ = "records_chain"
    seq: Mapped[int] = mapped_column(Integer, primary_key=True, autoincrement=False)
    at_utc: Mapped[str] = mapped_column(String(40))
    actor: Mapped[str] = mapped_column(String(200))
    action: Mapped[str] = mapped_column(String(10))
    table_name: Mapped[str] = mapped_column(String(100))
    row_key: Mapped[str] = mapped_column(String(200))
    row: Mapped[str | None] = mapped_column(Text, nullable=True)
    journal_id: Mapped[int | None] = mapped_column(Integer, unique=True, nullable=True)
    schema_fingerprint: Mapped[str] = mapped_column(String(100))
    prev_hash: Mapped[str] = mapped_column(String(64), unique=True)
    hash: Mapped[str] = mapped_column(String(64), unique=True)
    # the head's Ed25519 signature (hex) and the records key's id, on the last entry of each
    # append (migration 0011; None on the entries before it, which a later head covers)
    signature: Mapped[str | None] = mapped_column(String(128), nullable=True)
    key_id: Mapped[str | None] = mapped_column(String(64), nullable=True)


class JournalEntry(Base):
    """A row change noted by a database trigger, whoever made it (table, primary key,
    insert/update/delete); the chain entry of an application write claims it by id."""

    __tablename__ = "records_journal"
    id: Mapped[int] = mapped_column(primary_key=True)
    table_name: Mapped[str] = mapped_column(String(100))
    row_key: Mapped[str] = mapped_column(String(200))
    action: Mapped[str] = mapped_column(String(10))
