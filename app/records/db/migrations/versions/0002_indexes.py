"""Indexes for the due list and a sensor's history (bench/records.py: 10 000 sensors,
100 000 runs).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-23
"""

from __future__ import annotations

from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_index("ix_runs_sensor_started", "runs", ["sensor_id", "started_utc"])
    op.create_index("ix_runs_dut_id", "runs", ["dut_id"])
    op.create_index("ix_reference_standards_due", "reference_standards", ["due_date"])
    op.create_index("ix_certificates_run", "certificates", ["run_id"])


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
