"""`accelcal verify`: check a certificate PDF and trust nothing it claims about itself.

In order, each a line of the report: the file (a regular file of at most MAX_PDF_BYTES, read
once); the signature's byte layout, parsed from the bytes (app.certificate.pdf_signature: the
signed range covers the whole file but exactly its /Contents hex string, no revision after it,
no earlier signature); the signature's cryptography (pyHanko); the signer, always named with
its issuer and validity, valid now, and trusted only when `--trust` names its CA (without it
the report never says verified); the embedded DCC's own signature (enveloped XAdES, by the
PDF's signer, trusted by `--trust`: app.certificate.dcc_sign); the embedded DCC, parsed as
bytes by an inert parser and valid against DCC 3.3.0; the PDF's printed items, read from its
marked text layer (app.certificate.pdf_marks: delimiters the writer places as PDF operators,
never text), equal to the DCC's, value by value; with `--run`, the run's manifest, its seal
(recomputed) and the records chain head it names, its results equal to the DCC's, and the PDF's
results table equal, cell by cell, to the run's lines as printed
(app.certificate.printed.table_cells, from which the PDF was drawn); with the records in use,
the register's word (app.certificate.register_status: the file issued, in force, not replaced
or withdrawn, its amendment as entered). A DCC given alone (.xml) is checked the same way but
for the PDF: its signature, its validity, the run's checks and the register's (its SHA-256
against the DCC issued). The whole check is bounded in time (TIME_LIMIT_S).
"""

from __future__ import annotations

import contextlib
import io
import logging
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from app.certificate import CertificateError
from app.certificate.pdf_marks import MarkError, PageMarks, read_marks
from app.certificate.pdf_signature import SignatureStructureError, check_layout
from app.certificate.printed import Column, PrintedLine, printed_lines, table_cells
from app.certificate.readback import (
    PrintedError,
    PrintedItems,
    differences,
    items_from_dcc,
    items_from_pdf,
    parse_inert,
    rows_of,
)
from app.io.checks import MIB, InputFileError, read_regular_bytes

MAX_PDF_BYTES = 50 * MIB
MAX_TRUST_BYTES = 1 * MIB
TIME_LIMIT_S = 30.0
_QUIET = ("pyhanko", "pyhanko_certvalidator", "pypdf", "xmlschema")


class VerifyRefusal(CertificateError):
    """An input `verify` does not examine (too large, not a regular file, too slow)."""


