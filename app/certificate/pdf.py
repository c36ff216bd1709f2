"""Drawing the PDF calibration certificate (SPEC.md section 10; ISO/IEC 17025 clause 7.8).

From a stored run and its numbered certificate items only: the numbers are the stored results
as printed by app.certificate.printed, the sentences app.certificate.text's. Reproducible:
reportlab's invariant mode and dates taken from the run make the same run and items give the
same bytes but for the creation date (app.certificate.pdf_page: $SOURCE_DATE_EPOCH fixes it).
The DCC XML is attached (PDF/A-3 style) and the file signed last when asked.

Layout: page 1 identifies the item, the method, the conditions, the reference standard, the
result at the reference frequency and the overall verdict with the statement of conformity;
the table of results starts there only with room for a useful part of it (TABLE_START_ROOM),
else on page 2; charts, budget and statements follow, each block kept on one page.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from reportlab.lib import colors
from reportlab.lib.enums import TA_CENTER, TA_RIGHT
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import ParagraphStyle
from reportlab.lib.units import mm
from reportlab.platypus import (
    CondPageBreak,
    KeepTogether,
    Paragraph,
    SimpleDocTemplate,
    Spacer,
    Table,
    TableStyle,
)

import app.certificate.pdf_complete as complete  # issue 35: conditions, spec, instruments
import app.certificate.reference_dcc as reference_dcc
import app.certificate.text as text
from app import formatting as fmt
from app.certificate.attach import embed
from app.certificate.info import CertificateInfo
from app.certificate.load import StoredRun
from app.certificate.pdf_charts import (
    BODY,
    FONT,
    FONT_BOLD,
    GRID,
    HEAD,
    HEAD_KEEP,
    SMALL,
    STYLES,
    chart,
)
from app.certificate.pdf_marks import MarkedParagraph, MarkedTable, MarkedText
from app.certificate.pdf_page import numbered_canvas
from app.certificate.printed import Item, printed_lines, table_cells
from app.certificate.statements import warnings_section
from app.certificate.triaxial_pdf import triaxial_section
from app.records.db.units import STANDARD_GRAVITY_MS2
from app.records.run_record import RunRecord
from app.records.seal import named_chain_head, named_seal
from app.records.sweep_summary import SweepSummary
from dsp.calibration import Results
from dsp.characteristic import characteristic
from dsp.uncertainty import Quantity

TITLE = ParagraphStyle(
    "title", parent=STYLES["Title"], fontName=FONT_BOLD, fontSize=17, alignment=TA_CENTER
)
TABLE_START_ROOM = 75 * mm  # room the results table needs to start on a page (~15 rows)
MV_PER_G = "mV/g"
TITLE_PREFIX = "Calibration certificate "  # the document title: this, then the number
VERDICT = ParagraphStyle(
    "verdict",
    parent=STYLES["Title"],
    fontName=FONT_BOLD,
    fontSize=20,
    leading=24,
    alignment=TA_CENTER,
)


def _table(
    rows: list[list[Any]],
    widths: list[float],
    header: bool = True,
    size: float = 8,
    marked: bool = False,
) -> Table:
    """A table; `marked`: its MarkedText cells drawn inside their marks."""
    kind = MarkedTable if marked else Table
    table = kind(rows, colWidths=widths, repeatRows=1 if header else 0, hAlign="LEFT")
    style = [
        ("FONTNAME", (0, 0), (-1, -1), FONT),
        ("FONTSIZE", (0, 0), (-1, -1), size),
        ("LEADING", (0, 0), (-1, -1), size + 2),
        ("VALIGN", (0, 0), (-1, -1), "TOP"),
        ("LINEBELOW", (0, 0), (-1, 0 if header else -1), 0.5, colors.black if header else GRID),
        ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5),
        ("TOPPADDING", (0, 0), (-1, -1), 1.5),
    ]
    if header:
        style += [
            ("FONTNAME", (0, 0), (-1, 0), FONT_BOLD),
            ("ALIGN", (1, 1), (-1, -1), "RIGHT"),
        ]
    table.setStyle(TableStyle(style))
    return table


def _kv(rows: list[tuple[str, str]] | list[tuple[str, str, Item | None]]) -> Table:
    """A table of labels and values; a value with an Item is drawn inside its mark
    (app.certificate.pdf_marks: what `accelcal verify` reads back)."""
    data = []
    for row in rows:
        label, value, item = (*row, None)[:3]
        cell = MarkedParagraph(value, BODY, item) if item is not None else Paragraph(value, BODY)
        data.append([Paragraph(f"<b>{label}</b>", BODY), cell])
    table = Table(data, colWidths=[48 * mm, 126 * mm], hAlign="LEFT")
    table.setStyle(
        TableStyle(
            [
                ("FONTNAME", (0, 0), (-1, -1), FONT),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
                ("BOTTOMPADDING", (0, 0), (-1, -1), 1),
                ("TOPPADDING", (0, 0), (-1, -1), 1),
            ]
        )
    )
    return table


def _dof(value: float) -> str:
    return "∞" if not math.isfinite(value) or value > 1e4 else f"{value:.0f}"


def _esc(words: Any) -> str:
    return str(words).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def write_pdf(
    run: StoredRun,
    info: CertificateInfo,
    sweep: SweepSummary | None,
    out: Path,
    dcc_xml: bytes | None = None,
    signer: Any = None,
) -> None:
    """Draw the certificate PDF of `run` with `info` (numbered) to `out`, read-only, with the
    DCC XML attached when given, signed last with `signer` (app.certificate.sign.Signer) when
    given."""
    record, results = run.record, run.results
    stand = record.stand
    lab = dict(stand.laboratory)
    reference = dict(stand.reference)
    number = str(info.certificate_number)  # numbered before the PDF is made (_numbered)
    story: list[Any] = []
    r = results.reference
    phase, u_phase = fmt.round_gum(r.phase_deg, r.phase_expanded_uncertainty_deg)
    p_percent = f"{100 * results.coverage_probability:.2f} %"

    story += [
        Paragraph("CALIBRATION CERTIFICATE", TITLE),
        Paragraph(
            f"<b>{_esc(lab.get('name', ''))}</b><br/>{_esc(lab.get('address', ''))}"
            + (f"<br/>{_esc(lab['accreditation'])}" if lab.get("accreditation") else ""),
            ParagraphStyle("lab", parent=BODY, alignment=TA_CENTER),
        ),
        Spacer(1, 4 * mm),
        _kv(
            [
                ("Certificate number", _esc(number), Item.NUMBER),
                *_amendment_rows(info),
                (
                    "Customer",
                    f"{_esc(info.customer)}, {_esc(complete.customer_address_text(info))}",
                    Item.CUSTOMER,
                ),
                ("Item calibrated", f"{_esc(info.dut_type)}: {_esc(info.dut_model)}", None),
                ("Serial number", _esc(info.dut_serial), Item.SERIAL),
                ("Date of calibration", _esc(record.started_utc[:10]), Item.CALIBRATION_DATE),
                ("Date of issue", _esc(info.issue_date), Item.ISSUE_DATE),
                ("Calibration run", _esc(record.run_id), Item.RUN_ID),
                *[("Run seal", seal, Item.SEAL) for seal in [named_seal(run.path)] if seal],
                *[
                    ("Records chain head", head, Item.CHAIN_HEAD)
                    for head in [named_chain_head(run.path)]
                    if head
                ],
            ]
        ),
        *verification_qr(run, number),
        Paragraph("Method", HEAD),
        Paragraph(text.method_text(record, results), BODY),
        Paragraph("Conditions", HEAD),
        _kv(
            [
                *complete.condition_rows(info),
                ("Mounting", _esc(info.mounting)),
                *[("Fixture", _esc(f)) for f in [complete.fixture_position_text(run.start)] if f],
                ("Excitation level", f"{record.level_ms2 or 0:g} m/s² peak per frequency"),
            ]
        ),
        Paragraph("Reference standard and traceability", HEAD),
        _kv(
            [
                (
                    "Reference standard",
                    f"{_esc(reference.get('model', ''))}, "
                    f"serial {_esc(reference.get('serial', ''))} "
                    f"(id {_esc(reference.get('id', ''))})",
                ),
                (
                    "Its calibration",
                    f"certificate {_esc(reference.get('certificate_number', ''))} of "
                    f"{_esc(reference.get('certificate_date', ''))}, traceable to national "
                    "standards",
                ),
                *reference_dcc.pdf_rows(reference),
            ]
        ),
        *complete.instruments_section(info, HEAD, BODY),
        Paragraph("Result at the reference frequency", HEAD),
        _kv(
            [
                ("Reference frequency", f"{r.frequency_hz:g} Hz"),
                ("Sensitivity", _reference_sensitivity(results, info)),
                (
                    "Phase",
                    f"({phase} ± {u_phase})°"
                    if results.phase_corrected_for_skew
                    else text.PHASE_NOT_STATED,
                ),
                ("Coverage", f"k = {r.coverage_factor:.2f}, coverage probability {p_percent}"),
            ]
        ),
    ]
    story += _verdict_section(results)
    story += [CondPageBreak(TABLE_START_ROOM)]
    story += _line_table(results, in_g=info.sensitivity_unit == MV_PER_G)
    story += _charts(results)
    if sweep is not None:
        story += _sweep_section(sweep)
    story += _budget_section(run, results)
    story += warnings_section(results, HEAD, SMALL)
    story += triaxial_section(info.triaxial) if info.triaxial is not None else []
    statements = _statements(results, info, p_percent) + _overrides_section(record)
    story += _sign_off(info, record, statements + validation_statement(info))
    document = SimpleDocTemplate(
        str(out),
        pagesize=A4,
        leftMargin=18 * mm,
        rightMargin=18 * mm,
        topMargin=20 * mm,
        bottomMargin=22 * mm,
        title=f"{TITLE_PREFIX}{number}",
        author=lab.get("name", ""),
        subject=f"{info.dut_model} serial {info.dut_serial}",
        creator=f"accelcal {record.software_version}",
    )
    document.build(story, canvasmaker=numbered_canvas(number, lab.get("name", "")))
    if dcc_xml is not None:
        embed(out, "certificate.xml", dcc_xml)
    if signer is not None:
        signer.sign_in_place(out, reason=f"Calibration certificate {number}")
    out.chmod(0o444)


def _amendment_rows(info: CertificateInfo) -> list[tuple[str, str, Item | None]]:
    """An amendment's rows under its number (ISO/IEC 17025 7.8.8.3): the certificate it
    replaces, which is withdrawn from use by it, and the reason; none for a first issue."""
    a = info.amendment
    if a is None:
        return []
    return [
        ("Replaces certificate", _esc(a.replaces), Item.REPLACES),
        ("", f"which it supersedes in full; {_esc(a.replaces)} is no longer valid", None),
        ("Reason for the amendment", _esc(a.reason), Item.AMENDMENT_REASON),
    ]


def _reference_sensitivity(results: Results, info: CertificateInfo) -> str:
    """The sensitivity at the reference frequency with its U: in mV/(m/s²) and dB, and first
    in mV/g when the sensor model states its sensitivity in mV/g (1 g = 9.80665 m/s²)."""
    r = results.reference
    value, u_value = fmt.round_gum(r.sensitivity_mv_per_ms2, r.expanded_uncertainty_mv_per_ms2)
    si = f"({value} ± {u_value}) mV/(m/s²)"
    db = f"{r.sensitivity_db:.2f} dB re 1 mV/(m/s²)"
    if info.sensitivity_unit != MV_PER_G:
        return f"<b>{si}</b>, i.e. {db}"
    g_value, u_g = fmt.round_gum(
        r.sensitivity_mv_per_ms2 * STANDARD_GRAVITY_MS2,
        r.expanded_uncertainty_mv_per_ms2 * STANDARD_GRAVITY_MS2,
    )
    return f"<b>({g_value} ± {u_g}) mV/g</b>, i.e. <b>{si}</b>, {db}"


def _verdict_section(results: Results) -> list[Any]:
    """The overall verdict, large and plain, with its reasons (app.procedure.verdict) as the
    certificate states them (without the technician's advice), kept together."""
    if results.verdict is None:
        return []
    reasons = "<br/>".join(
        f"• {_esc(text.certificate_reason(reason))}" for reason in results.verdict_reasons
    )
    return [
        KeepTogether(
            [
                Paragraph("Overall verdict", HEAD),
                MarkedParagraph(f"<b>{_esc(results.verdict)}</b>", VERDICT, Item.VERDICT),
                Paragraph(text.VERDICT_RULE_NOTE, SMALL),
                Paragraph(reasons, SMALL),
            ]
        )
    ]


class _Whole(Paragraph):
    """A paragraph never broken across pages: moved whole to the next one instead."""

    def split(self, availWidth: float, availHeight: float) -> list[Any]:
        return []


def _line_table(results: Results, in_g: bool = False) -> list[Any]:
    """The results per frequency, each cell drawn inside its mark (column, line) from
    app.certificate.printed.table_cells; with `in_g` a last column, the sensitivity in mV/g."""
    header = [
        "Nominal\nfreq.\nHz",
        "Actual\nfreq.\nHz",
        "Sensitivity\nmV/(m/s²)",
        "U\nmV/(m/s²)",
        "Deviation\n%",
        "U dev.\n%",
        "Dev.\ndB",
        "Phase\n°",
        "U phase\n°",
        "U rel.\n%",
        "k",
        "U vs.\nISO 16063-21\nlimit",
        *(["Sensitivity\nmV/g"] if in_g else []),
    ]
    rows: list[list[str]] = [header]
    stated = results.phase_corrected_for_skew
    for index, line in enumerate(printed_lines(results), start=1):  # as the DCC and verify
        cells = table_cells(line, stated, in_g)
        rows.append([MarkedText(value, column, index) for column, value in cells])
    widths: tuple[int, ...] = (13, 13, 20, 15, 15, 13, 13, 12, 13, 12, 9, 16)
    if in_g:
        widths = (12, 12, 19, 14, 14, 12, 12, 12, 12, 11, 8, 14, 18)
    table = _table(rows, [w * mm for w in widths], size=7.3 if not in_g else 7.0, marked=True)
    notes = [
        Paragraph(text.line_table_note(results.phase_corrected_for_skew), SMALL),
        Paragraph(text.cmc_statement(results), SMALL),  # where the CMC bounds U (issue 32)
    ]
    if results.phase_corrected_for_skew:
        notes.append(Paragraph(text.PHASE_CONVENTION, SMALL))
    return [Paragraph("Results per frequency", HEAD), table, Spacer(1, 1.5 * mm), *notes]


def _charts(results: Results) -> list[Any]:
    """The amplitude (deviation, %) and phase (degree) characteristics with their U bands
    (dsp.characteristic: the same numbers the GUI draws)."""
    c = characteristic(results)
    f = c.frequency_hz.tolist()
    amplitude = chart(
        f, c.deviation_percent.tolist(), c.deviation_expanded_percent.tolist(), "deviation in %"
    )
    if not results.phase_corrected_for_skew:  # no phase characteristic without the skew
        return [
            KeepTogether(
                [
                    Paragraph("Amplitude-frequency characteristic", HEAD),
                    amplitude,
                    Paragraph(f"Phase-frequency characteristic: {text.PHASE_NOT_STATED}.", BODY),
                    Paragraph(text.CHARTS_NOTE, SMALL),
                ]
            )
        ]
    phase = chart(f, c.phase_deg.tolist(), c.phase_expanded_deg.tolist(), "phase in degrees")
    return [  # one block a chart: the amplitude one may follow the table on its page
        KeepTogether([Paragraph("Amplitude-frequency characteristic", HEAD), amplitude]),
        KeepTogether(
            [
                Paragraph("Phase-frequency characteristic", HEAD),
                phase,
                Paragraph(text.CHARTS_NOTE, SMALL),
            ]
        ),
    ]


def _sweep_section(sweep: SweepSummary) -> list[Any]:
    """Sensitivity against frequency and level (mV/(m/s^2)) and linearity per frequency."""
    t = sweep.table
    if t is None:  # load_sweep admits complete sweeps only
        return []
    levels = sweep.levels_ms2
    header = ["Frequency\nHz", *(f"{lv:g} m/s²" for lv in levels), "Linearity\n%"]
    rows = [header]
    for k, f in enumerate(t.frequencies_hz):
        rows.append(
            [
                f"{f:g}",
                *(f"{row[k]:.4g}" for row in t.sensitivity_mv_per_ms2),
                fmt.significant(t.linearity_percent[k]),
            ]
        )
    width = 150 / (len(levels) + 2)
    return [
        Paragraph("Sensitivity against excitation level (mV/(m/s²))", HEAD),
        _table(rows, [width * mm] * (len(levels) + 2), size=7.3),
        Spacer(1, 1.5 * mm),
        Paragraph(
            f"Linearity: largest deviation of the sensitivity at any level from its mean over "
            f"the levels: {fmt.significant(t.reference_linearity_percent)} % at "
            f"{t.reference_frequency_hz:g} Hz, at most "
            f"{fmt.significant(t.worst_linearity_percent)} % (at "
            f"{t.worst_linearity_frequency_hz:g} Hz). Levels are peak accelerations per "
            f"frequency; runs {', '.join(sweep.run_ids)}.",
            SMALL,
        ),
    ]


def _budget_section(run: StoredRun, results: Results) -> list[Any]:
    r = results.reference
    line = next(ln for ln in results.lines if ln.nominal_frequency_hz == r.frequency_hz)
    rows = [["Component", "Value", "Distribution", "Standard\nuncertainty", "Degrees of\nfreedom"]]
    rows.append(
        [
            "Type A within this run (scatter of the periods)",
            "",
            "normal (t)",
            f"{100 * line.relative_type_a:.3g} %",
            f"{2 * (results.periods - 1)}",
        ]
    )
    f = line.frequency_hz
    for c in run.budget.at(f, Quantity.MAGNITUDE):
        rows.append(
            [
                Paragraph(_esc(c.name), SMALL),
                f"{100 * c.value * c.scale_at(f):.3g} %",  # the value at this line (its law)
                str(c.distribution),
                f"{100 * c.standard_uncertainty_at(f):.3g} %",
                _dof(c.dof),
            ]
        )
    rows.append(
        [
            "Combined standard uncertainty",
            "",
            "",
            f"{100 * line.relative_standard_uncertainty:.3g} %",
            _dof(line.effective_dof),
        ]
    )
    bounded = "U" in line.cmc_bounds.split(", ")  # k u_c below the CMC: the CMC is stated
    combined = fmt.significant(100 * line.coverage_factor * line.relative_standard_uncertainty)
    label = f"Expanded uncertainty (k = {line.coverage_factor:.2f})"
    label += f": the CMC (k u_c = {combined} % is below it)" if bounded else ""
    u_text = f"{fmt.significant(100 * line.relative_expanded_uncertainty)} %"
    rows.append([Paragraph(label, SMALL), "", "", u_text, ""])
    table = _table(rows, [w * mm for w in (78, 18, 24, 26, 22)], size=7.5)
    return [
        KeepTogether(
            [
                Paragraph(f"Uncertainty budget of the sensitivity at {r.frequency_hz:g} Hz", HEAD),
                table,
            ]
        )
    ]


def _statements(results: Results, info: CertificateInfo, p_percent: str) -> list[Any]:
    out = [
        Paragraph("Uncertainty statement", HEAD),
        Paragraph(text.uncertainty_statement(results.uncertainty_rule, p_percent), BODY),
    ]
    if results.tolerance_percent is not None or results.verdict is not None:
        verdicts = [ln.tolerance_verdict for ln in results.lines]
        out += [  # the overall verdict's words: the two sections cannot disagree
            Paragraph("Statement of conformity", HEAD_KEEP),
            _Whole(
                text.conformity_statement(results.verdict, results.tolerance_percent, verdicts),
                BODY,
            ),
            *complete.specification_paragraph(info, BODY),  # whose tolerances (issue 35)
        ]
    if info.notes:
        out += [Paragraph("Notes", HEAD), Paragraph(_esc(info.notes), BODY)]
    return out


def _overrides_section(record: RunRecord) -> list[Any]:
    """ "Overrides": each check the run went past with a stated reason (results.json's
    overrides: kind, what, reason, who, when); nothing when none."""
    if not record.overrides:
        return []
    story: list[Any] = [
        Paragraph("Overrides", HEAD),
        Paragraph("The run went past these checks for the reason stated:", BODY),
    ]
    for override in record.overrides:
        story.append(
            Paragraph(
                f"<b>{_esc(override.kind)}</b>: {_esc(override.what)}. Reason: "
                f"{_esc(override.why)} (by {_esc(override.who)}, {_esc(override.when_utc)})",
                BODY,
            )
        )
    return story


def _sign_off(info: CertificateInfo, record: RunRecord, before: list[Any]) -> list[Any]:
    """The sign-off block (prepared, authorised, date, software, raw data hash) kept on one
    page with the statements `before` it, so it never stands alone on the last page: all of
    them together when they fit on a page, else (KeepTogether splits) at least the last
    section (from its heading) with the block."""
    block = [
        Spacer(1, 6 * mm),
        _kv(
            [
                ("Prepared by", _esc(info.prepared_by or "not stated")),
                (
                    "Authorised by",
                    f"{_esc(info.authorised_by)}"
                    + (f"<br/>{_esc(info.authorised_function)}" if info.authorised_function else "")
                    + "<br/><br/>signature: ______________________",
                ),
                ("Date of issue", _esc(info.issue_date)),
                ("Software", f"accelcal {_esc(record.software_version)}"),
                (
                    "Raw data SHA-256",
                    f"<font size=7>{_esc(record.raw_data_sha256 or '')}</font>",
                ),
            ]
        ),
        Spacer(1, 2 * mm),
        Paragraph(text.RELATE_ONLY, BODY),
    ]
    headings = (HEAD.name, HEAD_KEEP.name)
    starts = [
        i for i, f in enumerate(before) if isinstance(f, Paragraph) and f.style.name in headings
    ]
    last = starts[-1] if starts else 0
    return [KeepTogether([*before[:last], KeepTogether([*before[last:], *block])])]


# ---- issue 27: the verification QR code and the software validation statement ------------


def verification_qr(run: StoredRun, number: str) -> list[Any]:
    """Page 1's QR code (QR_SIZE_MM square, right-aligned) with its address under it in small
    type; nothing when the stand file has no verify_url."""
    import io

    from reportlab.platypus import Image

    from app.certificate.qr import QR_SIZE_MM, qr_png, verification_address

    address = verification_address(run, number)
    if address is None:
        return []
    size = QR_SIZE_MM * mm
    image = Image(io.BytesIO(qr_png(address)), width=size, height=size)
    caption = Paragraph(
        f"Verify this certificate at<br/>{_esc(address)}",
        ParagraphStyle("qr", parent=SMALL, fontSize=6.5, leading=8, alignment=TA_RIGHT),
    )
    block = Table([[image], [caption]], colWidths=[80 * mm])  # the address under the code
    block.setStyle(
        TableStyle(
            [
                ("ALIGN", (0, 0), (-1, -1), "RIGHT"),
                ("LEFTPADDING", (0, 0), (-1, -1), 0),
                ("RIGHTPADDING", (0, 0), (-1, -1), 0),
                ("TOPPADDING", (0, 0), (-1, -1), 1),
                ("BOTTOMPADDING", (0, 0), (-1, -1), 1),
            ]
        )
    )
    block.hAlign = "RIGHT"
    return [Spacer(1, 2 * mm), block]


def validation_statement(info: CertificateInfo) -> list[Any]:
    """The software validation report the certificate names (`info.validation`: chosen by the
    issuing service, a report signed by the lab for this software, app.certificate.validated);
    nothing otherwise."""
    from app.certificate.validated import STATEMENT_NAME

    claim = info.validation
    if claim is None:
        return []
    return [Paragraph(STATEMENT_NAME, HEAD), Paragraph(_esc(claim.line()), SMALL)]
