"""The first records schema: customers, sensor models, sensors, reference standards, stands,
runs, settings, the certificate register and the append-only audit trail.

Revision ID: 0001
Revises:
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

_APPEND_ONLY = "the audit trail is append-only"


def upgrade() -> None:
    op.create_table(
        "customers",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(200), nullable=False, unique=True),
        sa.Column("address", sa.Text, nullable=False),
    )
    op.create_table(
        "sensor_models",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("maker", sa.String(100), nullable=False),
        sa.Column("model", sa.String(100), nullable=False),
        sa.Column("nominal_sensitivity", sa.Float, nullable=False),
        sa.Column("unit", sa.String(20), nullable=False),
        sa.Column("tolerance_percent", sa.Float, nullable=False),
        sa.Column("frequency_min_hz", sa.Float, nullable=False),
        sa.Column("frequency_max_hz", sa.Float, nullable=False),
        sa.Column("preset", sa.String(40), nullable=False),
        sa.Column("level_ms2", sa.Float, nullable=False),
        sa.Column("phase_tolerance_deg", sa.Float, nullable=True),
        sa.UniqueConstraint("maker", "model"),
        sa.CheckConstraint("nominal_sensitivity > 0", name="nominal_positive"),
        sa.CheckConstraint("tolerance_percent > 0", name="tolerance_positive"),
        sa.CheckConstraint(
            "frequency_min_hz > 0 AND frequency_max_hz > frequency_min_hz", name="range"
        ),
    )
    op.create_table(
        "sensors",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("serial", sa.String(100), nullable=False, unique=True),
        sa.Column("model_id", sa.Integer, sa.ForeignKey("sensor_models.id"), nullable=False),
        sa.Column("owner_id", sa.Integer, sa.ForeignKey("customers.id"), nullable=False),
        sa.Column("teds_identity", sa.String(100), nullable=True),
        sa.Column("interval_months", sa.Integer, nullable=False),
        sa.CheckConstraint("interval_months > 0", name="interval_positive"),
    )
    op.create_table(
        "reference_standards",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("identifier", sa.String(100), nullable=False, unique=True),
        sa.Column("model", sa.String(100), nullable=False),
        sa.Column("serial", sa.String(100), nullable=False),
        sa.Column("certificate_number", sa.String(100), nullable=False),
        sa.Column("calibration_date", sa.Date, nullable=False),
        sa.Column("due_date", sa.Date, nullable=False),
        sa.CheckConstraint("due_date > calibration_date", name="due_after_calibration"),
    )
    op.create_table(
        "reference_points",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column(
            "reference_id", sa.Integer, sa.ForeignKey("reference_standards.id"), nullable=False
        ),
        sa.Column("frequency_hz", sa.Float, nullable=False),
        sa.Column("sensitivity_mv_per_ms2", sa.Float, nullable=False),
        sa.Column("relative_expanded_uncertainty", sa.Float, nullable=False),
        sa.Column("phase_deg", sa.Float, nullable=True),
        sa.UniqueConstraint("reference_id", "frequency_hz"),
        sa.CheckConstraint("frequency_hz > 0 AND sensitivity_mv_per_ms2 > 0", name="positive"),
    )
    op.create_table(
        "stands",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("stand_file_sha256", sa.String(64), nullable=False, unique=True),
        sa.Column("name", sa.String(200), nullable=False),
    )
    op.create_table(
        "runs",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("run_id", sa.String(100), nullable=False, unique=True),
        sa.Column("manifest_sha256", sa.String(64), nullable=False, unique=True),
        sa.Column("folder", sa.Text, nullable=False),
        sa.Column("status", sa.String(20), nullable=False),
        sa.Column("started_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("dut_id", sa.String(100), nullable=False),
        sa.Column("stand_id", sa.Integer, sa.ForeignKey("stands.id"), nullable=False),
        sa.Column("sensor_id", sa.Integer, sa.ForeignKey("sensors.id"), nullable=True),
        sa.Column("reference_frequency_hz", sa.Float, nullable=True),
        sa.Column("sensitivity_mv_per_ms2", sa.Float, nullable=True),
        sa.Column("expanded_uncertainty_mv_per_ms2", sa.Float, nullable=True),
    )
    op.create_table(
        "settings",
        sa.Column("key", sa.String(100), primary_key=True),
        sa.Column("value", sa.Text, nullable=False),
    )
    op.create_table(
        "register_counters",
        sa.Column("prefix", sa.String(100), primary_key=True),
        sa.Column("last", sa.Integer, nullable=False),
    )
    op.create_table(
        "certificates",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("number", sa.String(100), nullable=False, unique=True),
        sa.Column("prefix", sa.String(100), nullable=False),
        sa.Column("sequence", sa.Integer, nullable=False),
        sa.Column("run_id", sa.Integer, sa.ForeignKey("runs.id"), nullable=False),
        sa.Column("sensor_id", sa.Integer, sa.ForeignKey("sensors.id"), nullable=False),
        sa.Column("state", sa.String(20), nullable=False),
        sa.Column("replaces", sa.String(100), nullable=True),
        sa.Column("reason", sa.Text, nullable=True),
        sa.Column("prepared_by", sa.String(200), nullable=False),
        sa.Column("approved_by", sa.String(200), nullable=False),
        sa.Column("issued_utc", sa.DateTime(timezone=True), nullable=False),
        sa.CheckConstraint("state IN ('issued', 'replaced', 'withdrawn')", name="state"),
        sa.UniqueConstraint("prefix", "sequence"),
    )
    op.create_table(
        "audit_trail",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("at_utc", sa.DateTime(timezone=True), nullable=False),
        sa.Column("actor", sa.String(200), nullable=False),
        sa.Column("action", sa.String(10), nullable=False),
        sa.Column("table_name", sa.String(100), nullable=False),
        sa.Column("row_key", sa.String(200), nullable=False),
        sa.Column("changes", sa.Text, nullable=False),
    )
    if op.get_bind().dialect.name == "postgresql":
        op.execute(
            "CREATE FUNCTION audit_trail_append_only() RETURNS trigger AS $$ BEGIN "
            f"RAISE EXCEPTION '{_APPEND_ONLY}'; END; $$ LANGUAGE plpgsql"
        )
        op.execute(
            "CREATE TRIGGER audit_trail_append_only BEFORE UPDATE OR DELETE ON audit_trail "
            "FOR EACH ROW EXECUTE FUNCTION audit_trail_append_only()"
        )
    else:
        for event in ("UPDATE", "DELETE"):
            op.execute(
                f"CREATE TRIGGER audit_trail_no_{event.lower()} BEFORE {event} ON audit_trail "
                f"BEGIN SELECT RAISE(ABORT, '{_APPEND_ONLY}'); END"
            )


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
