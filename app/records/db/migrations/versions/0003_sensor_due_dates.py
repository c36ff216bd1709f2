"""Each sensor carries the date of its last complete calibration and the due date that follows
from its interval, kept by `db import` in the same transaction as the run, so the due list is
one indexed range query (bench/records.py: 520 ms -> a few ms at 10 000 sensors).

Revision ID: 0003
Revises: 0002
Create Date: 2026-11-23
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    from app.records.db.lab import add_months  # the one month arithmetic, shared with the records

    with op.batch_alter_table("sensors") as batch:
        batch.add_column(sa.Column("last_calibrated_utc", sa.DateTime(timezone=True)))
        batch.add_column(sa.Column("due_date", sa.Date))
    op.create_index("ix_sensors_due_date", "sensors", ["due_date"])
    bind = op.get_bind()
    rows = bind.execute(
        sa.text(
            "SELECT s.id, s.interval_months, max(r.started_utc) FROM sensors s "
            "JOIN runs r ON r.sensor_id = s.id AND r.status = 'complete' "
            "GROUP BY s.id, s.interval_months"
        )
    ).all()
    row: Any
    for row in rows:
        sensor_id, interval, value = row
        # SQLite hands back text from an aggregate, PostgreSQL a datetime
        last = datetime.fromisoformat(value) if isinstance(value, str) else value
        if last.tzinfo is None:
            last = last.replace(tzinfo=UTC)
        bind.execute(
            sa.text(
                "UPDATE sensors SET last_calibrated_utc = :last, due_date = :due WHERE id = :id"
            ),
            {"last": last, "due": add_months(last.date(), int(interval)), "id": sensor_id},
        )


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
