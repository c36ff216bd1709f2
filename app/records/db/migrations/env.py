"""Alembic environment: runs migrations on the connection app.records.db.engine hands over."""

from __future__ import annotations

from alembic import context

from app.records.db.models import Base

target_metadata = Base.metadata


def run_migrations_online() -> None:
    """Migrate over the connection in config.attributes['connection'] (always given)."""
    connection = context.config.attributes["connection"]
    context.configure(connection=connection, target_metadata=target_metadata)
    with context.begin_transaction():
        context.run_migrations()


if context.is_offline_mode():
    raise RuntimeError("accelcal migrations run online only (accelcal db upgrade)")
run_migrations_online()
