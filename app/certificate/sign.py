"""Signing and checking certificates: PAdES signatures with the lab's key (pyHanko), and
`accelcal verify`: the signature, the embedded DCC against the PDF's numbers, and, with the run
folder, the run's manifest and the DCC against the run's own results.

The signature is the last thing written to a certificate PDF (an incremental update over the
finished document with its DCC attachment), so any later change of a byte breaks it.
"""

from __future__ import annotations

import io
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from app.errors import Refusal

PASSWORD_ENV = "ACCELCAL_SIGN_PASSWORD"


class SigningError(Refusal):
    """A key that cannot be used or a PDF that cannot be signed; the message says why."""


@dataclass(frozen=True)
class Signer:
    """The lab's signing key and certificate chain, loaded from a PKCS#12 file."""

    path: Path
    signer: Any

    @classmethod
    def load(cls, path: Path, password: str | None = None) -> Signer:
        """The key in `path` (PKCS#12), its password from `password` or $ACCELCAL_SIGN_PASSWORD."""
        from pyhanko.sign import signers

        if not path.is_file():
            raise SigningError(f"--sign: no such file {path}")
        secret = password if password is not None else os.environ.get(PASSWORD_ENV)
        try:
            signer = signers.SimpleSigner.load_pkcs12(
                str(path), passphrase=secret.encode() if secret else None
            )
        except Exception as exc:  # pyHanko reports a wrong password or format variously
            raise SigningError(f"--sign: {path}: cannot load the key ({exc})") from None
        if signer is None:
            raise SigningError(
                f"--sign: {path}: cannot load the key (wrong password? set ${PASSWORD_ENV})"
            )
        return cls(path, signer)

    def sign_in_place(self, pdf: Path, reason: str) -> None:
        """Sign `pdf` (PAdES baseline B) as its last revision."""
        from pyhanko.pdf_utils.incremental_writer import IncrementalPdfFileWriter
        from pyhanko.sign import fields, signers

        data = pdf.read_bytes()
        writer = IncrementalPdfFileWriter(io.BytesIO(data))
        meta = signers.PdfSignatureMetadata(
            field_name="LaboratorySignature",
            reason=reason,
            subfilter=fields.SigSeedSubFilter.PADES,
        )
        out = signers.sign_pdf(writer, meta, signer=self.signer)
        pdf.write_bytes(out.getvalue())


@dataclass
class Verification:
    """What `accelcal verify` found: each check with its outcome and the problems."""

    checks: list[tuple[str, bool, str]] = field(default_factory=list)

    def add(self, name: str, ok: bool, detail: str = "") -> None:
        self.checks.append((name, ok, detail))

    @property
    def ok(self) -> bool:
        return bool(self.checks) and all(ok for _, ok, _ in self.checks)


def verify(pdf: Path, run: Path | None = None, trust: Path | None = None) -> Verification:
    """Check a certificate PDF: its signature (intact, and trusted when `trust` names the CA
    certificate, PEM or DER), the embedded DCC (valid, and its numbers printed in the PDF), and
    with `run` the run's manifest and the DCC against the run's results."""
    from pypdf import PdfReader

    report = Verification()
    _check_signature(pdf, trust, report)
    try:
        reader = PdfReader(str(pdf))
        text = " ".join(" ".join(page.extract_text() for page in reader.pages).split())
        attachments = reader.attachments
    except Exception as exc:  # a damaged PDF
        report.add("PDF readable", False, str(exc))
        return report
    xml_list = attachments.get("certificate.xml") or []
    if len(xml_list) != 1:
        report.add("embedded DCC", False, "no certificate.xml attached")
        return report
    xml = xml_list[0]
    from app.certificate.dcc import validation_error

    problem = validation_error(xml)
    report.add("embedded DCC valid (DCC 3.3.0)", problem is None, problem or "")
    values = dcc_values(xml)
    missing = [
        f"{f} Hz: {s} {u}"
        for f, s, u in zip(values["f"], values["s"], values["u"], strict=True)
        if f"{s} {u}" not in text
    ]
    number = values["number"]
    report.add(
        "DCC numbers printed in the PDF",
        not missing and bool(values["s"]) and f"Calibration certificate {number}" in text,
        "; ".join(missing[:3]),
    )
    if run is not None:
        _check_run(run, values, report)
    return report


def _check_signature(pdf: Path, trust: Path | None, report: Verification) -> None:
    from pyhanko.pdf_utils.reader import PdfFileReader
    from pyhanko.sign.validation import validate_pdf_signature
    from pyhanko_certvalidator import ValidationContext

    try:
        with pdf.open("rb") as handle:
            reader = PdfFileReader(handle, strict=False)
            signatures = reader.embedded_signatures
            if not signatures:
                report.add("signature", False, "the PDF is not signed")
                return
            roots = [_load_certificate(trust)] if trust is not None else []
            context = ValidationContext(trust_roots=roots, allow_fetching=False)
            status = validate_pdf_signature(signatures[-1], context)
            covers_all = status.coverage is not None and status.coverage.name == "ENTIRE_FILE"
            report.add(
                "signature intact, covering the whole file",
                bool(status.intact and status.valid and covers_all),
                "" if status.intact else "the signed bytes were changed",
            )
            if trust is not None:
                report.add("signer trusted by the given CA", bool(status.trusted))
    except Exception as exc:  # a damaged signature or file
        report.add("signature", False, f"cannot be checked ({exc})")


def _load_certificate(path: Path) -> Any:
    from asn1crypto import pem, x509

    data = path.read_bytes()
    if pem.detect(data):
        _, _, data = pem.unarmor(data)
    return x509.Certificate.load(data)


def _check_run(run: Path, values: dict[str, Any], report: Verification) -> None:
    from app.certificate import load_stored_run
    from app.certificate.dcc import line_values

    try:
        stored = load_stored_run(run)  # verifies the manifest first
    except ValueError as exc:
        report.add("run manifest verified", False, str(exc))
        return
    report.add("run manifest verified", True)
    expected = line_values(stored.results)
    same = all(expected[key] == values[key] for key in ("f", "s", "u", "k"))
    report.add("DCC numbers equal the run's results", same)


def dcc_values(xml: bytes) -> dict[str, Any]:
    """From a DCC: its number and, per line, frequency, sensitivity, U and k (as printed)."""
    from app.certificate.dcc import DCC_NS, SI_NS

    ns = {"dcc": DCC_NS, "si": SI_NS}
    root = ET.fromstring(xml)
    out: dict[str, Any] = {
        "number": root.findtext(".//dcc:coreData/dcc:uniqueIdentifier", namespaces=ns),
        "f": [],
        "s": [],
        "u": [],
        "k": [],
    }
    for quantity in root.iterfind(".//dcc:result/dcc:data/dcc:list/dcc:quantity", ns):
        name = quantity.findtext("dcc:name/dcc:content", namespaces=ns) or ""
        values = (quantity.findtext(".//si:valueXMLList", namespaces=ns) or "").split()
        if name == "Excitation frequency":
            out["f"] = values
        elif name == "Sensitivity magnitude":
            out["s"] = values
            out["u"] = (
                quantity.findtext(".//si:valueExpandedMUXMLList", namespaces=ns) or ""
            ).split()
            out["k"] = (
                quantity.findtext(".//si:coverageFactorXMLList", namespaces=ns) or ""
            ).split()
    return out
