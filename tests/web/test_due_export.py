"""The due dates' files (app.web.due_export): CSV a spreadsheet cannot run, iCalendar read back
by an independent parser (icalendar's own reader, and the RFC 5545 line rules checked here)."""

from __future__ import annotations

import csv
import io
from datetime import UTC, date, datetime

from icalendar import Calendar

from app.web.due_export import due_csv, due_ical, due_state, event_uid
from app.web.store import SensorDue

TODAY = date(2026, 11, 27)
ITEMS = (
    SensorDue('=HYPERLINK("http://x")', "Evil; model", 12, None, None),
    SensorDue("SN-1", "Sim P-100", 12, datetime(2025, 11, 1, 9, tzinfo=UTC), date(2026, 11, 1)),
    SensorDue(
        "SN-2, long " + "x" * 80,
        "Sim P-100",
        24,
        datetime(2026, 1, 5, tzinfo=UTC),
        date(2028, 1, 5),
    ),
)


def test_the_state_of_a_due_date() -> None:
    assert [due_state(i, TODAY) for i in ITEMS] == ["never calibrated here", "overdue", "due"]
    assert due_state(SensorDue("S", "M", 12, None, TODAY), TODAY) == "due"  # due today


def test_csv_rows_and_no_formula_a_spreadsheet_would_run() -> None:
    text = due_csv(ITEMS, TODAY)
    assert text.endswith("\r\n") and text.count("\r\n") == 4
    rows = list(csv.DictReader(io.StringIO(text)))
    assert rows[0]["serial"] == '\'=HYPERLINK("http://x")' and rows[0]["due"] == ""
    assert rows[1] == {
        "serial": "SN-1",
        "model": "Sim P-100",
        "interval_months": "12",
        "last_calibrated": "2025-11-01",
        "due": "2026-11-01",
        "state": "overdue",
    }
    assert rows[2]["serial"].startswith("SN-2, long")  # a comma quoted, not split


def test_icalendar_events_read_back_and_follow_rfc_5545_lines() -> None:
    now = datetime(2026, 11, 27, 12, 30, 15, 999, tzinfo=UTC)
    data = due_ical(ITEMS, lab="lab.example", customer="ACME Ltd", now=now)
    lines = data.split(b"\r\n")
    assert lines[0] == b"BEGIN:VCALENDAR" and lines[-2] == b"END:VCALENDAR" and lines[-1] == b""
    assert all(len(line) <= 75 for line in lines)  # folded at 75 octets
    assert b"\n" not in data.replace(b"\r\n", b"")  # CRLF only
    calendar = Calendar.from_ical(data)
    assert str(calendar["version"]) == "2.0" and "accelcal" in str(calendar["prodid"])
    events = list(calendar.walk("VEVENT"))
    assert [e.decoded("dtstart") for e in events] == [date(2026, 11, 1), date(2028, 1, 5)]
    assert [e.decoded("dtend") for e in events] == [date(2026, 11, 2), date(2028, 1, 6)]
    assert events[1]["summary"] == f"Calibration due: Sim P-100, serial {ITEMS[2].serial}"
    assert events[0].decoded("dtstamp") == datetime(2026, 11, 27, 12, 30, 15, tzinfo=UTC)
    assert "24 months" in str(events[1]["description"])
    assert [str(e["uid"]) for e in events] == [
        event_uid("lab.example", "SN-1"),
        event_uid("lab.example", ITEMS[2].serial),
    ]


def test_an_events_uid_is_stable_per_lab_and_sensor_and_names_no_serial() -> None:
    uid = event_uid("lab.example", "SN-1")
    assert uid == event_uid("lab.example", "SN-1") and uid.endswith("@lab.example")
    assert uid != event_uid("lab.example", "SN-2") and uid != event_uid("other.example", "SN-1")
    assert "SN-1" not in uid
