"""Several DUTs in one run (issue 36): column `runs.batch_id`, the batch a run was one DUT of
(its config.json "batch" link, app.records.run_start.BatchLink); NULL for a single-DUT run,
every run indexed before this revision included. Indexed: a sensor's history lists the runs it
shared by it.

Revision ID: 0015
Revises: 0014
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0015"
down_revision = "0014"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("runs", sa.Column("batch_id", sa.String(100), nullable=True))
    op.create_index("ix_runs_batch_id", "runs", ["batch_id"])


def downgrade() -> None:
    op.drop_index("ix_runs_batch_id", table_name="runs")
    op.drop_column("runs", "batch_id")
