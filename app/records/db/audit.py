"""The audit trail: every ORM write to the records adds who, when and what changed.

A `before_flush` hook on the records session writes one AuditEntry per inserted, updated or
deleted row, in the same transaction as the change, so a change and its trail commit or
roll back together. The table itself refuses UPDATE and DELETE (triggers, migration 0001).
Every row written through the ORM, audit entries included, is also chained (app.records.db.chain,
whose mapper events are installed by importing it here).
"""

from __future__ import annotations

import json
from datetime import UTC, date, datetime
from typing import Any

from sqlalchemy import event, inspect
from sqlalchemy.orm import Session

from app.records.db.chain import current_actor  # importing chain installs its events
from app.records.db.models import AuditEntry, Base


def _plain(value: Any) -> Any:
    if isinstance(value, datetime | date):
        return value.isoformat()
    return value


def _row_key(obj: Base) -> str:
    mapper = inspect(obj).mapper
    for name in ("serial", "number", "run_id", "identifier", "name", "key", "prefix"):
        if name in mapper.columns:
            return str(getattr(obj, name))
    return str(inspect(obj).identity or "new")


def _changes(obj: Base, action: str) -> dict[str, Any]:
    state = inspect(obj)
    result: dict[str, Any] = {}
    for attr in state.mapper.column_attrs:
        history = state.attrs[attr.key].history
        if action == "insert":
            result[attr.key] = _plain(getattr(obj, attr.key))
        elif action == "update" and history.has_changes():
            old = history.deleted[0] if history.deleted else None
            new = history.added[0] if history.added else None
            result[attr.key] = [_plain(old), _plain(new)]
        elif action == "delete":
            result[attr.key] = _plain(getattr(obj, attr.key))
    return result


def _before_flush(session: Session, _context: Any, _instances: Any) -> None:
    actor = session.info.get("actor") or current_actor()
    now = datetime.now(UTC)
    entries = []
    for action, objects in (
        ("insert", session.new),
        ("update", session.dirty),
        ("delete", session.deleted),
    ):
        for obj in objects:
            if isinstance(obj, AuditEntry) or not isinstance(obj, Base):
                continue
            if action == "update" and not session.is_modified(obj, include_collections=False):
                continue
            changes = _changes(obj, action)
            entries.append(
                AuditEntry(
                    at_utc=now,
                    actor=actor,
                    action=action,
                    table_name=obj.__tablename__,
                    row_key=_row_key(obj),
                    changes=json.dumps(changes, sort_keys=True, default=str),
                )
            )
    session.add_all(entries)


def install(session: Session) -> None:
    """Audit every flush of `session`."""
    event.listen(session, "before_flush", _before_flush)
