"""Customer accounts of the web view's portal (issue 35 point 5): user name (unique), display
name, the records customer it is bound to, argon2 password hash, active flag and creation time
(UTC). Written only by app.web.accounts (created by staff, audited with the hash left out). The
table is audited, so it gets its journal trigger; on PostgreSQL, as for staff users, only an
administrator adds, re-enables, renames or rebinds an account or sets its password.

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain import journal_trigger_sql
from app.records.db.chain_rules import postgresql_account_rules

revision = "0012"
down_revision = "0011"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "customer_accounts",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("username", sa.String(100), nullable=False),
        sa.Column("display_name", sa.String(200), nullable=False),
        sa.Column("customer_id", sa.Integer, sa.ForeignKey("customers.id"), nullable=False),
        sa.Column("password_hash", sa.String(200), nullable=False),
        sa.Column("active", sa.Boolean, nullable=False),
        sa.Column("created_utc", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("username", name="uq_customer_accounts_username"),
    )
    op.create_index("ix_customer_accounts_customer", "customer_accounts", ["customer_id"])
    dialect = op.get_bind().dialect.name
    for statement in journal_trigger_sql(dialect, "customer_accounts", "id"):
        op.execute(statement)
    if dialect == "postgresql":
        for statement in postgresql_account_rules():
            op.execute(statement)


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
