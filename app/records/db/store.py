"""The records' ground floor: a session over the lab's engine whose flushes are audited and keep
the sensors' due dates, the refusal every records check raises (naming the field), and the
small checks and calendar arithmetic every part of the records shares.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from datetime import UTC, date, datetime
from typing import Any

from sqlalchemy import Engine, event
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from app.records.db import audit
from app.records.db.errors import RecordsInputError
from app.records.db.models import Run, Sensor
from app.records.run_folder import STATUS_COMPLETE


class RecordsError(RecordsInputError):
    """A refused write or an unknown record; the message names the field and the reason."""


def text_field(value: str | None, field: str, *, max_len: int = 200) -> str:
    text = (value or "").strip()
    if not text:
        raise RecordsError(f"{field}: must not be blank")
    if len(text) > max_len:
        raise RecordsError(f"{field}: longer than {max_len} characters")
    return text


def number_field(value: float, field: str, *, low: float, high: float) -> float:
    if not (math.isfinite(value) and low < value <= high):
        raise RecordsError(f"{field}: must be in ({low:g}, {high:g}], got {value!r}")
    return float(value)


def add_months(day: date, months: int) -> date:
    """`day` plus whole calendar months (the last day of the month when it has fewer days)."""
    month_index = day.month - 1 + months
    year, month = day.year + month_index // 12, month_index % 12 + 1
    for last in (31, 30, 29, 28):
        with contextlib.suppress(ValueError):
            return date(year, month, min(day.day, last))
    raise AssertionError("unreachable")


class Store:
    """The records of one lab over one database engine, as sessions (the parts of `Lab` share
    it)."""

    def __init__(self, engine: Engine, *, actor: str | None = None) -> None:
        self.engine = engine
        self.actor = actor or audit.current_actor()

    @contextlib.contextmanager
    def session(self) -> Iterator[Session]:
        """A session whose flushes are audited; committed at the end, rolled back on error."""
        with Session(self.engine, expire_on_commit=False) as session:
            session.info["actor"] = self.actor
            event.listen(session, "before_flush", _keep_sensor_due_dates)
            audit.install(session)  # after: the trail sees the due dates it changed
            try:
                yield session
                session.commit()
            except IntegrityError as exc:
                session.rollback()
                raise RecordsError(integrity_message(exc)) from None
            except BaseException:
                session.rollback()
                raise


def _keep_sensor_due_dates(session: Session, _context: Any, _instances: Any) -> None:
    """A new complete run of a sensor moves the sensor's last calibration and due date."""
    for obj in list(session.new):
        if not isinstance(obj, Run) or obj.status != STATUS_COMPLETE:
            continue
        sensor = obj.sensor
        if sensor is None and obj.sensor_id is not None:
            sensor = session.get(Sensor, obj.sensor_id)
        if sensor is None:
            continue
        started = utc(obj.started_utc)
        last = sensor.last_calibrated_utc
        if last is None or utc(last) < started:
            sensor.last_calibrated_utc = started
            sensor.due_date = add_months(started.date(), sensor.interval_months)


def utc(moment: datetime) -> datetime:
    """`moment` as an aware UTC time (SQLite hands back naive UTC)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


def integrity_message(exc: IntegrityError) -> str:
    text = str(exc.orig).splitlines()[0] if exc.orig is not None else str(exc)
    return f"refused by the database: {text}"
