"""The impact report of a corrected reference standard (ISO/IEC 17025 7.10): a CSV and a PDF
(reportlab) listing every affected run with old and new sensitivity (mV/(m/s^2)), the change in
units of U and the verdicts that change, and a draft notice per customer (plain text).
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime

from app.io.csv_cells import csv_text
from app.procedure.impact import CorrectedTable, RunImpact

CSV_HEADER = (
    "run_id",
    "started_utc",
    "dut_id",
    "owner",
    "certificates",
    "reference_frequency_hz",
    "old_sensitivity_mv_per_ms2",
    "new_sensitivity_mv_per_ms2",
    "ratio_new_old",
    "expanded_uncertainty_mv_per_ms2",
    "change_in_u",
    "worst_change_in_u",
    "worst_frequency_hz",
    "old_verdict",
    "new_verdict",
    "verdict_changed",
    "problem",
)


@dataclass(frozen=True)
class ImpactReport:
    """What `accelcal impact` found: the reference, the corrected table, the window (UTC; None:
    open), the affected runs (checked or not) in time order and the certificates flagged."""

    serial: str
    table: CorrectedTable
    since: datetime | None
    until: datetime | None
    runs: tuple[RunImpact, ...]
    flagged: tuple[str, ...] = ()
    runs_in_window: int = 0

    @property
    def checked(self) -> tuple[RunImpact, ...]:
        return tuple(r for r in self.runs if r.problem is None)

    @property
    def unchecked(self) -> tuple[RunImpact, ...]:
        return tuple(r for r in self.runs if r.problem is not None)

    def window_text(self) -> str:
        since = self.since.date().isoformat() if self.since else "the first run"
        until = self.until.date().isoformat() if self.until else "now"
        return f"{since} to {until}"


def _num(value: float | None, fmt: str = ".12g") -> str:
    return "" if value is None else format(value, fmt)


def to_csv(report: ImpactReport) -> str:
    """One row per affected run (CSV_HEADER); a run that could not be checked names why.
    Names a spreadsheet would run as formulas are written as text (app.io.csv_cells)."""
    rows: list[Sequence[object]] = [CSV_HEADER]
    for r in report.runs:
        ratio = (
            r.new_sensitivity / r.old_sensitivity
            if r.new_sensitivity is not None and r.old_sensitivity
            else None
        )
        rows.append(
            [
                r.task.run_id,
                r.task.started_utc.isoformat(),
                r.task.dut_id,
                r.task.owner or "",
                " ".join(r.task.certificates),
                _num(r.reference_frequency_hz, "g"),
                _num(r.old_sensitivity),
                _num(r.new_sensitivity),
                _num(ratio, ".9g"),
                _num(r.expanded_uncertainty),
                _num(r.change_in_u, "+.3f"),
                _num(r.worst_change_in_u, "+.3f"),
                _num(r.worst_frequency_hz, "g"),
                r.old_verdict or "",
                r.new_verdict or "",
                "yes" if r.verdict_changed else "no",
                r.problem or "",
            ]
        )
    return csv_text(rows)


def summary_lines(report: ImpactReport) -> list[str]:
    """The report's head as text lines (the CLI prints them; the PDF starts with them)."""
    changed = [r for r in report.checked if r.verdict_changed]
    return [
        f"Reference standard {report.serial}: corrected table sha256 {report.table.sha256}",
        f"Window: {report.window_text()}; {report.runs_in_window} indexed run(s) checked, "
        f"{len(report.runs)} used this reference",
        f"Re-analysed: {len(report.checked)}; could not be checked: {len(report.unchecked)}; "
        f"verdicts changed: {len(changed)}; certificates flagged under review: "
        f"{len(report.flagged)}",
    ]


