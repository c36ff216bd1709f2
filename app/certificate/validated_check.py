"""What a certificate PDF states about its software validation report: the report PDF's
SHA-256 in the embedded DCC's "Software validation" statement, read inertly (app.certificate
.readback), for `accelcal verify --validation-report` to recompute (app.certificate.validated).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from app.certificate.dcc import DCC_NS
from app.certificate.readback import PrintedError, parse_inert
from app.certificate.validated import STATEMENT_NAME, ValidationClaimError

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
    app.certificate.readback), or None when it names no validation report.
    ValidationClaimError when the PDF holds no single readable DCC."""
    from pypdf import PdfReader
    from pypdf.errors import PyPdfError

    try:
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
