"""The records' hash chain: `records_chain` (append-only, one SHA-256-linked entry per write to
an audited table) and `records_journal` (a trigger on every audited table notes each row
change, whoever makes it). The existing rows are entered into the chain by the upgrade itself
(app.records.db.chain_check.after_migration), once the schema is at its target.

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain import (
    PG_JOURNAL_FUNCTION,
    append_only_sql,
    journal_trigger_sql,
)

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None

# the audited tables at this revision and their primary keys (a later migration that adds an
# audited table adds its journal trigger with app.records.db.chain.journal_trigger_sql)
AUDITED = {
    "audit_trail": "id",
    "certificates": "id",
    "customers": "id",
    "reference_points": "id",
    "reference_standards": "id",
    "run_templates": "id",
    "runs": "id",
    "sensor_models": "id",
    "sensors": "id",
    "settings": "key",
    "stands": "id",
    "users": "id",
}


def upgrade() -> None:
    op.create_table(
        "records_chain",
        sa.Column("seq", sa.Integer, primary_key=True, autoincrement=False),
        sa.Column("at_utc", sa.String(40), nullable=False),
        sa.Column("actor", sa.String(200), nullable=False),
        sa.Column("action", sa.String(10), nullable=False),
        sa.Column("table_name", sa.String(100), nullable=False),
        sa.Column("row_key", sa.String(200), nullable=False),
        sa.Column("row", sa.Text, nullable=True),
        sa.Column("journal_id", sa.Integer, nullable=True),
        sa.Column("schema_fingerprint", sa.String(100), nullable=False),
        sa.Column("prev_hash", sa.String(64), nullable=False),
        sa.Column("hash", sa.String(64), nullable=False),
        sa.UniqueConstraint("journal_id", name="uq_records_chain_journal_id"),
        sa.UniqueConstraint("prev_hash", name="uq_records_chain_prev_hash"),
        sa.UniqueConstraint("hash", name="uq_records_chain_hash"),
    )
    op.create_table(
        "records_journal",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("table_name", sa.String(100), nullable=False),
        sa.Column("row_key", sa.String(200), nullable=False),
        sa.Column("action", sa.String(10), nullable=False),
        sqlite_autoincrement=True,
    )
    op.create_index("ix_records_journal_row", "records_journal", ["table_name", "row_key"])
    dialect = op.get_bind().dialect.name
    if dialect == "postgresql":
        op.execute(PG_JOURNAL_FUNCTION)
    for table in ("records_chain", "records_journal"):
        for statement in append_only_sql(dialect, table):
            op.execute(statement)
    for table, key in AUDITED.items():
        for statement in journal_trigger_sql(dialect, table, key):
            op.execute(statement)
    if dialect == "postgresql":  # the older append-only trigger also fires under replica
        op.execute("ALTER TABLE audit_trail ENABLE ALWAYS TRIGGER audit_trail_append_only")


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
