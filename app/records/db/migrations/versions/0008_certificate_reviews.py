"""Certificate reviews (ISO/IEC 17025 7.10): a certificate flagged "under review" with its
subject (e.g. the impact of a reference standard), reason, opening time and, once decided, the
outcome (amended or confirmed). The certificates table itself is unchanged.

Revision ID: 0008
Revises: 0007 (the records' hash chain: this table is audited, so it gets its
journal trigger like every audited table)
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain import journal_trigger_sql

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "certificate_reviews",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("certificate_id", sa.Integer, sa.ForeignKey("certificates.id"), nullable=False),
        sa.Column("subject", sa.String(200), nullable=False),
        sa.Column("reason", sa.Text, nullable=False),
        sa.Column("opened_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("outcome", sa.String(20), nullable=True),
        sa.Column("closed_utc", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "outcome IS NULL OR outcome IN ('amended', 'confirmed')", name="outcome"
        ),
    )
    op.create_index("ix_certificate_reviews_certificate", "certificate_reviews", ["certificate_id"])
    for statement in journal_trigger_sql(op.get_bind().dialect.name, "certificate_reviews", "id"):
        op.execute(statement)


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
