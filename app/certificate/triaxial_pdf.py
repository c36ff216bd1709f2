"""The PDF section of a triaxial sensor (issue 36 point 3): the 3 x 3 sensitivity matrix at the
reference frequency with U, the largest transverse sensitivity per axis with its direction,
and per axis its characteristic and its transverse statements per line, as reportlab
flowables in the certificate's fonts; every number as app.certificate.triaxial prints it.

`sample_pdf` draws the section alone on numbered A4 pages (the certificate's page furniture),
for a look at it before the certificate's assembly from three stored orientation runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from reportlab.lib import colors
from reportlab.lib.pagesizes import A4
from reportlab.lib.styles import ParagraphStyle
from reportlab.lib.units import mm
from reportlab.platypus import KeepTogether, Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

from app.certificate.pdf_charts import BODY, FONT, FONT_BOLD, GRID, HEAD_KEEP, SMALL
from app.certificate.pdf_page import numbered_canvas
from app.certificate.triaxial import (
    SECTION_TITLE,
    Printed,
    PrintedAxis,
    PrintedTriaxial,
    direction_text,
    printed_triaxial,
)
from dsp.triaxial import TriaxialResult

HEAD = HEAD_KEEP  # a section's heads stay with what follows
SUBHEAD = ParagraphStyle("tri_subhead", parent=HEAD, fontSize=10, spaceBefore=6)
MATRIX_NOTE = (
    "S[j, o]: the output of channel j per m/s² along the sensor's axis o (column o measured "
    "with the exciter along o), magnitude in mV/(m/s²) and phase in degrees. An off-diagonal "
    "entry's U holds the exciter's transverse motion and the mounting's alignment as stated."
)
TRANSVERSE_NOTE = (
    "Transverse sensitivity ratio towards axis k: S[j, k] / S[j, j] in % of the main-axis "
    "sensitivity, its phase 0° in phase with the main axis (towards +k), 180° in antiphase "
    "(towards −k). Largest transverse sensitivity: √(|S[j, k]|² + |S[j, l]|²) / |S[j, j]| "
    "(ISO 16063-31), at the angle of its in-phase part in the plane normal to j, from +k "
    "towards +l. n/s: not stated."
)


def _table(rows: list[list[Any]], widths_mm: list[float], size: float = 7.0) -> Table:
    table = Table(rows, colWidths=[w * mm for w in widths_mm], repeatRows=1, hAlign="LEFT")
    table.setStyle(
        TableStyle(
            [
                ("FONTNAME", (0, 0), (-1, -1), FONT),
                ("FONTNAME", (0, 0), (-1, 0), FONT_BOLD),
                ("FONTSIZE", (0, 0), (-1, -1), size),
                ("LEADING", (0, 0), (-1, -1), size + 2),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
                ("ALIGN", (1, 1), (-1, -1), "RIGHT"),
                ("LINEBELOW", (0, 0), (-1, 0), 0.5, colors.black),
                ("BOTTOMPADDING", (0, 0), (-1, -1), 1.2),
                ("TOPPADDING", (0, 0), (-1, -1), 1.2),
            ]
        )
    )
    return table


def _pair(p: Printed) -> list[str]:
    return [p.value, p.expanded]


def matrix_table(section: PrintedTriaxial) -> Table:
    """The 3 x 3 matrix at the reference frequency: per row (channel) and column (axis of
    excitation) the magnitude ± U and the phase ± U."""
    header = ["Channel", *(f"along {o}: |S|, mV/(m/s²)\nphase, °" for o in ("x", "y", "z"))]
    rows: list[list[Any]] = [header]
    for row in section.matrix:
        cells = [f"{row[0].row}"]
        for e in row:
            magnitude = f"{e.magnitude.value} ± {e.magnitude.expanded}"
            cells.append(f"{magnitude}\n{e.phase.value}° ± {e.phase.expanded}°")
        rows.append(cells)
    table = _table(rows, [22, 50, 50, 50], size=8)
    table.setStyle(TableStyle([("LINEBELOW", (0, 1), (-1, -2), 0.25, GRID)]))
    return table


def characteristic_table(axis: PrintedAxis) -> Table:
    """One axis per line: frequency, sensitivity, deviation and phase, each with U."""
    header = [
        "f\nHz",
        "Sensitivity\nmV/(m/s²)",
        "U\nmV/(m/s²)",
        "Deviation\n%",
        "U dev.\n%",
        "Phase\n°",
        "U phase\n°",
        "k",
    ]
    rows: list[list[Any]] = [header]
    for ln in axis.lines:
        rows.append(
            [
                ln.frequency,
                *_pair(ln.sensitivity),
                *_pair(ln.deviation),
                *_pair(ln.phase),
                ln.sensitivity.k,
            ]
        )
    return _table(rows, [16, 26, 22, 22, 20, 20, 20, 14])


def transverse_table(axis: PrintedAxis) -> Table:
    """One axis per line: the ratios towards k and l (magnitude and phase), the largest
    transverse sensitivity and its angle, each with U."""
    k, el = axis.towards_k, axis.towards_l
    header = [
        *("f\nHz", f"→{k}\n%", "U\n%", f"→{k}\nphase °", "U\n°", f"→{el}\n%", "U\n%"),
        *(f"→{el}\nphase °", "U\n°", "largest\n%", "U\n%", f"angle °\n+{k}→+{el}", "U\n°"),
    ]
    rows: list[list[Any]] = [header]
    for ln in axis.lines:
        rows.append(
            [
                ln.frequency,
                *_pair(ln.ratio_k),
                *_pair(ln.ratio_k_phase),
                *_pair(ln.ratio_l),
                *_pair(ln.ratio_l_phase),
                *_pair(ln.largest),
                *_pair(ln.angle),
            ]
        )
    return _table(rows, [13, 13, 12, 14, 12, 13, 12, 14, 12, 14, 12, 15, 12], size=6.8)


def triaxial_section(result: TriaxialResult) -> list[Any]:
    """The flowables of the section: heading, matrix, largest transverse per axis, then per
    axis its characteristic and transverse tables, and the notes."""
    section = printed_triaxial(result)
    p = section.coverage_probability
    story: list[Any] = [
        Paragraph(SECTION_TITLE, HEAD),
        Paragraph(
            f"Sensitivity matrix at the reference frequency {section.reference_frequency} Hz "
            f"(expanded uncertainty U with a coverage probability of {p} %)",
            SUBHEAD,
        ),
        matrix_table(section),
        Spacer(1, 1.5 * mm),
        Paragraph(MATRIX_NOTE, SMALL),
        Paragraph(f"Largest transverse sensitivity at {section.reference_frequency} Hz", SUBHEAD),
        *[Paragraph(direction_text(a), BODY) for a in section.axes],
    ]
    for axis in section.axes:
        story += [
            Paragraph(f"Axis {axis.axis}: characteristic (exciter along {axis.axis})", SUBHEAD),
            characteristic_table(axis),
            KeepTogether(
                [
                    Paragraph(f"Axis {axis.axis}: transverse sensitivity", SUBHEAD),
                    transverse_table(axis),
                ]
            ),
        ]
    story += [Spacer(1, 2 * mm), Paragraph(TRANSVERSE_NOTE, SMALL)]
    story += [Paragraph(_esc(note), SMALL) for note in section.notes]
    return story


def _esc(words: str) -> str:
    return words.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def sample_pdf(result: TriaxialResult, out: Path, number: str, laboratory: str) -> None:
    """The section alone on A4 pages with the certificate's header and 'page x of y'."""
    document = SimpleDocTemplate(
        str(out),
        pagesize=A4,
        leftMargin=18 * mm,
        rightMargin=18 * mm,
        topMargin=20 * mm,
        bottomMargin=22 * mm,
        title=f"Triaxial section {number}",
        author=laboratory,
    )
    document.build(triaxial_section(result), canvasmaker=numbered_canvas(number, laboratory))
