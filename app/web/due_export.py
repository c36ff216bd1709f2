"""A customer's due dates as files (issue 35 point 5): CSV (one row per sensor) and iCalendar
(RFC 5545, one all-day event per sensor with a due date, written by the `icalendar` package so
that folding, escaping and CRLF are a maintained library's, not ours).

An event's UID is stable per laboratory and sensor, so a calendar that imports the file again
updates the event when the due date moves (a new calibration) instead of adding a second one.
"""

from __future__ import annotations

import csv
import hashlib
import io
from collections.abc import Sequence
from datetime import UTC, date, datetime, timedelta

from app.web.store import SensorDue

CSV_COLUMNS = ("serial", "model", "interval_months", "last_calibrated", "due", "state")
FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")  # a spreadsheet would run these as formulas
PRODID = "-//accelcal//customer portal due dates//EN"


def due_state(item: SensorDue, today: date) -> str:
    """'never calibrated here', 'overdue' (due before `today`) or 'due' (today or later)."""
    if item.due is None:
        return "never calibrated here"
    return "overdue" if item.due < today else "due"


def _cell(value: str) -> str:
    """A text cell a spreadsheet shows as text (a leading ' before a formula's first
    character, OWASP's CSV-injection advice)."""
    return "'" + value if value.startswith(FORMULA_STARTS) else value


def due_csv(items: Sequence[SensorDue], today: date) -> str:
    """The due dates as CSV (RFC 4180, CRLF; dates ISO 8601; the interval in months)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\r\n")
    writer.writerow(CSV_COLUMNS)
    for item in items:
        last = item.last_calibrated_utc.date().isoformat() if item.last_calibrated_utc else ""
        writer.writerow(
            (
                _cell(item.serial),
                _cell(item.model),
                item.interval_months,
                last,
                item.due.isoformat() if item.due else "",
                due_state(item, today),
            )
        )
    return out.getvalue()


def event_uid(lab: str, serial: str) -> str:
    """The UID of a sensor's due event: stable for the laboratory `lab` (a host name) and the
    sensor, and naming no serial (a SHA-256 prefix)."""
    digest = hashlib.sha256(f"{lab}\x00{serial}".encode()).hexdigest()[:24]
    return f"calibration-due-{digest}@{lab}"


def due_ical(
    items: Sequence[SensorDue], *, lab: str, customer: str, now: datetime | None = None
) -> bytes:
    """The due dates as an iCalendar file (RFC 5545): one all-day VEVENT per sensor with a due
    date, "Calibration due: MODEL, serial SERIAL" (sensors never calibrated here have no date
    and no event)."""
    from icalendar import Calendar, Event

    stamp = (now or datetime.now(UTC)).astimezone(UTC).replace(microsecond=0)
    calendar = Calendar()
    calendar.add("prodid", PRODID)
    calendar.add("version", "2.0")
    calendar.add("calscale", "GREGORIAN")
    calendar.add("x-wr-calname", f"Calibrations due: {customer}")
    for item in items:
        if item.due is None:
            continue
        event = Event()
        event.add("uid", event_uid(lab, item.serial))
        event.add("dtstamp", stamp)
        event.add("dtstart", item.due)
        event.add("dtend", item.due + timedelta(days=1))
        event.add("summary", f"Calibration due: {item.model}, serial {item.serial}")
        event.add(
            "description",
            f"Sensor {item.serial} ({item.model}) is due for calibration on "
            f"{item.due.isoformat()}: its calibration interval is {item.interval_months} months.",
        )
        event.add("transp", "TRANSPARENT")
        calendar.add_component(event)
    return bytes(calendar.to_ical())
