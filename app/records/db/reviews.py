"""Certificates under review (ISO/IEC 17025 7.10) and the runs a review looks at: the indexed
runs in a time window with their certificates and owners, and the review flag itself (opened
with a subject and reason; closed as confirmed, or as amended once an amendment of the same
sensor replaces the certificate, with who and why), every write audited and chained.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.orm import Session, joinedload

from app.records.db.models import Certificate, CertificateReview, Run, Sensor
from app.records.db.store import RecordsError, Store, text_field, utc

OUTCOMES = ("amended", "confirmed")
IMPACT_SUBJECT = "impact of reference "  # + the reference standard's serial or id


def impact_subject(serial: str) -> str:
    """The subject of a review opened by the impact of reference standard `serial`."""
    return f"{IMPACT_SUBJECT}{serial}"


@dataclass(frozen=True)
class IndexedRun:
    """An indexed run as a review needs it: its folder and the manifest hash the index holds
    (the folder must still verify against it), its owner and its certificates' numbers."""

    run_id: str
    folder: str
    manifest_sha256: str
    started_utc: datetime
    status: str
    dut_id: str
    owner: str | None
    owner_address: str | None
    certificates: tuple[str, ...]  # issued ones (not replaced or withdrawn), in issue order


@dataclass(frozen=True)
class Review:
    """One review of a certificate: subject, reason, opened (UTC), outcome when closed, and
    how it was closed: when (UTC), by whom, why, and the amendment that replaced it."""

    number: str
    subject: str
    reason: str
    opened_utc: datetime
    outcome: str | None
    closed_utc: datetime | None
    closed_by: str | None = None
    close_reason: str | None = None
    amended_by: str | None = None

    @property
    def reference(self) -> str | None:
        """The reference standard whose impact opened it (None: another subject)."""
        if self.subject.startswith(IMPACT_SUBJECT):
            return self.subject[len(IMPACT_SUBJECT) :].strip() or None
        return None


def as_review(r: CertificateReview) -> Review:
    """The typed Review of a row (read inside its session)."""
    return Review(
        r.certificate.number,
        r.subject,
        r.reason,
        utc(r.opened_utc),
        r.outcome,
        None if r.closed_utc is None else utc(r.closed_utc),
        r.closed_by,
        r.close_reason,
        r.amended_by,
    )


