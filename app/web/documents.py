"""A certificate's documents on the lab's disk: its PDF, found through the certificate register
of the run's runs root (app.records.register), its DCC (the XML attached to the PDF) and the
verification of both (app.certificate.sign.verify). Nothing is served unless it checks out:
the register's entry names this number and run, the file is a PDF whose SHA-256 is the one
the register recorded when it was issued.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from app.records.register import RegisterError, read_register
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


def certificate_pdf(number: str, run_id: str, run_folder: str) -> Path:
    """The PDF of certificate `number` of run `run_id`, checked against its register entry
    (same run, same SHA-256 as when issued, a PDF); DocumentError saying why not."""
    root = Path(run_folder).parent
    try:
        entries = read_register(root)
    except RegisterError as exc:
        raise DocumentError(str(exc)) from None
    entry = next((e for e in entries if e.number == number), None)
    if entry is None:
        raise DocumentError(f"certificate {number}: not in the register of {root}")
    if entry.run_id != run_id:
        raise DocumentError(f"certificate {number}: the register names run {entry.run_id}")
    path = Path(entry.file)
    if path.suffix.lower() != ".pdf" or not path.is_file():
        raise DocumentError(f"certificate {number}: its PDF {path} is missing")
    with path.open("rb") as handle:
        if handle.read(len(PDF_MAGIC)) != PDF_MAGIC:
            raise DocumentError(f"certificate {number}: {path} is not a PDF")
    if sha256_of(path) != entry.sha256:
        raise DocumentError(f"certificate {number}: {path} changed since it was issued")
    return path


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


def verify_certificate(
    number: str, pdf: Path, run_folder: str, trust: Path | None = None
) -> list[CheckLine]:
    """Every check of `accelcal verify` on `pdf` with its run folder (and the lab's CA
    certificate `trust`, when given), and that the DCC in the PDF is certificate `number`."""
    from app.certificate.readback import items_from_dcc, parse_inert
    from app.certificate.verify import verify

    report = verify(pdf, Path(run_folder), trust)
    lines = [CheckLine(name, ok, detail) for name, ok, detail in report.checks]
    try:
        found = items_from_dcc(parse_inert(embedded_dcc(pdf))).number
    except (DocumentError, ValueError) as exc:
        lines.append(CheckLine(f"the PDF is certificate {number}", False, str(exc)))
    else:
        lines.append(
            CheckLine(f"the PDF is certificate {number}", found == number, f"DCC names {found}")
        )
    return lines
