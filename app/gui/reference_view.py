"""What the Setup tab says about the reference standard: the one the run will use, from the
stand file loaded (its [reference] table), and what the records know of it (certificate, due
date, expired). It reads and asks; the rule itself is the run service's (app.procedure.service,
evaluated once per Start): Start refuses a reference standard not on record or past its due
date unless an override reason is typed, as `run --reference-override`.
"""

from __future__ import annotations

import html
import logging
from datetime import UTC, date, datetime
from typing import Any

from PySide6.QtWidgets import QInputDialog

from app.gui.field_marks import ERROR
from app.procedure.reference import simulators_own

log = logging.getLogger(__name__)


def describe_reference(config: Any, link: Any = None, today: date | None = None) -> str:
    """Rich text: the reference standard of `config` and its record in `link` (RecordsLink)."""
    ref = config.reference
    today = today or datetime.now(UTC).date()
    simulated = config.backend == "sim"
    origin = "the simulated stand" if simulated else f"the stand file {config.source}"
    table = (
        f"sensitivity table of {len(ref.frequencies_hz)} frequencies"
        if ref.frequencies_hz
        else "sensitivity from its certificate"
        + (" (the simulated stand issues its own)" if simulated else "")
    )
    lines = [
        f"<b>{html.escape(ref.id)}</b>: {html.escape(ref.model)}, serial {html.escape(ref.serial)}",
        f"certificate {html.escape(ref.certificate_number)} of "
        f"{html.escape(ref.certificate_date)}; {table}; from {html.escape(origin)}",
    ]
    if link is None or getattr(link, "lab", None) is None:
        why = "opening ..." if link is not None and link.opening else "not available"
        lines.append(f"<i>records: {why}; due date not checked here</i>")
        return "<br/>".join(lines)
    record = link.reference(ref.id)
    if record is None:
        lines.append(
            "<i>not in the records: the simulator's own reference standard, used as such "
            "(a real stand's must be on record)</i>"
            if simulators_own(config)
            else "<i>not in the records (the stand file's data is used)</i>"
        )
    elif record.due_date < today:
        lines.append(
            f"<span style='color:#c0392b'><b>records: EXPIRED, due on {record.due_date}</b> "
            f"(certificate {html.escape(record.certificate_number)}); recalibrate it or "
            "record an override reason</span>"
        )
    else:
        lines.append(
            f"<span style='color:#1e8449'>records: certificate "
            f"{html.escape(record.certificate_number)} of {record.calibration_date}, due on "
            f"{record.due_date}</span>"
        )
    return "<br/>".join(lines)


def ask_override(setup: Any, refusal: str) -> str | None:
    """Ask the operator for an override reason for the reference standard's `refusal` (the
    run service's rule, as `run --reference-override`); the reason typed, None when cancelled
    or blank."""
    reason, ok = QInputDialog.getText(
        setup,
        "Reference standard not usable as on record",
        f"{refusal}.\n\nOverride reason (required to run; recorded with the run, in the "
        "audit trail and on the certificate):",
    )
    return reason.strip() if ok and reason.strip() else None


def mark_refusal(setup: Any, refusal: str) -> str:
    """Mark Start's refusal at the reference standard; the line to show."""
    text = f"Start refused: {refusal}"
    setup.field_marks.note(setup.reference_label, text, ERROR)
    return text
