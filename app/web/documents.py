"""A certificate's documents on the lab's disk: its PDF, at the path its row of the records'
register names (app.records.db.models.Certificate.file), its DCC (the XML attached to the PDF)
and the verification of both (app.certificate.sign.verify). Nothing is served unless it checks
out: the file is a PDF whose SHA-256 is the one the register recorded when it was issued, the
DCC's SHA-256 likewise.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from app.records.run_folder import sha256_of

PDF_MAGIC = b"%PDF-"


class DocumentError(LookupError):
    """A certificate's document that cannot be served; the message says why."""


@dataclass(frozen=True)
class CheckLine:
    """One line of a verification: what was checked, its outcome and the detail."""

    name: str
    ok: bool
    detail: str
    shown: str = ""  # the outcome's word when not "pass"/"FAIL" ("not signed": the lab's policy)


UNSIGNED_DETAIL = "the PDF is not signed: nothing proves who issued it"  # accelcal verify's
NOT_SIGNED_BY_POLICY = (
    "not signed, by the laboratory's policy (the web view names no laboratory CA: --trust); the "
    "other checks prove the document is the one in the register"
)


def _policy(line: CheckLine, trust: Path | None) -> CheckLine:
    """A lab that does not sign (no CA given to the web view) sees its unsigned certificates
    as "not signed, by the laboratory's policy", not as a failure; with a CA an unsigned PDF
    stays a failure. So does the DCC's own signature (app.certificate.dcc_sign)."""
    from app.certificate import dcc_sign

    unsigned = not line.ok and (
        (line.name == "signature" and line.detail == UNSIGNED_DETAIL)
        or (line.name == dcc_sign.CHECK and line.detail == dcc_sign.UNSIGNED_DETAIL)
    )
    if trust is None and unsigned:
        return CheckLine(line.name, True, NOT_SIGNED_BY_POLICY, shown="not signed")
    return line


def printed_verification_address(number: str, run_folder: str) -> str | None:
    """The verification address page 1 of certificate `number` printed under its QR code (the
    run's [laboratory] verify_url, as the PDF was drawn: app.certificate.pdf.verification_qr);
    None when it printed none. DocumentError when the run cannot be read."""
    from app.certificate.load import load_stored_run
    from app.certificate.qr import verification_address

    try:
        run = load_stored_run(Path(run_folder))
    except (ValueError, OSError) as exc:
        raise DocumentError(f"run folder {run_folder}: {exc}") from None
    return verification_address(run, number)


def certificate_pdf(number: str, file: str | None, sha256: str | None) -> Path:
    """The PDF of certificate `number` at `file` (the absolute path its register row names),
    checked: a PDF whose SHA-256 is `sha256`, the one the row recorded when it was issued;
    DocumentError saying why not."""
    if not file or not sha256:
        raise DocumentError(f"certificate {number}: the register records no issued PDF")
    path = Path(file)
    if not path.is_absolute() or path.suffix.lower() != ".pdf" or not path.is_file():
        raise DocumentError(f"certificate {number}: its PDF {path} is missing")
    with path.open("rb") as handle:
        if handle.read(len(PDF_MAGIC)) != PDF_MAGIC:
            raise DocumentError(f"certificate {number}: {path} is not a PDF")
    if sha256_of(path) != sha256.lower():
        raise DocumentError(f"certificate {number}: {path} changed since it was issued")
    return path


def certificate_pdf_bytes(number: str, file: str | None, sha256: str | None) -> bytes:
    """The bytes of certificate `number`'s checked PDF (certificate_pdf), checked again as
    read, so what is served is what was hashed; DocumentError saying why not."""
    data = certificate_pdf(number, file, sha256).read_bytes()
    if not data.startswith(PDF_MAGIC) or hashlib.sha256(data).hexdigest() != str(sha256).lower():
        raise DocumentError(f"certificate {number}: {file} changed since it was issued")
    return data


def embedded_dcc(pdf: Path) -> bytes:
    """The digital calibration certificate attached to `pdf` (certificate.xml)."""
    from pypdf import PdfReader

    try:
        attachments = PdfReader(str(pdf)).attachments
    except Exception as exc:  # a damaged PDF
        raise DocumentError(f"{pdf.name}: unreadable ({exc})") from None
    found = attachments.get("certificate.xml") or []
    if len(found) != 1:
        raise DocumentError(f"{pdf.name}: carries no digital calibration certificate")
    return bytes(found[0])


def certificate_dcc(number: str, pdf: Path, dcc_sha256: str | None) -> bytes:
    """The DCC of certificate `number`: the one attached to its checked `pdf`, served only
    when its SHA-256 is `dcc_sha256`, the one the register recorded; DocumentError if not."""
    if not dcc_sha256:
        raise DocumentError(f"certificate {number}: the register records no DCC")
    data = embedded_dcc(pdf)
    if hashlib.sha256(data).hexdigest() != dcc_sha256.lower():
        raise DocumentError(f"certificate {number}: its DCC is not the one issued")
    return data


def verify_certificate(
    number: str, pdf: Path, run_folder: str, trust: Path | None = None
) -> list[CheckLine]:
    """Every check of `accelcal verify` on `pdf` with its run folder (and the lab's CA
    certificate `trust`, when given), and that the DCC in the PDF is certificate `number`."""
    from app.certificate.readback import items_from_dcc, parse_inert
    from app.certificate.verify import verify

    report = verify(pdf, Path(run_folder), trust)
    lines = [_policy(CheckLine(name, ok, detail), trust) for name, ok, detail in report.checks]
    try:
        found = items_from_dcc(parse_inert(embedded_dcc(pdf))).number
    except (DocumentError, ValueError) as exc:
        lines.append(CheckLine(f"the PDF is certificate {number}", False, str(exc)))
    else:
        lines.append(
            CheckLine(f"the PDF is certificate {number}", found == number, f"DCC names {found}")
        )
    return lines