@dataclass
class Verification:
    """What `accelcal verify` found: each check with its outcome and detail, in order."""

    checks: list[tuple[str, bool, str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # shown beside the checks, not one of them
    pdf_signer: bytes = field(default=b"", repr=False)  # the PDF signer's certificate (DER)

    def add(self, name: str, ok: bool, detail: str = "") -> None:
        self.checks.append((name, ok, _one_line(detail)))

    @property
    def ok(self) -> bool:
        return bool(self.checks) and all(ok for _, ok, _ in self.checks)

    def lines(self) -> list[str]:
        """The report as printed: one line per check, then the outcome (with the first
        failure)."""
        out = [f"{'ok  ' if ok else 'FAIL'} {name}" + (f": {d}" if d else "") for name, ok, d in
               self.checks]  # fmt: skip
        failed = next(((n, d) for n, ok, d in self.checks if not ok), None)
        if failed is None and self.ok:
            out.append("certificate verified")
        else:
            name, detail = failed or ("nothing checked", "")
            out.append(f"certificate NOT verified: {name}" + (f": {detail}" if detail else ""))
        return out


def _one_line(text: str, limit: int = 300) -> str:
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 3] + "..."


@dataclass(frozen=True)
class SignerInfo:
    """The signer's certificate as shown: subject, issuer and validity (UTC)."""

    subject: str
    issuer: str
    not_before: datetime
    not_after: datetime

    @classmethod
    def of(cls, cert: Any) -> SignerInfo:
        """From an asn1crypto x509.Certificate."""
        validity = cert["tbs_certificate"]["validity"]
        return cls(
            str(cert.subject.human_friendly),
            str(cert.issuer.human_friendly),
            validity["not_before"].native,
            validity["not_after"].native,
        )

    def describe(self) -> str:
        return (
            f"{self.subject}, issued by {self.issuer}, valid "
            f"{self.not_before:%Y-%m-%d %H:%M} to {self.not_after:%Y-%m-%d %H:%M} UTC"
        )

    def validity_problem(self, now: datetime | None = None) -> str | None:
        """Why the certificate is not valid at `now` (default: the current time), or None."""
        now = now or datetime.now(UTC)
        if now < self.not_before:
            return f"not valid before {self.not_before:%Y-%m-%d %H:%M} UTC"
        if now > self.not_after:
            return f"expired on {self.not_after:%Y-%m-%d %H:%M} UTC"
        return None


def verify(
    pdf: Path, run: Path | None = None, trust: Path | None = None, records: str | None = None
) -> Verification:
    """Check the certificate `pdf` (with the run folder `run`, the CA certificate `trust`,
    PEM or DER, and the records' register at the URL `records`, when given: whether it is the
    file issued and still in force, app.certificate.register_status). VerifyRefusal for an
    input that is not examined at all."""
    roots = [_load_certificate(trust)] if trust is not None else None
    try:
        data = read_regular_bytes(pdf, MAX_PDF_BYTES, "certificate PDF", follow_links=True)
    except InputFileError as exc:
        raise VerifyRefusal(str(exc)) from None
    report = Verification()
    with _quiet(), _time_limit(TIME_LIMIT_S):
        if _is_dcc(pdf, data):  # a DCC given alone (issue 35): its own signature proves it
            _verify_dcc(data, run, roots, records, report)
            return report
        if not _check_signature(data, roots, report):
            return report  # nothing an unproven file says is worth parsing further
        found = _check_dcc(data, report, roots)
        if found is not None and run is not None:
            _check_run(run, *found, report)
        if found is not None and records is not None:
            _check_register(data, found[0], records, report)
    return report


def _is_dcc(path: Path, data: bytes) -> bool:
    """True for a DCC file (.xml, or bytes that open as XML), not a PDF."""
    return path.suffix.lower() == ".xml" or data.lstrip()[:1] == b"<"


def _verify_dcc(
    data: bytes, run: Path | None, roots: list[Any] | None, records: str | None,
    report: Verification,
) -> None:  # fmt: skip
    """A DCC given alone: its signature (app.certificate.dcc_sign), its validity, and with
    `run` and `records` the run's and the register's checks as for a PDF (no PDF table)."""
    try:
        root = parse_inert(data)
    except PrintedError as exc:
        report.add("DCC readable", False, str(exc))
        return
    from app.certificate.dcc_sign import CHECK

    report.add(CHECK, *_dcc_signature(data, roots))
    from lxml import etree

    from app.certificate.dcc import validation_error

    problem = validation_error(etree.tostring(root, encoding="utf-8", xml_declaration=True))
    report.add("DCC valid (DCC 3.3.0)", problem is None, problem or "")
    dcc = items_from_dcc(root)
    if run is not None:
        _check_run(run, dcc, None, report)
    if records is not None:
        _check_register(data, dcc, records, report, of_dcc=True)


def _check_register(
    data: bytes, printed: PrintedItems, url: str, report: Verification, of_dcc: bool = False
) -> None:
    """Add the register's check (app.certificate.register_status), or a note when the records
    cannot be opened."""
    from app.certificate.register_status import CHECK, RecordsUnavailable, register_findings

    try:
        report.add(CHECK, *register_findings(data, printed, url, of_dcc))
    except RecordsUnavailable as exc:
        report.notes.append(f"register: not consulted: {exc}")


# --- signature --------------------------------------------------------------------------------


def _check_signature(data: bytes, roots: list[Any] | None, report: Verification) -> bool:
    """Add the signature's checks; False when the file is not a PDF or claims a signature whose
    layout is not proven (nothing it says is parsed further). An unsigned PDF fails the
    signature check but its DCC and run are still compared (the report stays NOT verified)."""
    if not data.startswith(b"%PDF-") or b"%%EOF" not in data[-1024:]:
        report.add("signature", False, "not a PDF file (no %PDF- header or %%EOF marker)")
        return False
    if b"/ByteRange" not in data and b"/Sig" not in data:
        report.add("signature", False, "the PDF is not signed: nothing proves who issued it")
        return True
    name = "signature intact, covering the whole file"
    try:
        layout = check_layout(data)  # from the bytes, before any parser reads the file
    except SignatureStructureError as exc:
        report.add(name, False, str(exc))
        return False
    try:
        from pyhanko.pdf_utils.reader import PdfFileReader

        signatures = PdfFileReader(io.BytesIO(data), strict=False).embedded_signatures
    except Exception as exc:  # pyHanko's reader fails in many ways on a damaged file
        report.add("signature", False, f"cannot be read ({exc})")
        return False
    if not signatures:
        report.add("signature", False, "the PDF has no signature field")
        return False
    sig = max(signatures, key=lambda s: _end(s.byte_range))
    try:
        layout.check_is([int(v) for v in sig.byte_range], sig.pkcs7_content)
        layout.check_contents(data)
    except (SignatureStructureError, TypeError, ValueError) as exc:
        report.add(name, False, str(exc))
        return False
    signer = SignerInfo.of(sig.signer_cert)
    report.pdf_signer = sig.signer_cert.dump()
    status = _validate(sig, roots)
    intact = bool(status is not None and status.intact and status.valid)
    report.add(
        name,
        intact,
        "" if intact else "the signed bytes or the signature do not match",
    )
    for earlier in layout.earlier:
        report.add("no earlier signature", False, earlier.describe())
    problem = signer.validity_problem()
    report.add(f"signer: {signer.describe()}", problem is None, problem or "")
    if roots is None:
        report.add(
            "signer trust",
            False,
            f"signature {'intact' if intact else 'NOT intact'}, signer NOT checked: "
            f"{signer.describe()} (give --trust with the laboratory's CA certificate)",
        )
    else:
        trusted = bool(status is not None and status.trusted)
        report.add(
            "signer trusted by the given CA",
            trusted,
            "" if trusted else f"{signer.subject} (issuer {signer.issuer}) is not",
        )
    return intact


def _end(byte_range: Any) -> int:
    try:
        return int(byte_range[2]) + int(byte_range[3])
    except (IndexError, TypeError, ValueError):
        return -1


def _validate(sig: Any, roots: list[Any] | None) -> Any:
    """pyHanko's status of `sig` (its digest, signature and, with `roots`, its chain), or None
    when it cannot be evaluated."""
    from pyhanko.sign.validation import validate_pdf_signature
    from pyhanko_certvalidator import ValidationContext

    context = ValidationContext(trust_roots=roots or [], allow_fetching=False)
    try:
        return validate_pdf_signature(sig, context, skip_diff=True)
    except Exception:  # a damaged CMS structure: reported as not intact
        return None


def _load_certificate(path: Path) -> Any:
    from asn1crypto import pem, x509

    try:
        data = read_regular_bytes(path, MAX_TRUST_BYTES, "CA certificate", follow_links=True)
        if pem.detect(data):
            _, _, data = pem.unarmor(data)
        cert = x509.Certificate.load(data)
        cert.native  # noqa: B018 - parses every field now, so a damaged one fails here
    except InputFileError as exc:
        raise VerifyRefusal(f"--trust: {exc}") from None
    except (ValueError, TypeError) as exc:
        raise VerifyRefusal(f"--trust: {path}: not a certificate (PEM or DER): {exc}") from None
    return cert


# --- DCC and printed items --------------------------------------------------------------------


def _check_dcc(
    data: bytes, report: Verification, roots: list[Any] | None = None
) -> tuple[PrintedItems, PageMarks] | None:
    """Add the DCC's checks (its own signature first: app.certificate.dcc_sign); the DCC's
    printed items and the PDF's marked text layer, or None when the DCC cannot be read."""
    from pypdf import PdfReader

    try:
        xml_list = list(PdfReader(io.BytesIO(data)).attachments.get("certificate.xml") or [])
    except Exception as exc:  # pypdf fails in many ways on a damaged file
        report.add("PDF readable", False, str(exc))
        return None
    if len(xml_list) != 1:
        report.add("embedded DCC", False, "no single certificate.xml attached")
        return None
    try:
        root = parse_inert(xml_list[0])
    except PrintedError as exc:
        report.add("embedded DCC readable", False, str(exc))
        return None
    from app.certificate.dcc_sign import CHECK  # a DCC read inertly first: its own signature

    report.add(CHECK, *_dcc_signature(bytes(xml_list[0]), roots, report.pdf_signer))
    from lxml import etree

    from app.certificate.dcc import validation_error

    problem = validation_error(etree.tostring(root, encoding="utf-8", xml_declaration=True))
    report.add("embedded DCC valid (DCC 3.3.0)", problem is None, problem or "")
    dcc = items_from_dcc(root)
    name = "DCC numbers printed in the PDF"
    try:
        marks = read_marks(data)
    except MarkError as exc:
        report.add(name, False, f"its marked text layer is not readable: {exc}")
        return dcc, PageMarks()
    except Exception as exc:  # pypdf fails in many ways on a damaged file
        report.add(name, False, f"its pages cannot be read: {exc}")
        return dcc, PageMarks()
    if not marks.items and not marks.cells:
        report.add(name, False, "the PDF has no marked text layer (drawn before certificates "
                   "had one, app.certificate.pdf_marks): its printed items cannot be read; the "
                   "DCC is still checked against the run")  # fmt: skip
        return dcc, marks
    diff = differences(dcc, items_from_pdf(marks), "DCC", "PDF")
    if not dcc.lines:
        diff.insert(0, "the DCC states no result lines")
    report.add(name, not diff, "; ".join(diff[:3]))
    return dcc, marks


COVERED_BY_PDF = (
    "not signed itself (issued before DCCs were signed): the PDF's signature covers it, but "
    "taken out of this PDF it proves nothing"
)


def _dcc_signature(
    xml: bytes, roots: list[Any] | None, pdf_signer_der: bytes = b""
) -> tuple[bool, str]:
    """(ok, detail) of the DCC's own signature (app.certificate.dcc_sign): not signed (a
    failure, worded as the PDF's), not intact, signed by another than the PDF's signer (when
    the PDF is signed: `pdf_signer_der`), not valid now, not trusted by the given CA (`roots`);
    else ok, naming the signer (and, without a CA, that it is not checked). An unsigned DCC
    inside a signed PDF is ok: the PAdES signature covers it."""
    from asn1crypto import x509 as asn1_x509

    from app.certificate.dcc_sign import check_dcc_signature

    status = check_dcc_signature(xml, roots)
    if not status.signed and pdf_signer_der:  # inside an intact signed PDF (issued before
        return True, COVERED_BY_PDF  # DCCs were signed): the PDF's signature covers it
    if not status.signed or not status.intact:
        return False, status.detail
    signer = SignerInfo.of(asn1_x509.Certificate.load(status.certificate_der))
    who = signer.describe()
    if pdf_signer_der and status.certificate_der != pdf_signer_der:
        return False, f"signed by {who}, not by the PDF's signer"
    problem = signer.validity_problem()
    if problem is not None:
        return False, f"intact, but its signer's certificate is {problem} ({who})"
    if status.trusted is None:
        return True, f"intact, signed by {who}; signer NOT checked (give --trust)"
    if not status.trusted:
        return False, f"intact, but {signer.subject} (issuer {signer.issuer}) is not trusted"
    return True, f"intact, signed by {who}, trusted by the given CA"


def _check_run(run: Path, dcc: PrintedItems, marks: PageMarks | None, report: Verification) -> None:
    """Add the run's checks: its manifest, its seal (and the records chain head it names)
    against the ones the certificate names, its results against the DCC's, and (`marks`: a
    PDF's) the PDF's results table cell by cell against the run's lines as printed (the
    PrintedLine objects the PDF was drawn from: app.certificate.printed.table_cells)."""
    from app.certificate.load import load_stored_run
    from app.records.seal import SealError, read_seal

    try:
        stored = load_stored_run(run)  # verifies the manifest first
    except ValueError as exc:
        report.add("run manifest verified", False, str(exc))
        return
    report.add("run manifest verified", True)
    try:
        seal, seal_hash = read_seal(run)
        problem = "" if seal.run_id == stored.record.run_id else "it names another run"
        head = seal.records_chain_head or ""
    except SealError as exc:
        seal_hash, problem, head = "", str(exc), ""
    if not problem and dcc.seal != seal_hash:
        problem = f"the certificate names seal {dcc.seal or 'none'}, the run's is {seal_hash}"
    if not problem and dcc.chain_head != head:
        problem = (
            f"the certificate names records chain head {dcc.chain_head or 'none'}, the run's "
            f"seal {head or 'none'}"
        )
    report.add("run seal recomputed and named by the certificate", not problem, problem)
    results = stored.results
    lines = printed_lines(results)
    expected = PrintedItems(
        run_id=str(stored.record.run_id or ""),
        verdict=str(results.verdict or "not stated"),
        lines=rows_of(lines, results.phase_corrected_for_skew),
    )
    got = PrintedItems(run_id=dcc.run_id, verdict=dcc.verdict, lines=dcc.lines)
    diff = differences(expected, got, "run", "DCC")
    report.add("DCC numbers equal the run's results", not diff, "; ".join(diff[:3]))
    if marks is None:
        return
    diff = _table_differences(lines, results.phase_corrected_for_skew, marks)
    report.add("PDF results table equals the run's results", not diff, "; ".join(diff[:3]))


def _table_differences(
    lines: tuple[PrintedLine, ...], phase_stated: bool, marks: PageMarks
) -> list[str]:
    """Each cell of the PDF's table that is not the run's line as printed, and each line or
    cell printed that the run does not have, or missing."""
    in_g = any(column == Column.SENSITIVITY_G for _, column in marks.cells)
    expected = {
        (n, column): value
        for n, line in enumerate(lines, start=1)
        for column, value in table_cells(line, phase_stated, in_g)
    }
    out = []
    if marks.lines != len(lines):
        out.append(f"lines: run has {len(lines)}, PDF {marks.lines}")
    for key in sorted(set(expected) | set(marks.cells)):
        n, column = key
        printed = marks.cell(n, column)
        if printed != expected.get(key):
            out.append(f"line {n} {column}: run {expected.get(key)!r}, PDF {printed!r}")
    return out


# --- bounds -----------------------------------------------------------------------------------


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Keep the libraries' own warnings (pyHanko's PathBuildingError and the like) off stderr:
    what they found is in the report."""
    loggers = [logging.getLogger(name) for name in _QUIET]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for lg, level in zip(loggers, levels, strict=True):
            lg.setLevel(level)


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    """VerifyRefusal when the block runs longer than `seconds` (a timer signal; only on the
    main thread, elsewhere the block runs unbounded)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def expire(signum: int, frame: Any) -> None:
        raise VerifyRefusal(f"the check took longer than {seconds:g} s and was stopped")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
