"""What the Setup tab says about the reference standard: the one the run will use, from the
stand file loaded (its [reference] table), and what the records know of it (certificate, due
date, expired). It reads; the rule itself is the CLI's (`app.procedure.reference`, applied by
`build_request`): Start refuses a reference standard not on record or past its due date unless
an override reason is typed, as `run --reference-override`.
"""

from __future__ import annotations

import html
import logging
from datetime import UTC, date, datetime
from typing import Any

from PySide6.QtWidgets import QInputDialog

from app.gui.field_marks import ERROR
from app.procedure.reference import simulators_own
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


def reference_allows_run(setup: Any, today: date) -> tuple[bool, str | None, str | None]:
    """Whether Start may go on with the Setup tab's reference standard on `today`, the refusal
    to show (None when allowed) and the override reason typed (None: none needed). The rule is
    the CLI's (`app.procedure.reference`, as `build_request` applies it): not on record or
    past its due date, the refusal is shown and an override reason asked; without one nothing
    starts and the refusal is marked at the reference standard; a stand-file table that
    differs from the records' cannot be overridden. Records not open: not checked here (the
    run still records to its folder), as the CLI."""
    from app.procedure.reference import ReferenceRefusal, reference_from_records
    from app.records.db.audit import current_actor

    lab = setup.records.lab
    marks = setup.field_marks
    marks.note(setup.reference_label, None)
    if lab is None:
        return True, None, None

    def check(reason: str | None) -> None:
        resolved = reference_from_records(
            setup.config, lab, override_reason=reason, who=current_actor(), today=today
        )
        for note in resolved.notes if resolved.overrides else ():
            log.warning("%s", note)

    def refuse(refusal: str) -> tuple[bool, str | None, str | None]:
        marks.note(setup.reference_label, f"Start refused: {refusal}", ERROR)
        return False, f"Start refused: {refusal}", None

    try:
        check(None)
        return True, None, None
    except ReferenceRefusal as exc:
        if not exc.overridable:
            return refuse(str(exc))
        refusal = str(exc)
    except RecordsInputError as exc:
        return refuse(str(exc))
    reason, ok = QInputDialog.getText(
        setup,
        "Reference standard not usable as on record",
        f"{refusal}.\n\nOverride reason (required to run; recorded with the run, in the "
        "audit trail and on the certificate):",
    )
    if not ok or not reason.strip():
        return refuse(refusal)
    try:
        check(reason.strip())
    except (ReferenceRefusal, RecordsInputError) as exc:  # the records changed meanwhile
        return refuse(str(exc))
    return True, None, reason.strip()
