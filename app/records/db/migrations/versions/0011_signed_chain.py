"""Authenticated records (issue 33): every chain head signed with the records key (columns
`signature`, `key_id` of records_chain; the public keys in `records_keys`, append-only), an
index of the chain by row (the quick check compares every live row with its newest entry), and
the business rules the database enforces for every role (app.records.db.chain_rules).

The records key itself is made by `accelcal db upgrade` before it migrates
(app.records.db.records_key), never stored here; the rows are re-entered and the new head
signed by the upgrade (app.records.db.chain_check.after_migration).

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain import KEYS_TABLE, append_only_sql
from app.records.db.chain_rules import postgresql_rules, sqlite_rules

revision = "0011"
down_revision = "0010"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("records_chain", sa.Column("signature", sa.String(128), nullable=True))
    op.add_column("records_chain", sa.Column("key_id", sa.String(64), nullable=True))
    op.create_index("ix_records_chain_row", "records_chain", ["table_name", "row_key"])
    op.create_table(
        KEYS_TABLE,
        sa.Column("key_id", sa.String(64), primary_key=True),
        sa.Column("public_key", sa.String(64), nullable=False),
        sa.Column("created_utc", sa.String(40), nullable=False),
    )
    bind = op.get_bind()
    dialect = bind.dialect.name
    for statement in append_only_sql(dialect, KEYS_TABLE):
        op.execute(statement)
    if dialect == "postgresql":
        for statement in postgresql_rules():
            op.execute(statement)
    else:
        columns = [c["name"] for c in sa.inspect(bind).get_columns("certificates")]
        for statement in sqlite_rules(columns):
            op.execute(statement)


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
