"""What a certificate states besides the numbers (issue 25 points 2 and 5): every warning of
the run that does not block it (app.records.warnings), and the JCGM 101 Monte Carlo
interval of each line whose GUM interval failed the clause 8 check (stored per line by
--mcm). Plain strings; the PDF draws them (app.certificate.pdf). Magnitude in %, phase in
degrees.
"""

from __future__ import annotations

from typing import Any

from reportlab.lib.styles import ParagraphStyle
from reportlab.platypus import Paragraph

from app.procedure.verdict import run_warnings
from app.records.warnings import printed
from dsp.calibration import Results

__all__ = ["mcm_statements", "printed_warnings", "warnings_section"]


def printed_warnings(results: Results) -> list[str]:
    """The run's warnings the certificate prints, each once, in the run's order."""
    return [w.text for w in printed(run_warnings(results))]


def mcm_statements(results: Results) -> list[str]:
    """One sentence per stored Monte Carlo result whose GUM interval was not validated: the
    coverage interval JCGM 101 gives instead (about the stated value)."""
    out = []
    for m in results.mcm:
        if m.get("validated", True):
            continue
        try:
            f, low, high = float(m["frequency_hz"]), float(m["low"]), float(m["high"])
            p, trials = float(m["probability"]), int(m["trials"])
            gum = float(m["gum_high"])
        except (KeyError, TypeError, ValueError):
            continue  # a malformed entry states nothing (the seal protects stored results)
        scale, unit = (100.0, " %") if m.get("quantity") == "magnitude" else (1.0, "°")
        what = "sensitivity" if unit == " %" else "phase"
        out.append(
            f"{f:g} Hz, {what}: the GUM interval ±{scale * gum:.3g}{unit} failed the JCGM 101 "
            f"clause 8 check; the Monte Carlo coverage interval ({trials} trials, p = "
            f"{100 * p:.2f} %) is [{scale * low:+.3g}, {scale * high:+.3g}]{unit} about the "
            "stated value"
        )
    return out


def warnings_section(results: Results, head: ParagraphStyle, body: ParagraphStyle) -> list[Any]:
    """The PDF's "Warnings" and "Monte Carlo validation (JCGM 101)" sections (none when there
    is nothing to state), in the certificate's heading and body styles."""
    out: list[Any] = []
    for title, items in (
        ("Warnings", printed_warnings(results)),
        ("Monte Carlo validation (JCGM 101)", mcm_statements(results)),
    ):
        if items:
            out += [
                Paragraph(title, head),
                Paragraph("<br/>".join(f"• {_esc(item)}" for item in items), body),
            ]
    return out


def _esc(words: str) -> str:
    return words.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
