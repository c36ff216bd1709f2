"""How a certificate review was closed (ISO/IEC 17025 7.10): who closed it, why, and for an
amendment the number of the certificate that replaces the reviewed one. Nullable: reviews
opened before this revision, and open ones, have none.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("certificate_reviews") as batch:
        batch.add_column(sa.Column("closed_by", sa.String(200), nullable=True))
        batch.add_column(sa.Column("close_reason", sa.Text, nullable=True))
        batch.add_column(sa.Column("amended_by", sa.String(100), nullable=True))


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
