"""The files of each certificate in its register row: the PDF's absolute path, its SHA-256 and
its DCC's (nullable: rows entered before this revision have none). Written in the issuing
transaction, before the files take their final names (crash-safe issuance, issue 23 point 4).

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("certificates") as batch:
        batch.add_column(sa.Column("file", sa.Text, nullable=True))
        batch.add_column(sa.Column("sha256", sa.String(64), nullable=True))
        batch.add_column(sa.Column("dcc_sha256", sa.String(64), nullable=True))


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
