"""What a certificate PDF states about its software validation report: the report PDF's
SHA-256 in the embedded DCC's "Software validation" statement, read inertly (app.certificate
.readback), for `accelcal verify --validation-report` to recompute (app.certificate.validated).
"""

from __future__ import annotations

import re
from pathlib import Path

from app.certificate.dcc import DCC_NS
from app.certificate.readback import PrintedError, parse_inert
from app.certificate.validated import STATEMENT_NAME, ValidationClaimError

_STATED = re.compile(r"report PDF's SHA-256 is ([0-9a-f]{64})")


def stated_report_sha256(pdf: Path) -> str | None:
    """The validation report's SHA-256 a certificate PDF states in its embedded DCC (read
    inertly, app.certificate.readback), or None when it names no validation report.
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
        match = _STATED.search(" ".join(str(text).split()))
        if match:
            return match.group(1)
    return None
