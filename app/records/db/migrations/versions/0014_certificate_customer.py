"""The customer each certificate is issued to (issue 35 point 5, ISO/IEC 17025 4.2): column
`certificates.customer_id`, set at issue from the sensor's owner (the customer the PDF names)
and never changed, so a sensor sold to another customer takes none of its certificates along.

Rows issued before this revision are bound to the sensor's owner at upgrade (docs/records.md).
Filling them is an UPDATE the certificates' rules (migration 0011) refuse, so the upgrade
(the owner role) sets them aside for that one statement: on PostgreSQL the rule's trigger is
disabled and enabled ALWAYS again, and the column made NOT NULL; on SQLite the rule triggers
are dropped and recreated over the new columns (their frozen list then holds customer_id) and
a trigger refuses an INSERT without a customer (ALTER TABLE cannot add a NOT NULL column
there). On PostgreSQL the rule freezes every column of an issued certificate already, this
one included. The journal notes every filled row; the upgrade enters them in the chain
(app.records.db.chain_check.after_migration).

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from app.records.db.chain_rules import (
    SQLITE_CERTIFICATE_RULES,
    sqlite_customer_rule,
    sqlite_rules,
)

revision = "0014"
down_revision = "0013"
branch_labels = None
depends_on = None

FILL = (
    "UPDATE certificates SET customer_id = "
    "(SELECT owner_id FROM sensors WHERE sensors.id = certificates.sensor_id)"
)


def upgrade() -> None:
    bind = op.get_bind()
    if bind.dialect.name == "postgresql":
        op.add_column(
            "certificates",
            sa.Column(
                "customer_id",
                sa.Integer,
                sa.ForeignKey("customers.id", name="fk_certificates_customer"),
                nullable=True,
            ),
        )
        op.execute("ALTER TABLE certificates DISABLE TRIGGER records_rule_certificates")
        op.execute(FILL)
        op.execute("ALTER TABLE certificates ENABLE ALWAYS TRIGGER records_rule_certificates")
        op.alter_column("certificates", "customer_id", nullable=False)
    else:
        op.execute(
            "ALTER TABLE certificates ADD COLUMN customer_id INTEGER REFERENCES customers (id)"
        )
        for name in SQLITE_CERTIFICATE_RULES:
            op.execute(f"DROP TRIGGER {name}")
        op.execute(FILL)
        columns = [c["name"] for c in sa.inspect(bind).get_columns("certificates")]
        for statement in sqlite_rules(columns):
            op.execute(statement)
        op.execute(sqlite_customer_rule())
    op.create_index("ix_certificates_customer", "certificates", ["customer_id"])


def downgrade() -> None:
    raise RuntimeError("records are never downgraded: restore a backup instead")
