"""Certificates under review (ISO/IEC 17025 7.10) and the runs a review looks at: the indexed
runs in a time window with their certificates and owners, and the review flag itself (opened
with a subject and reason, closed as amended or confirmed), every write audited.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import select
from sqlalchemy.orm import joinedload

from app.records.db.models import Certificate, CertificateReview, Run, Sensor
from app.records.db.store import RecordsError, Store, text_field, utc

OUTCOMES = ("amended", "confirmed")


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
    """One review of a certificate: subject, reason, opened (UTC), outcome when closed."""

    number: str
    subject: str
    reason: str
    opened_utc: datetime
    outcome: str | None
    closed_utc: datetime | None


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

    def close_review(self, number: str, *, subject: str, outcome: str) -> None:
        """Close the open review of `number` for `subject` as amended or confirmed."""
        if outcome not in OUTCOMES:
            raise RecordsError(f"outcome: must be one of {', '.join(OUTCOMES)}, got {outcome!r}")
        with self.session() as s:
            review = s.scalar(
                select(CertificateReview)
                .join(Certificate, CertificateReview.certificate_id == Certificate.id)
                .where(
                    Certificate.number == number,
                    CertificateReview.subject == subject,
                    CertificateReview.outcome.is_(None),
                )
            )
            if review is None:
                raise RecordsError(f"number: {number} has no open review for {subject!r}")
            review.outcome, review.closed_utc = outcome, datetime.now(UTC)

    def reviews(self, *, open_only: bool = False) -> list[Review]:
        """Every review (or only the open ones), oldest first."""
        with self.session() as s:
            query = select(CertificateReview).options(joinedload(CertificateReview.certificate))
            if open_only:
                query = query.where(CertificateReview.outcome.is_(None))
            rows = s.scalars(query.order_by(CertificateReview.opened_utc, CertificateReview.id))
            return [
                Review(
                    r.certificate.number,
                    r.subject,
                    r.reason,
                    utc(r.opened_utc),
                    r.outcome,
                    None if r.closed_utc is None else utc(r.closed_utc),
                )
                for r in rows
            ]