def to_pdf(report: ImpactReport, lab_name: str = "") -> bytes:
    """The impact report as a PDF (A4 landscape): summary, then one table row per run."""
    from reportlab.lib import colors
    from reportlab.lib.pagesizes import A4, landscape
    from reportlab.lib.styles import getSampleStyleSheet
    from reportlab.lib.units import mm
    from reportlab.platypus import Paragraph, SimpleDocTemplate, Spacer, Table, TableStyle

    styles = getSampleStyleSheet()
    buffer = io.BytesIO()
    title = f"Impact of reference standard {report.serial} (ISO/IEC 17025 7.10)"
    doc = SimpleDocTemplate(
        buffer,
        pagesize=landscape(A4),
        leftMargin=12 * mm,
        rightMargin=12 * mm,
        topMargin=12 * mm,
        bottomMargin=12 * mm,
        title=title,
        author=lab_name or "accelcal",
        invariant=True,
    )
    story: list = [Paragraph(_escape(title), styles["Title"])]
    if lab_name:
        story.append(Paragraph(_escape(lab_name), styles["Normal"]))
    story.extend(Paragraph(_escape(line), styles["Normal"]) for line in summary_lines(report))
    story.append(Spacer(1, 4 * mm))
    small = styles["BodyText"].clone("small", fontSize=7, leading=8.5)
    header = [
        "Run",
        "Started (UTC)",
        "DUT / owner",
        "Certificates",
        "f (Hz)",
        "S old",
        "S new",
        "dS/U",
        "worst dS/U",
        "Verdict",
    ]
    rows: list[list] = [header]
    for r in report.runs:
        if r.problem:
            rows.append(
                [
                    Paragraph(_escape(r.task.run_id), small),
                    r.task.started_utc.strftime("%Y-%m-%d %H:%M"),
                    Paragraph(_escape(f"{r.task.dut_id} / {r.task.owner or '-'}"), small),
                    Paragraph(_escape(" ".join(r.task.certificates) or "-"), small),
                    Paragraph(_escape(f"not checked: {r.problem}"), small),
                    "",
                    "",
                    "",
                    "",
                    "",
                ]
            )
            continue
        verdict = f"{r.old_verdict} -> {r.new_verdict}" if r.verdict_changed else str(r.new_verdict)
        worst = (
            f"{r.worst_change_in_u:+.2f} @ {r.worst_frequency_hz:g} Hz"
            if r.worst_change_in_u is not None
            else "-"
        )
        rows.append(
            [
                Paragraph(_escape(r.task.run_id), small),
                r.task.started_utc.strftime("%Y-%m-%d %H:%M"),
                Paragraph(_escape(f"{r.task.dut_id} / {r.task.owner or '-'}"), small),
                Paragraph(_escape(" ".join(r.task.certificates) or "-"), small),
                _num(r.reference_frequency_hz, "g"),
                _num(r.old_sensitivity, ".6g"),
                _num(r.new_sensitivity, ".6g"),
                _num(r.change_in_u, "+.2f"),
                worst,
                verdict,
            ]
        )
    widths = [m * mm for m in (52, 26, 40, 34, 24, 20, 20, 14, 28, 40)]
    table = Table(rows, colWidths=widths, repeatRows=1)
    table.setStyle(
        TableStyle(
            [
                ("FONTSIZE", (0, 0), (-1, -1), 7),
                ("BACKGROUND", (0, 0), (-1, 0), colors.lightgrey),
                ("GRID", (0, 0), (-1, -1), 0.25, colors.grey),
                ("VALIGN", (0, 0), (-1, -1), "TOP"),
            ]
        )
    )
    story.append(table)
    story.append(Spacer(1, 4 * mm))
    story.append(
        Paragraph(
            "S in mV/(m/s^2) at the reference frequency; old: re-analysed with the stored "
            "reference table, new: with the corrected one, both from the raw recording through "
            "the same analysis; dS/U: the change in units of the old expanded uncertainty.",
            small,
        )
    )
    doc.build(story)
    return buffer.getvalue()


def notices(report: ImpactReport, lab_name: str = "") -> dict[str, str]:
    """A draft notice per customer (by customer name; runs of unknown owner under "(no
    owner on record)"), plain text listing their certificates and what changes."""
    by_owner: dict[str, list[RunImpact]] = {}
    for r in report.runs:
        by_owner.setdefault(r.task.owner or "(no owner on record)", []).append(r)
    out: dict[str, str] = {}
    for owner, runs in sorted(by_owner.items()):
        lines = [
            f"DRAFT - to be reviewed before sending{f' ({lab_name})' if lab_name else ''}",
            "",
            f"To: {owner}",
            "Subject: calibration results that used reference standard "
            f"{report.serial} ({report.window_text()})",
            "",
            f"A reference standard used for your calibrations ({report.serial}) was found to "
            "deviate from its calibration table at its recalibration. We recomputed each of "
            "your results below from its raw recording with the corrected table.",
            "",
        ]
        for r in runs:
            certificates = ", ".join(r.task.certificates) or "no certificate issued"
            lines.append(f"- sensor {r.task.dut_id}, run {r.task.run_id} ({certificates}):")
            if r.problem:
                lines.append("    could not be recomputed; we are reviewing it by hand")
                continue
            lines.append(
                f"    sensitivity at {r.reference_frequency_hz:g} Hz: {r.old_sensitivity:.5g} "
                f"-> {r.new_sensitivity:.5g} mV/(m/s^2) ({r.change_in_u:+.2f} times the stated "
                "expanded uncertainty)"
                if r.change_in_u is not None
                else f"    sensitivity: {r.old_sensitivity} -> {r.new_sensitivity} mV/(m/s^2)"
            )
            if r.verdict_changed:
                lines.append(f"    statement of conformity: {r.old_verdict} -> {r.new_verdict}")
        lines += [
            "",
            "Each certificate concerned is under review; we will confirm it or issue an "
            "amended certificate and tell you which.",
        ]
        out[owner] = "\n".join(lines) + "\n"
    return out


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


def owners(runs: Sequence[RunImpact]) -> list[str]:
    """The customers concerned, sorted."""
    return sorted({r.task.owner for r in runs if r.task.owner})
