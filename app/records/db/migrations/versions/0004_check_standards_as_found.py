"""Check standards (a sensor measured regularly on each stand for a control chart) and
as-found results on a certificate when a sensor is adjusted (the certified run is as-left).

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("sensors") as batch:
        batch.add_column(
            sa.Column("check_standard", sa.Boolean, nullable=False, server_default=sa.false())
        )
    with op.batch_alter_table("certificates") as batch:
        batch.add_column(
            sa.Column(
                "as_found_run_id",
                sa.Integer,
                sa.ForeignKey("runs.id", name="fk_certificates_as_found_run"),
                nullable=True,
            )
        )


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
