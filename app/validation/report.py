"""The validation report (ISO/IEC 17025:2017 7.11.2) as one PDF signed with the lab's key: the
software (version, SHA-256 over its installed files), the environment, and each case with
expected, obtained, tolerance and pass/fail, printed and embedded as a JSON record under the
signature; a readable JSON copy beside it. A report is written once, never over a file."""

from __future__ import annotations

import hashlib
import json
import platform
import sys
from dataclasses import asdict
from datetime import UTC, datetime
from importlib import metadata, resources
from pathlib import Path
from typing import TYPE_CHECKING

from app.certificate.validated import PACKAGES, REPORT_ATTACHMENT, Software
from app.files import FileExistsRefusal, write_with
from app.validation.cases import CaseResult

if TYPE_CHECKING:
    from app.certificate.sign import Signer

ENVIRONMENT_PACKAGES = ("numpy", "scipy", "h5py", "reportlab", "sqlalchemy", "pypdf")
FONT, FONT_BOLD = "DejaVuSans", "DejaVuSans-Bold"


def environment() -> dict[str, str]:
    """Python, operating system, machine and the versions of the numerical libraries."""
    env = {
        "python": sys.version.split()[0],
        "implementation": platform.python_implementation(),
        "system": platform.platform(),
        "machine": platform.machine(),
    }
    for name in ENVIRONMENT_PACKAGES:
        try:
            env[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            env[name] = "not installed"
    return env


def _fonts() -> None:
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    if FONT in pdfmetrics.getRegisteredFontNames():
        return
    data = resources.files("app").joinpath("data")
    for name, file in ((FONT, "DejaVuSans.ttf"), (FONT_BOLD, "DejaVuSans-Bold.ttf")):
        pdfmetrics.registerFont(TTFont(name, str(data.joinpath(file))))


def write_report(
    out: Path,
    cases: list[CaseResult],
    software: Software,
    env: dict[str, str],
    when: datetime,
    signer: Signer | None = None,
) -> None:
    """Write the PDF report to `out` with its record (date, software, environment, every case)
    embedded as REPORT_ATTACHMENT and, with `signer` (the lab's key), signed over the whole
    file as its last revision: the one form a certificate accepts (app.certificate
    .validated_check.read_report). Then a readable JSON copy beside it (same name, .json,
    with the PDF's SHA-256), which nothing trusts. FileExistsError (app.files) when either
    file exists."""
    if out.with_suffix(".json").exists():
        raise FileExistsRefusal(f"{out.with_suffix('.json')}: exists")
    record = {
        "report": "software validation, ISO/IEC 17025:2017 7.11.2",
        "date_utc": when.isoformat(timespec="seconds"),
        "software": asdict(software),
        "environment": env,
        "passed": all(case.passed for case in cases),
        "cases": [asdict(case) for case in cases],
    }

    def write_pdf(path: Path) -> None:
        from app.certificate.attach import embed

        _pdf(path, cases, software, env, when)
        embed(path, REPORT_ATTACHMENT, json.dumps(record, indent=2).encode("utf-8"))
        if signer is not None:
            signer.sign_in_place(path, "software validation, ISO/IEC 17025:2017 7.11.2")

    write_with(out, write_pdf)
    copy = {
        **record,
        "signed": signer is not None,
        "report_pdf_sha256": hashlib.sha256(out.read_bytes()).hexdigest(),
    }

    def write_json(path: Path) -> None:
        path.write_text(json.dumps(copy, indent=2), encoding="utf-8")

    try:
        write_with(out.with_suffix(".json"), write_json)
    except BaseException:
        out.unlink(missing_ok=True)
        raise


def _pdf(
    path: Path, cases: list[CaseResult], software: Software, env: dict[str, str], when: datetime
) -> None:
    from xml.sax.saxutils import escape

    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4, landscape
    from reportlab.lib.styles import ParagraphStyle
    from reportlab.lib.units import mm
    from reportlab.platypus import Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

    _fonts()
    body = ParagraphStyle("body", fontName=FONT, fontSize=8, leading=10)
    small = ParagraphStyle("small", parent=body, fontSize=6.5, leading=8, textColor=colors.grey)
    title = ParagraphStyle("title", parent=body, fontName=FONT_BOLD, fontSize=14, leading=18)
    heading = ParagraphStyle("heading", parent=body, fontName=FONT_BOLD, fontSize=10, leading=14)

    def p(text: str, style: ParagraphStyle = body) -> Paragraph:
        return Paragraph(escape(text), style)

    passed = sum(case.passed for case in cases)
    verdict = (
        "PASS: every case passed"
        if passed == len(cases)
        else (f"FAIL: {len(cases) - passed} of {len(cases)} cases failed")
    )
    story: list = [
        p("Software validation report", title),
        p("ISO/IEC 17025:2017 clause 7.11.2: validation of the software before use"),
        Spacer(1, 4 * mm),
        p("Software", heading),
        _kv(
            [
                ("name", "accelcal"),
                ("version", software.version),
                ("SHA-256 of the installed files", software.sha256),
                ("files covered", f"{software.files} (packages {', '.join(PACKAGES)})"),
                ("validated on", when.strftime("%Y-%m-%d %H:%M:%S UTC")),
            ],
            p,
        ),
        Spacer(1, 3 * mm),
        p("Environment", heading),
        _kv(list(env.items()), p),
        Spacer(1, 3 * mm),
        p(f"Result: {verdict}", heading),
        Spacer(1, 2 * mm),
    ]
    rows = [[p(h) for h in ("group", "case", "expected", "obtained", "tolerance", "result")]]
    for case in cases:
        rows.append(
            [
                p(case.group),
                [p(case.name), p(case.source, small)],
                p(case.expected),
                p(case.obtained),
                p(case.tolerance),
                p("pass" if case.passed else "FAIL"),
            ]
        )
    table = Table(
        rows, colWidths=[30 * mm, 95 * mm, 40 * mm, 50 * mm, 25 * mm, 15 * mm], repeatRows=1
    )
    style = [
        ("GRID", (0, 0), (-1, -1), 0.3, colors.grey),
        ("BACKGROUND", (0, 0), (-1, 0), colors.whitesmoke),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
    ]
    style += [
        ("BACKGROUND", (-1, i), (-1, i), colors.mistyrose)
        for i, case in enumerate(cases, 1)
        if not case.passed
    ]
    table.setStyle(TableStyle(style))
    story.append(table)

    def footer(canvas, doc) -> None:  # type: ignore[no-untyped-def]
        canvas.setFont(FONT, 7)
        canvas.drawString(15 * mm, 8 * mm, f"accelcal {software.version}: validation report")
        canvas.drawRightString(282 * mm, 8 * mm, f"page {doc.page}")

    doc = SimpleDocTemplate(
        str(path),
        pagesize=landscape(A4),
        leftMargin=15 * mm,
        rightMargin=15 * mm,
        topMargin=12 * mm,
        bottomMargin=15 * mm,
        title="accelcal software validation report",
        author="accelcal",
        subject=f"software {software.version}, SHA-256 {software.sha256}",
    )
    doc.build(story, onFirstPage=footer, onLaterPages=footer)


def _kv(rows: list[tuple[str, str]], p) -> object:  # type: ignore[no-untyped-def]
    from reportlab.lib.units import mm
    from reportlab.platypus import Table, TableStyle

    table = Table([[p(k), p(v)] for k, v in rows], colWidths=[50 * mm, 200 * mm], hAlign="LEFT")
    table.setStyle(TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP")]))
    return table


def now_utc() -> datetime:
    """The report's date."""
    return datetime.now(UTC)
