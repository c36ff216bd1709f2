"""What a lab does with its records: sensors, reference standards, runs, due dates, history and
the certificate register. Every write is checked first (a refusal names the field) and audited
(app.records.db.audit); every read verifies what it hands over.

`Lab` composes the parts, each in its own module: `store` (sessions, the refusal, shared
checks), `sensors` (customers, models, sensors, run templates), `references` (reference
standards, the due list), `run_index` (runs, history, control charts), `certificates`
(settings and the register) and `reviews` (certificates under review, runs in a window).
The names below are re-exported for the callers of this module.
"""

from __future__ import annotations

from app.records.db.certificates import (
    DEFAULT_PATTERN,
    SETTING_PATTERN,
    SETTING_TWO_PERSON,
    CertificateRegister,
    check_pattern,
    split_pattern,
)
from app.records.db.references import DueItem, ReferenceRecords
from app.records.db.reviews import IndexedRun, Review, ReviewRecords
from app.records.db.run_index import (
    D2_MOVING_RANGE,
    DAYS_PER_YEAR,
    MIN_CONTROL_POINTS,
    MIN_DRIFT_SPAN_DAYS,
    ControlChart,
    History,
    HistoryPoint,
    ImportReport,
    RunIndex,
    drift_percent_per_year,
    individuals_chart,
)
from app.records.db.store import RecordsError, add_months

__all__ = [
    "D2_MOVING_RANGE",
    "DAYS_PER_YEAR",
    "DEFAULT_PATTERN",
    "MIN_CONTROL_POINTS",
    "MIN_DRIFT_SPAN_DAYS",
    "SETTING_PATTERN",
    "SETTING_TWO_PERSON",
    "ControlChart",
    "DueItem",
    "History",
    "HistoryPoint",
    "ImportReport",
    "IndexedRun",
    "Lab",
    "RecordsError",
    "Review",
    "add_months",
    "check_pattern",
    "drift_percent_per_year",
    "individuals_chart",
    "split_pattern",
]


class Lab(RunIndex, CertificateRegister, ReferenceRecords, ReviewRecords):
    """The records of one lab over one database engine (`Lab(engine, actor=...)`)."""