class ReviewRecords(Store):
    """The runs in a window and the review flags of certificates."""

    def runs_between(self, since: datetime | None, until: datetime | None) -> list[IndexedRun]:
        """Every indexed run started in [since, until] (either end open when None), oldest
        first, with its owner and issued certificates."""
        with self.session() as s:
            query = select(Run).options(joinedload(Run.sensor).joinedload(Sensor.owner))
            if since is not None:
                query = query.where(Run.started_utc >= since)
            if until is not None:
                query = query.where(Run.started_utc <= until)
            runs = s.scalars(query.order_by(Run.started_utc, Run.id)).unique().all()
            issued: dict[int, list[str]] = {}
            for run_key, number in s.execute(
                select(Certificate.run_id, Certificate.number)
                .where(Certificate.state == "issued")
                .order_by(Certificate.issued_utc, Certificate.id)
            ):
                issued.setdefault(run_key, []).append(number)
            return [
                IndexedRun(
                    run_id=r.run_id,
                    folder=r.folder,
                    manifest_sha256=r.manifest_sha256,
                    started_utc=utc(r.started_utc),
                    status=r.status,
                    dut_id=r.dut_id,
                    owner=r.sensor.owner.name if r.sensor else None,
                    owner_address=r.sensor.owner.address if r.sensor else None,
                    certificates=tuple(issued.get(r.id, ())),
                )
                for r in runs
            ]

    def open_review(self, number: str, *, subject: str, reason: str) -> bool:
        """Flag certificate `number` under review for `subject` (e.g. "impact of REF X") with
        `reason`; False (nothing written) when a review of the same subject is already open.
        RecordsError naming the field for an unknown certificate or a blank subject/reason."""
        subject = text_field(subject, "subject")
        reason = text_field(reason, "reason", max_len=2000)
        with self.session() as s:
            certificate = s.scalar(select(Certificate).where(Certificate.number == number))
            if certificate is None:
                raise RecordsError(f"number: no certificate {number!r}")
            if s.scalar(
                select(CertificateReview).where(
                    CertificateReview.certificate_id == certificate.id,
                    CertificateReview.subject == subject,
                    CertificateReview.outcome.is_(None),
                )
            ):
                return False
            s.add(
                CertificateReview(
                    certificate=certificate,
                    subject=subject,
                    reason=reason,
                    opened_utc=datetime.now(UTC),
                )
            )
        return True

    def close_review(
        self,
        number: str,
        *,
        outcome: str,
        reason: str,
        amended_by: str | None = None,
        subject: str | None = None,
    ) -> list[Review]:
        """Close the open reviews of certificate `number` (only the one of `subject` when
        given) with `reason`, by this Lab's actor: "confirmed" (the result stands; the
        certificate must still be in force) or "amended" (`amended_by`: an amendment of the
        same sensor that replaces `number`, not withdrawn). The reviews closed; RecordsError
        naming the field otherwise (nothing written)."""
        if outcome not in OUTCOMES:
            raise RecordsError(f"outcome: must be one of {', '.join(OUTCOMES)}, got {outcome!r}")
        reason = text_field(reason, "reason", max_len=2000)
        with self.session() as s:
            certificate = s.scalar(select(Certificate).where(Certificate.number == number))
            if certificate is None:
                raise RecordsError(f"number: no certificate {number!r}")
            query = select(CertificateReview).where(
                CertificateReview.certificate_id == certificate.id,
                CertificateReview.outcome.is_(None),
            )
            if subject is not None:
                query = query.where(CertificateReview.subject == subject)
            rows = list(s.scalars(query.order_by(CertificateReview.id)).all())
            if not rows:
                about = f" for {subject!r}" if subject is not None else ""
                raise RecordsError(f"number: {number} has no open review{about}")
            if outcome == "confirmed":
                if amended_by is not None:
                    raise RecordsError("amended by: a confirmed review names no amendment")
                if certificate.state != "issued":
                    raise RecordsError(
                        f"number: {number} is {certificate.state}, not in force; a review is "
                        "confirmed only for a certificate that stands"
                    )
            else:
                amended_by = self._check_amendment(s, certificate, amended_by)
            now = datetime.now(UTC)
            for row in rows:
                row.outcome, row.closed_utc = outcome, now
                row.closed_by, row.close_reason, row.amended_by = self.actor, reason, amended_by
            s.flush()
            return [as_review(r) for r in rows]

    @staticmethod
    def _check_amendment(s: Session, certificate: Certificate, amended_by: str | None) -> str:
        """`amended_by` when it is a certificate of the same sensor that replaces
        `certificate` and is not withdrawn; RecordsError naming why otherwise."""
        number = certificate.number
        if amended_by is None or not amended_by.strip():
            raise RecordsError("amended by: an amended review names the amendment's number")
        amended_by = amended_by.strip()
        new = s.scalar(select(Certificate).where(Certificate.number == amended_by))
        if new is None:
            raise RecordsError(f"amended by: no certificate {amended_by!r}")
        if new.replaces != number:
            replaced = f"replaces {new.replaces}" if new.replaces else "replaces none"
            raise RecordsError(f"amended by: {amended_by} {replaced}, not {number}")
        if new.sensor_id != certificate.sensor_id:
            raise RecordsError(f"amended by: {amended_by} is a certificate of another sensor")
        if new.state == "withdrawn":
            raise RecordsError(f"amended by: {amended_by} is withdrawn")
        return amended_by

    def reviews(self, *, open_only: bool = False, number: str | None = None) -> list[Review]:
        """Every review (or only the open ones; only those of certificate `number` when
        given), oldest first."""
        with self.session() as s:
            query = select(CertificateReview).options(joinedload(CertificateReview.certificate))
            if open_only:
                query = query.where(CertificateReview.outcome.is_(None))
            if number is not None:
                query = query.join(
                    Certificate, CertificateReview.certificate_id == Certificate.id
                ).where(Certificate.number == number)
            rows = s.scalars(query.order_by(CertificateReview.opened_utc, CertificateReview.id))
            return [as_review(r) for r in rows]
