"""Where the records database is and how it is opened, created and migrated.

The URL comes from `--db URL`, else the environment variable ACCELCAL_DB, else an SQLite file
`records.sqlite` in the user's data directory ($ACCELCAL_DATA_DIR, else platformdirs). SQLite
runs in WAL mode with a busy timeout, and every transaction starts with BEGIN IMMEDIATE so two
writers queue instead of failing half-way. PostgreSQL is reached through psycopg 3
(`postgresql://...` URLs are mapped to `postgresql+psycopg://`). A database whose schema is
older than this program's is refused until `accelcal db upgrade`. Nothing here creates a
database as a side effect of opening it: `accelcal db upgrade` (`upgrade`) creates the schema
(and the records key when there is none, app.records.db.records_key), and until then the
records are not in use (`records_url` answers None for a missing default file), so opening the
GUI or running a command never changes what a later command accepts.
"""

from __future__ import annotations

import logging
import os
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

from app.records.db.errors import RecordsInputError

if TYPE_CHECKING:
    from sqlalchemy import Engine

# SQLAlchemy is imported by the functions that use it: knowing whether records are in use
# (`records_url`) must not cost its import (a run without records, issue 34).

log = logging.getLogger(__name__)

ENV_VAR = "ACCELCAL_DB"
SQLITE_BUSY_TIMEOUT_S = 30.0
# the newest migration (migrations/versions): what `open_engine` checks a database against
# without importing Alembic (about twice `import numpy`, issue 34); a test holds it to
# Alembic's own head (tests/app/records/db/test_engine_head.py)
SCHEMA_HEAD = "0015"


class DatabaseError(RecordsInputError):
    """The records database cannot be used; the message says why and what to do."""


class RecordsMissing(DatabaseError):
    """No records database yet (its SQLite file does not exist): the normal state until
    `accelcal db upgrade` creates it."""


def default_path() -> Path:
    """The embedded default's file: records.sqlite in the user's data directory
    (app.files.data_dir: $ACCELCAL_DATA_DIR, else platformdirs)."""
    from app.files import data_dir

    return data_dir() / "records.sqlite"


def default_url() -> str:
    """The embedded default: the SQLite file `default_path`."""
    return f"sqlite:///{default_path()}"


