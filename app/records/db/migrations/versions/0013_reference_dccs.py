"""A reference standard's DCC read in (issue 35 point 4): table reference_dccs holds each DCC
with its identity (uniqueIdentifier, calibrating laboratory), its signature as verified, its
SHA-256 and the file itself (base64); the one in force names the reference on every
certificate made with it. Journalled like every records table.

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-27
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain import journal_trigger_sql

revision = "0013"
down_revision = "0012"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "reference_dccs",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column(
            "reference_id", sa.Integer, sa.ForeignKey("reference_standards.id"), nullable=False
        ),
        sa.Column("unique_identifier", sa.String(200), nullable=False),
        sa.Column("laboratory", sa.String(300), nullable=False),
        sa.Column("sha256", sa.String(64), nullable=False),
        sa.Column("signature", sa.String(500), nullable=False),
        sa.Column("file_name", sa.String(255), nullable=False),
        sa.Column("content_base64", sa.Text, nullable=False),
        sa.Column("added_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("in_force", sa.Boolean, nullable=False),
    )
    op.create_index("ix_reference_dccs_reference_id", "reference_dccs", ["reference_id"])
    for statement in journal_trigger_sql(op.get_bind().dialect.name, "reference_dccs", "id"):
        op.execute(statement)


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
