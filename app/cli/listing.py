"""`--json` of the list commands (customers, models, sensors and refs list, due, register list,
register reviews, records user list, control: one object per stand; history as one object):
a JSON array of objects with
stable keys, printed to stdout for scripts.

Keys are snake_case and carry their unit where they have one (`level_ms2`,
`tolerance_percent`); numbers are JSON numbers, a missing value is null, dates are ISO 8601
(`2026-11-27`) and instants ISO 8601 in UTC with their offset (`2026-11-27T12:30:00+00:00`).
A key is never dropped for a row that lacks its value: every row of a list has the same keys.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from datetime import UTC, date, datetime
from typing import Any

Row = dict[str, Any]


def iso(value: date | datetime | None) -> str | None:
    """ISO 8601: a date as yyyy-mm-dd, an instant in UTC with its offset (a naive one, as
    SQLite returns them, is UTC: the records store UTC only)."""
    if value is None:
        return None
    if isinstance(value, datetime):
        aware = value if value.tzinfo is not None else value.replace(tzinfo=UTC)
        return aware.astimezone(UTC).isoformat()
    return value.isoformat()


def print_rows(rows: Iterable[Mapping[str, Any]]) -> None:
    """The rows as one JSON array (UTF-8 text as it is, not escaped)."""
    print(json.dumps([dict(r) for r in rows], indent=2, ensure_ascii=False, allow_nan=False))


def customer_row(c: Any) -> Row:
    return {"name": c.name, "address": c.address}


def model_row(m: Any) -> Row:
    return {
        "maker": m.maker,
        "model": m.model,
        "nominal_sensitivity": m.nominal_sensitivity,
        "unit": m.unit,
        "tolerance_percent": m.tolerance_percent,
        "frequency_min_hz": m.frequency_min_hz,
        "frequency_max_hz": m.frequency_max_hz,
        "preset": m.preset,
        "level_ms2": m.level_ms2,
        "phase_tolerance_deg": m.phase_tolerance_deg,
    }


def sensor_row(s: Any) -> Row:
    return {
        "serial": s.serial,
        "maker": s.model.maker,
        "model": s.model.model,
        "owner": s.owner.name,
        "interval_months": s.interval_months,
        "teds_identity": s.teds_identity,
        "check_standard": bool(s.check_standard),
        "last_calibrated_utc": iso(s.last_calibrated_utc),
        "due_date": iso(s.due_date),
    }


def reference_row(r: Any) -> Row:
    return {
        "identifier": r.identifier,
        "model": r.model,
        "serial": r.serial,
        "certificate_number": r.certificate_number,
        "calibration_date": iso(r.calibration_date),
        "due_date": iso(r.due_date),
        "table_rows": len(r.points),
    }


def due_row(item: Any, today: date) -> Row:
    return {
        "kind": item.kind,
        "identifier": item.identifier,
        "owner": item.owner,
        "due_date": iso(item.due),
        "overdue": item.due is not None and item.due < today,
    }


def certificate_row(c: Any, under_review: Mapping[str, str]) -> Row:
    return {
        "number": c.number,
        "state": c.state,
        "reason": c.reason,
        "issued_utc": iso(c.issued_utc),
        "run_id": c.run.run_id,
        "sensor_serial": c.sensor.serial,
        "prepared_by": c.prepared_by,
        "approved_by": c.approved_by,
        "replaces": c.replaces,
        "as_found_run_id": c.as_found_run.run_id if c.as_found_run is not None else None,
        "under_review": under_review.get(c.number),
    }


def review_row(r: Any) -> Row:
    return {
        "number": r.number,
        "subject": r.subject,
        "reason": r.reason,
        "opened_utc": iso(r.opened_utc),
    }


def user_row(u: Any) -> Row:
    return {
        "username": u.username,
        "display_name": u.display_name,
        "active": bool(u.active),
        "created_utc": iso(u.created_utc),
    }


def account_row(a: Any) -> Row:
    """`records account list --json`: a customer's portal account (no hash)."""
    return {
        "username": a.username,
        "display_name": a.display_name,
        "customer": a.customer,
        "active": bool(a.active),
        "created_utc": iso(a.created_utc),
    }


def history_object(history: Any) -> Row:
    """`history --json`: the sensor, its calibrations (oldest first) and the fitted drift."""
    return {
        "serial": history.serial,
        "points": [
            {
                "run_id": p.run_id,
                "started_utc": iso(p.started_utc),
                "reference_frequency_hz": p.reference_frequency_hz,
                "sensitivity_mv_per_ms2": p.sensitivity_mv_per_ms2,
                "expanded_uncertainty_mv_per_ms2": p.expanded_uncertainty_mv_per_ms2,
                # one DUT of several in one run (issue 36): the batch, the other DUTs' serials
                **(
                    {"batch_id": p.batch_id, "shared_with": list(p.shared_with)}
                    if getattr(p, "batch_id", None)
                    else {}
                ),
            }
            for p in history.points
        ],
        "drift_percent_per_year": history.drift_percent_per_year,
    }


def control_row(chart: Any) -> Row:
    """`control --json`: one stand's individuals chart of the check standard, mV/(m/s^2)."""
    return {
        "serial": chart.serial,
        "stand": chart.stand,
        "centre_mv_per_ms2": chart.centre,
        "lower_mv_per_ms2": chart.lower,
        "upper_mv_per_ms2": chart.upper,
        "warning": chart.warning,
        "points": [{"run_id": run_id, "sensitivity_mv_per_ms2": v} for run_id, v in chart.points],
    }