def resolve_url(explicit: str | None = None) -> str:
    """The database URL: `explicit`, else $ACCELCAL_DB, else the default SQLite file."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    url = explicit or os.environ.get(ENV_VAR) or default_url()
    try:
        parsed = make_url(url)
    except ArgumentError:
        raise DatabaseError(f"--db: not a database URL: {url!r}") from None
    if parsed.drivername in ("postgresql", "postgres"):
        parsed = parsed.set(drivername="postgresql+psycopg")
    elif parsed.drivername not in ("sqlite", "sqlite+pysqlite", "postgresql+psycopg"):
        raise DatabaseError(
            f"--db: unsupported database {parsed.drivername!r} (use sqlite:/// or postgresql://)"
        )
    return parsed.render_as_string(hide_password=False)


def records_url(explicit: str | None = None) -> str | None:
    """The URL of the records in use, the one answer for every face (`run`, `certificate`, the
    GUI): `explicit` (--db), else $ACCELCAL_DB, else the default SQLite file when it exists;
    None when no records database is in use (per-folder numbering, stated on the
    certificate)."""
    if explicit or os.environ.get(ENV_VAR):
        return resolve_url(explicit)
    if default_path().is_file():  # no file: no records, and SQLAlchemy is not even imported
        return resolve_url(default_url())
    return None


def _sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    dbapi_connection.isolation_level = None  # SQLAlchemy's "begin" event issues BEGIN itself
    cursor = dbapi_connection.cursor()
    cursor.execute(f"PRAGMA busy_timeout = {int(SQLITE_BUSY_TIMEOUT_S * 1000)}")
    cursor.execute("PRAGMA journal_mode = WAL")
    cursor.execute("PRAGMA foreign_keys = ON")
    cursor.close()


def make_engine(url: str) -> Engine:
    """An engine for `url` (already resolved); SQLite gets WAL, busy timeout, IMMEDIATE."""
    from sqlalchemy import create_engine, event
    from sqlalchemy.engine import make_url

    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        database = parsed.database
        if database and database != ":memory:":
            Path(database).parent.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"timeout": SQLITE_BUSY_TIMEOUT_S})
        event.listen(engine, "connect", _sqlite_pragmas)
        event.listen(engine, "begin", lambda conn: conn.exec_driver_sql("BEGIN IMMEDIATE"))
        return engine
    return create_engine(url, pool_pre_ping=True)


def _alembic_config(engine: Engine) -> Any:
    from alembic.config import Config

    config = Config()
    config.set_main_option(
        "script_location", str(resources.files("app.records.db").joinpath("migrations"))
    )
    return config


def head_revision(engine: Engine) -> str:
    """The newest schema revision this program knows."""
    from alembic.script import ScriptDirectory

    head = ScriptDirectory.from_config(_alembic_config(engine)).get_current_head()
    assert head is not None
    return head


def current_revision(engine: Engine) -> str | None:
    """The schema revision the database is at (None: no schema at all)."""
    from alembic.runtime.migration import MigrationContext

    with engine.connect() as connection:
        return MigrationContext.configure(connection).get_current_revision()


def _at_head(engine: Engine) -> bool:
    """Whether the database's one stored revision (Alembic's alembic_version table, read with
    SQLAlchemy Core) is SCHEMA_HEAD. False for anything else, which `open_engine` then asks
    Alembic about (no schema, older, several heads, unknown)."""
    from sqlalchemy import inspect, text

    with engine.connect() as connection:
        if not inspect(connection).has_table("alembic_version"):
            return False
        rows = connection.execute(text("SELECT version_num FROM alembic_version")).all()
    return [tuple(row) for row in rows] == [(SCHEMA_HEAD,)]


def upgrade(engine: Engine, revision: str = "head") -> tuple[str | None, str | None]:
    """Migrate the schema to `revision`; returns (revision before, revision after)."""
    from alembic import command

    from app.records.db import chain, chain_check, records_key

    before = current_revision(engine)
    config = _alembic_config(engine)
    sqlite = engine.dialect.name == "sqlite"
    records_key.ensure_key()  # every head the upgrade appends is signed with it
    with engine.connect() as connection:
        raw = connection.connection.driver_connection
        if sqlite and raw is not None:  # batch migrations rebuild tables: keys checked after
            raw.execute("PRAGMA foreign_keys = OFF")
        with connection.begin():
            config.attributes["connection"] = connection
            pending = before != (head_revision(engine) if revision == "head" else revision)
            if pending:  # the records chain: verified before, rows re-entered after
                chain_check.before_migration(connection)
            command.upgrade(config, revision)
            if pending:
                chain_check.after_migration(connection)
            if sqlite:
                broken = connection.exec_driver_sql("PRAGMA foreign_key_check").all()
                if broken:
                    raise DatabaseError(f"migration to {revision} broke foreign keys: {broken}")
        if before is None:  # new records where others may have been: their last head is moot
            identity = chain.database_identity(connection)
            records_key.forget_signed(records_key.database_id(identity))
        chain.remember_head(connection)
        if sqlite and raw is not None:
            raw.execute("PRAGMA foreign_keys = ON")
    after = current_revision(engine)
    if before != after:
        log.info("records database migrated from %s to %s", before or "nothing", after)
    return before, after


def _has_tables(engine: Engine) -> bool:
    from sqlalchemy import inspect

    return bool(inspect(engine).get_table_names())


def _missing_sqlite_file(url: str) -> Path | None:
    """The file of an SQLite `url` when it does not exist yet (None: it exists, or the URL is
    in memory or another engine's)."""
    from sqlalchemy.engine import make_url

    parsed = make_url(url)
    database = parsed.database
    if parsed.get_backend_name() != "sqlite" or not database or database == ":memory:":
        return None
    path = Path(database)
    return None if path.is_file() else path


def open_engine(url: str | None = None, *, create: bool = False) -> Engine:
    """An engine on a database whose schema is this program's. A database without the schema
    (an SQLite file that does not exist, an empty server database) is created only when
    `create` (`accelcal db upgrade` and the tests say so); otherwise it is refused with what to
    do, and a missing SQLite file is left missing. A database at an older revision, or one of
    unknown origin, is refused with what to do."""
    resolved = resolve_url(url)
    missing = _missing_sqlite_file(resolved)
    if missing is not None and not create:
        raise RecordsMissing(
            f"records database {missing}: does not exist; `accelcal db upgrade` creates it "
            "(records are created only on request)"
        )
    engine = make_engine(resolved)
    try:
        if _at_head(engine):  # the usual case, without importing Alembic
            return engine
        current = current_revision(engine)
    except Exception as exc:  # unreachable server, bad file
        engine.dispose()
        raise DatabaseError(f"records database {_safe(resolved)}: cannot connect ({exc})") from exc
    head = head_revision(engine)
    if current == head:
        return engine
    if current is None:
        if create and not _has_tables(engine):
            upgrade(engine)
            return engine
        engine.dispose()
        raise DatabaseError(
            f"records database {_safe(resolved)}: no accelcal schema; run `accelcal db upgrade`"
        )
    engine.dispose()
    raise DatabaseError(
        f"records database {_safe(resolved)}: schema revision {current}, this program needs "
        f"{head}; run `accelcal db upgrade` (after a backup)"
    )


def _safe(url: str) -> str:
    from sqlalchemy.engine import make_url

    return make_url(url).render_as_string(hide_password=True)
