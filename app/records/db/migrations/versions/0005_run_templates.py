"""Run templates: named run settings per sensor model (plan preset and lines, level, periods or
type A target, time bound, tolerance, estimator), chosen from a list in the GUI and saved
from a run's settings. Audited like every table (app.records.db.audit covers any mapped row).

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-25
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "run_templates",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column(
            "model_id",
            sa.Integer,
            sa.ForeignKey("sensor_models.id", name="fk_run_templates_model"),
            nullable=False,
        ),
        sa.Column("name", sa.String(100), nullable=False),
        sa.Column("preset", sa.String(40), nullable=False),
        sa.Column("frequencies_hz", sa.Text, nullable=True),
        sa.Column("level_ms2", sa.Float, nullable=False),
        sa.Column("periods", sa.Integer, nullable=False),
        sa.Column("target_type_a", sa.Float, nullable=True),
        sa.Column("max_acquisition_s", sa.Float, nullable=True),
        sa.Column("tolerance_percent", sa.Float, nullable=True),
        sa.Column("estimator", sa.String(20), nullable=False),
        sa.UniqueConstraint("model_id", "name", name="uq_run_templates_model_name"),
        sa.CheckConstraint("level_ms2 > 0", name="level_positive"),
        sa.CheckConstraint("periods >= 2", name="periods_enough"),
    )


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
