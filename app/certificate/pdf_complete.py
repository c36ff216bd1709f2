"""The PDF's parts of a complete certificate (issue 35 point 2; app.certificate.complete): the
ambient conditions with where they come from, the specification beside the statement of
conformity and the table of instruments used with their calibration due dates."""

from __future__ import annotations

from typing import Any

from reportlab.lib.units import mm
from reportlab.platypus import Paragraph, Table, TableStyle

from app.certificate.complete import condition_value
from app.certificate.complete import customer_address_text as customer_address_text
from app.certificate.complete import fixture_position_text as fixture_position_text
from app.certificate.info import CertificateInfo
from app.certificate.pdf_charts import FONT, FONT_BOLD, GRID

INSTRUMENTS_HEAD = "Instruments used"
NO_SPECIFICATION = "Specification: none named (no tolerance was checked)."


def _esc(words: Any) -> str:
    return str(words).replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def condition_rows(info: CertificateInfo) -> list[tuple[str, str]]:
    """The Conditions table's temperature (°C) and relative humidity (%) rows, each with its
    source (typed, or the environment sensor read at run start)."""
    temperature = condition_value(info.temperature_c, "°C", info.temperature_source)
    humidity = condition_value(info.humidity_percent, "%", info.humidity_source)
    return [("Ambient temperature", _esc(temperature)), ("Relative humidity", _esc(humidity))]


def specification_paragraph(info: CertificateInfo, style: Any) -> list[Any]:
    """The specification behind the statement of conformity (kind, identity, tolerances)."""
    spec = info.specification
    return [Paragraph(_esc(spec.line() if spec is not None else NO_SPECIFICATION), style)]


def instruments_section(info: CertificateInfo, head: Any, body: Any) -> list[Any]:
    """'Instruments used': kind, model, serial, calibration due, from where; nothing when the
    certificate lists none (a run before instruments were listed)."""
    if not info.instruments:
        return []
    rows: list[list[Any]] = [["Instrument", "Model", "Serial", "Calibration due", "From"]]
    for x in info.instruments:
        rows.append(
            [
                Paragraph(_esc(x.kind), body),
                Paragraph(_esc(x.model), body),
                Paragraph(_esc(x.serial), body),
                x.calibration_due or "not stated",
                x.source,
            ]
        )
    table = Table(rows, colWidths=[w * mm for w in (38, 56, 30, 28, 22)], hAlign="LEFT")
    table.setStyle(
        TableStyle(
            [
                ("FONTNAME", (0, 0), (-1, -1), FONT),
                ("FONTNAME", (0, 0), (-1, 0), FONT_BOLD),
                ("FONTSIZE", (0, 0), (-1, -1), 8),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
                ("LINEBELOW", (0, 0), (-1, 0), 0.5, GRID),
                ("TOPPADDING", (0, 0), (-1, -1), 1),
                ("BOTTOMPADDING", (0, 0), (-1, -1), 1),
            ]
        )
    )
    return [Paragraph(INSTRUMENTS_HEAD, head), table]
