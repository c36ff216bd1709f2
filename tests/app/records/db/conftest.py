"""Records tests run on SQLite and on a real PostgreSQL 16 the session starts itself (pgserver,
in a temporary folder). With CI=true a PostgreSQL that cannot start fails the suite."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from sqlalchemy import Engine, text

from app.records.db.engine import make_engine, resolve_url, upgrade
from tests.pg_server import start_pgserver

_counter = itertools.count()


@pytest.fixture(scope="session")
def postgres_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """The URL of a PostgreSQL server private to this test session."""
    try:
        # tmp_path_factory is per xdist worker: each worker has a server of its own
        server = start_pgserver(tmp_path_factory.mktemp("pg"))
    except Exception as exc:  # no wheel, no start
        if os.environ.get("CI") == "true":
            pytest.fail(f"PostgreSQL could not start in CI: {exc}")
        pytest.skip(f"PostgreSQL could not start: {exc}")
    try:
        yield server.get_uri()
    finally:
        server.cleanup()


def _postgres_database(server_url: str) -> str:
    """A new empty database on the session's server; its URL."""
    name = f"accelcal_test_{os.getpid()}_{next(_counter)}"
    admin = make_engine(resolve_url(server_url))
    with admin.connect().execution_options(isolation_level="AUTOCOMMIT") as conn:
        conn.execute(text(f'CREATE DATABASE "{name}"'))
    admin.dispose()
    base, _, query = server_url.partition("?")
    return f"{base.rsplit('/', 1)[0]}/{name}?{query}"


@pytest.fixture(params=["sqlite", "postgresql"])
def empty_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    """The URL of an empty database (no schema) on each engine."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'records.sqlite'}"
    return resolve_url(_postgres_database(request.getfixturevalue("postgres_server")))


@pytest.fixture
def engine(empty_url: str) -> Iterator[Engine]:
    """An engine on a database migrated to the newest schema."""
    engine = make_engine(resolve_url(empty_url))
    upgrade(engine)
    yield engine
    engine.dispose()
