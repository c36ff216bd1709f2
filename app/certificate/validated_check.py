"""Proving a software validation report (issue 33 point 4), and what a certificate PDF states
about its report.

A report proves itself (`read_report`) only as one signed PDF made by `accelcal validate
--sign`: its record (date, software, every case with its result) embedded as
REPORT_ATTACHMENT and the lab's PAdES signature over the whole file, checked as `accelcal
verify` checks a certificate's (app.certificate.verify). It is accepted only when that
signature is intact and its signer is trusted by the given trust anchors (the lab's CA or its
own signing key), the record names the expected software's SHA-256, every case passed, and its
date is not in the future. A JSON file beside it is a readable copy and is never read here.
A certificate states the report PDF's SHA-256 and the software's in its embedded DCC's
"Software validation" statement, read inertly (app.certificate.readback), which `accelcal
verify --validation-report` recomputes and proves (`verify_report`).
"""

from __future__ import annotations

import hashlib
import io
import json
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.certificate.dcc import DCC_NS
from app.certificate.readback import PrintedError, parse_inert
from app.certificate.validated import (
    CLOCK_SKEW,
    MAX_REPORT_BYTES,
    MAX_REPORTS,
    REPORT_ATTACHMENT,
    STATEMENT_NAME,
    ValidationClaim,
    ValidationClaimError,
    software_identity,
    validation_folder,
)

_HEX64 = re.compile(r"^[0-9a-f]{64}$")
_STATED = re.compile(r"report PDF's SHA-256 is ([0-9a-f]{64})")
_SOFTWARE = re.compile(r"files SHA-256 ([0-9a-f]{64})\)")


@dataclass(frozen=True)
class StatedValidation:
    """What a certificate states about its validation report: the report PDF's SHA-256 and
    the SHA-256 of the software it says was validated (None in statements made before the
    report was signed)."""

    report_sha256: str
    software_sha256: str | None


def stated_report_sha256(pdf: Path) -> str | None:
    """The validation report's SHA-256 a certificate PDF states in its embedded DCC, or None
    when it names no validation report (see `stated_validation`)."""
    stated = stated_validation(pdf)
    return None if stated is None else stated.report_sha256


def stated_validation(pdf: Path) -> StatedValidation | None:
    """The validation report a certificate PDF states in its embedded DCC (read inertly,
    app.certificate.readback), or None when it names no validation report; `pdf` may be the
    DCC alone (.xml). ValidationClaimError when the PDF holds no single readable DCC."""
    from pypdf import PdfReader
    from pypdf.errors import PyPdfError

    try:
        if pdf.suffix.lower() == ".xml":  # a DCC given alone (issue 35)
            xml_list = [pdf.read_bytes()]
        else:
            xml_list = list(PdfReader(pdf).attachments.get("certificate.xml") or [])
    except (OSError, PyPdfError, ValueError) as exc:
        raise ValidationClaimError(f"{pdf}: not a readable PDF ({exc})") from None
    if len(xml_list) != 1:
        raise ValidationClaimError(f"{pdf}: no single certificate.xml attached")
    try:
        root = parse_inert(xml_list[0])
    except PrintedError as exc:
        raise ValidationClaimError(f"{pdf}: embedded DCC: {exc}") from None
    path = "//dcc:statement[dcc:name/dcc:content=$name]/dcc:declaration/dcc:content/text()"
    found = root.xpath(path, namespaces={"dcc": DCC_NS}, name=STATEMENT_NAME)
    for text in found:
        line = " ".join(str(text).split())
        match = _STATED.search(line)
        if match:
            software = _SOFTWARE.search(line)
            return StatedValidation(match.group(1), software.group(1) if software else None)
    return None


# --- trust anchors ------------------------------------------------------------------------------


def trust_from_ca(path: Path) -> list[Any]:
    """The CA certificate (PEM or DER) in `path` as a trust anchor; ValidationClaimError
    naming --trust when it is no certificate."""
    from app.certificate.verify import VerifyRefusal, _load_certificate

    try:
        return [_load_certificate(path)]
    except VerifyRefusal as exc:
        raise ValidationClaimError(str(exc)) from None


