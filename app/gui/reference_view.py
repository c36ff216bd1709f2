"""What the Setup tab says about the reference standard: the one the run will use, from the
stand file loaded (its [reference] table), and what the records know of it (certificate, due
date, expired). It reads; the due-date rule itself is the records' (`Lab.reference_for_run`,
through `app.records.db.runs.reference_due_note`, the CLI's own check): Start refuses a reference
standard past its due date unless an override reason is typed, as `run --reference-override`.
"""

from __future__ import annotations

import html
import logging
from datetime import UTC, date, datetime
from typing import Any

from PySide6.QtWidgets import QInputDialog

from app.gui.field_marks import ERROR
from app.records.db.errors import RecordsInputError

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
        lines.append("<i>not in the records (the stand file's data is used)</i>")
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


def reference_allows_run(setup: Any, today: date) -> tuple[bool, str | None]:
    """Whether Start may go on with the Setup tab's reference standard on `today`, and a note
    to show (when refused: the refusal). Past its due date on record: the refusal names the
    date and asks an override reason; without one nothing starts and the refusal is shown at
    the reference standard. Records not open: not checked here (the run still records to its
    folder), as the CLI."""
    from app.records.db.runs import reference_due_note

    lab = setup.records.lab
    marks = setup.field_marks
    marks.note(setup.reference_label, None)
    if lab is None:
        return True, None
    reference_id = setup.config.reference.id
    try:
        return True, reference_due_note(lab, reference_id, today=today, override_reason=None)
    except RecordsInputError as exc:
        refusal = str(exc)
    reason, ok = QInputDialog.getText(
        setup,
        "Reference standard past its due date",
        f"{refusal}.\n\nOverride reason (required to run; kept in the log):",
    )
    if not ok or not reason.strip():
        marks.note(setup.reference_label, f"Start refused: {refusal}", ERROR)
        return False, f"Start refused: {refusal}"
    try:
        note = reference_due_note(lab, reference_id, today=today, override_reason=reason.strip())
    except RecordsInputError as exc:  # the records changed meanwhile
        marks.note(setup.reference_label, f"Start refused: {exc}", ERROR)
        return False, None
    log.warning("%s", note)
    return True, note