def trust_from_signer(signer: Any) -> list[Any]:
    """The lab's own signing key as trust anchors: its certificate and the CA certificates its
    PKCS#12 file carries (a report signed with the lab's key, or another key of its CA)."""
    inner = signer.signer
    anchors = [inner.signing_cert]
    anchors += [c for c in (inner.cert_registry or []) if c != inner.signing_cert]
    return anchors


# --- reading a report ---------------------------------------------------------------------------


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _record(data: bytes, name: str) -> dict[str, Any]:
    """The signed record embedded in a report PDF (after its signature held)."""
    from pypdf import PdfReader
    from pypdf.errors import PyPdfError

    try:
        found = list(PdfReader(io.BytesIO(data)).attachments.get(REPORT_ATTACHMENT) or [])
    except (OSError, PyPdfError, ValueError, KeyError, TypeError) as exc:
        raise ValidationClaimError(f"{name}: the PDF cannot be read ({exc})") from None
    if len(found) != 1:
        raise ValidationClaimError(
            f"{name}: no single {REPORT_ATTACHMENT} inside: not a report made by "
            "`accelcal validate`"
        )
    try:
        record = json.loads(found[0].decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise ValidationClaimError(f"{name}: {REPORT_ATTACHMENT}: not JSON ({exc})") from None
    if not isinstance(record, dict):
        raise ValidationClaimError(f"{name}: {REPORT_ATTACHMENT}: not a JSON object")
    return record


def _parse_date(text: Any, name: str) -> datetime:
    try:
        when = datetime.fromisoformat(str(text))
    except ValueError:
        raise ValidationClaimError(f"{name}: date {text!r} is not an ISO 8601 time") from None
    if when.tzinfo is None:
        raise ValidationClaimError(f"{name}: date {text!r} has no time zone")
    return when.astimezone(UTC)


def read_report(
    path: Path, trust: list[Any] | None, software_sha256: str, now: datetime | None = None
) -> ValidationClaim:
    """The claim of the report PDF `path` when it proves itself (see the module's docstring)
    for the software `software_sha256`; ValidationClaimError naming the report and the first
    thing found wrong otherwise: not signed, signature not intact, signer not trusted (or
    nothing to trust: `trust` None), no record inside, another software's hash, a failed or
    missing case, a date in the future."""
    from app.certificate.verify import (
        TIME_LIMIT_S,
        Verification,
        VerifyRefusal,
        _check_signature,
        _quiet,
        _time_limit,
    )
    from app.io.checks import InputFileError, read_regular_bytes

    name = Path(path).name
    try:
        data = read_regular_bytes(path, MAX_REPORT_BYTES, "validation report")
    except InputFileError as exc:
        raise ValidationClaimError(str(exc)) from None
    checks = Verification()
    try:
        with _quiet(), _time_limit(TIME_LIMIT_S):
            _check_signature(data, trust, checks)
    except VerifyRefusal as exc:  # a file made to keep the check busy
        raise ValidationClaimError(f"{name}: signature: {exc}") from None
    failed = next(((n, d) for n, ok, d in checks.checks if not ok), None)
    if failed is not None or not checks.checks:
        what, detail = failed or ("signature", "not checked")
        if trust is None and what == "signer trust":
            detail = "signer NOT checked: no lab key or CA to check it against"
        elif what == "signer trusted by the given CA":
            what, detail = "signer", f"{detail} trusted by the lab's key or CA: not trusted"
        raise ValidationClaimError(f"{name}: {what}: {detail}")
    signer = _signer_subject(data)
    record = _record(data, name)
    software = record.get("software")
    if not isinstance(software, dict) or not _HEX64.match(str(software.get("sha256", ""))):
        raise ValidationClaimError(f"{name}: the record names no software SHA-256")
    if software["sha256"] != software_sha256:
        raise ValidationClaimError(
            f"{name}: validates software {software['sha256']}, not this software "
            f"({software_sha256})"
        )
    cases = record.get("cases")
    if not isinstance(cases, list) or not cases:
        raise ValidationClaimError(f"{name}: the record lists no cases")
    failed_cases = [
        str(c.get("name", "?")) if isinstance(c, dict) else "?"
        for c in cases
        if not isinstance(c, dict) or c.get("passed") is not True
    ]
    if failed_cases or record.get("passed") is not True:
        raise ValidationClaimError(
            f"{name}: not every case passed ({len(failed_cases)} of {len(cases)} failed: "
            f"{', '.join(failed_cases[:3])})"
        )
    when = _parse_date(record.get("date_utc"), name)
    now = now or datetime.now(UTC)
    if when > now + CLOCK_SKEW:
        raise ValidationClaimError(
            f"{name}: dated {when:%Y-%m-%d %H:%M} UTC, in the future (now {now:%Y-%m-%d %H:%M} UTC)"
        )
    return ValidationClaim(
        name,
        when.isoformat(timespec="seconds"),
        hashlib.sha256(data).hexdigest(),
        str(software.get("version") or ""),
        software_sha256,
        len(cases),
        signer,
    )


def _signer_subject(data: bytes) -> str:
    """The report signer's subject (its signature already checked)."""
    from pyhanko.pdf_utils.reader import PdfFileReader

    from app.certificate.verify import SignerInfo

    signatures = PdfFileReader(io.BytesIO(data), strict=False).embedded_signatures
    return SignerInfo.of(signatures[-1].signer_cert).subject


@dataclass(frozen=True)
class FolderClaim:
    """What a validation folder offers: the claim of its newest report that proves itself
    (None: none does) and, for each report refused, why (one line each)."""

    claim: ValidationClaim | None
    refused: tuple[str, ...] = ()

    def summary(self) -> str:
        """One line for the faces: the report named, or why none is."""
        if self.claim is not None:
            return (
                f"software validation: report {self.claim.report} of "
                f"{self.claim.date_utc[:10]} (signed by {self.claim.signer}) named"
            )
        why = "; ".join(self.refused) or "no report in the lab's validation folder"
        return f"software validation: no report named ({why})"


def folder_claim(
    folder: Path, trust: list[Any] | None, software_sha256: str, now: datetime | None = None
) -> FolderClaim:
    """The newest report PDF in `folder` that proves itself for `software_sha256` (by its
    signed date), and why each other one examined was refused. Without `trust` nothing is
    accepted: the refusal says so."""
    folder = Path(folder)
    if not folder.is_dir():
        return FolderClaim(None, (f"no validation folder {folder}",))
    pdfs = sorted(
        (p for p in folder.glob("*.pdf") if not p.is_symlink() and p.is_file()),
        key=lambda p: p.name,
    )[-MAX_REPORTS:]
    if trust is None:
        if not pdfs:
            return FolderClaim(None, (f"no report in {folder}",))
        return FolderClaim(
            None,
            (
                "no lab key to check a report's signature against: issue with --sign (the "
                "lab's key) or --trust (its CA certificate)",
            ),
        )
    accepted: list[ValidationClaim] = []
    refused: list[str] = []
    for pdf in pdfs:
        try:
            accepted.append(read_report(pdf, trust, software_sha256, now))
        except ValidationClaimError as exc:
            refused.append(str(exc))
    if not pdfs:
        refused.append(f"no report in {folder}")
    best = max(accepted, key=lambda c: c.date_utc) if accepted else None
    return FolderClaim(best, tuple(refused))


def current_claim(trust: list[Any] | None) -> FolderClaim:
    """What the lab's validation folder offers the installed software, checked against
    `trust` (app.certificate.service passes the lab's key or CA; None accepts nothing)."""
    return folder_claim(validation_folder(), trust, software_identity().sha256)


def verify_report(
    stated_sha256: str,
    report: Path,
    trust: list[Any] | None = None,
    stated_software: str | None = None,
) -> ValidationClaim | None:
    """ValidationClaimError unless `report`'s SHA-256 is the one a certificate states and, with
    `stated_software` (the software SHA-256 the certificate states), unless the report proves
    itself for that software against `trust` (read_report). The report's claim, or None when
    only its hash was compared."""
    if not report.is_file():
        raise ValidationClaimError(f"--validation-report: no such file {report}")
    actual = _sha256(report)
    if actual != stated_sha256.strip().lower():
        raise ValidationClaimError(
            f"--validation-report: {report} has SHA-256 {actual}, the certificate names "
            f"{stated_sha256}"
        )
    if stated_software is None:
        return None
    try:
        return read_report(report, trust, stated_software)
    except ValidationClaimError as exc:
        raise ValidationClaimError(f"--validation-report: {exc}") from None
